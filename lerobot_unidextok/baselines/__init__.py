"""Baseline hand-state tokenizers (uniform binning, PCA + binning, UniHM-style VQ-VAE, FSQ / RVQ) and their rates.

Errors are scored with `lerobot_unidextok.evaluation.metrics`, the same code for every method.

Layer 2: imports `constants` and torch only; hands are known by name, limits and masks arrive as data.
The FSQ / RVQ baselines need the `baselines` extra (vector-quantize-pytorch), imported when built.
"""

from lerobot_unidextok.baselines.base import (
    Rate,
    StateTokenizer,
    TrainableStateTokenizer,
    bits_per_state,
    reconstruct,
    tokens_per_state,
)
from lerobot_unidextok.baselines.binning import BinningConfig, HandRange, UniformBinning
from lerobot_unidextok.baselines.pca import PCAConfig, PCATokenizer
from lerobot_unidextok.baselines.quantized_ae import (
    QuantizedAEConfig,
    QuantizedAETokenizer,
    fsq_tokenizer,
    rvq_tokenizer,
)
from lerobot_unidextok.baselines.unidextok_adapter import UniDexTokAdapter
from lerobot_unidextok.baselines.unihm import UNIHM_PRESETS, UniHMConfig, UniHMTokenizer

__all__ = [
    "UNIHM_PRESETS",
    "BinningConfig",
    "HandRange",
    "PCAConfig",
    "PCATokenizer",
    "QuantizedAEConfig",
    "QuantizedAETokenizer",
    "Rate",
    "StateTokenizer",
    "TrainableStateTokenizer",
    "UniDexTokAdapter",
    "UniHMConfig",
    "UniHMTokenizer",
    "UniformBinning",
    "bits_per_state",
    "fsq_tokenizer",
    "reconstruct",
    "rvq_tokenizer",
    "tokens_per_state",
]
