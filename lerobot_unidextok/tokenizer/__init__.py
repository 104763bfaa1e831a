"""UniDexTok tokenizer (layer 2): config, adaLN blocks, factorised cosine VQ, Hub-format model."""

from lerobot_unidextok.tokenizer.configuration_unidextok import (
    DEFAULT_HAND_NAMES,
    FORMAT_VERSION,
    PRESETS,
    UniDexTokConfig,
)
from lerobot_unidextok.tokenizer.modeling_unidextok import UniDexTok, UniDexTokOutput, count_parameters
from lerobot_unidextok.tokenizer.quantizer import FactorizedCosineVQ

__all__ = [
    "DEFAULT_HAND_NAMES",
    "FORMAT_VERSION",
    "PRESETS",
    "FactorizedCosineVQ",
    "UniDexTok",
    "UniDexTokConfig",
    "UniDexTokOutput",
    "count_parameters",
]
