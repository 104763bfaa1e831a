"""UniDexTok tokenizer (layer 2): config, adaLN blocks, factorised cosine VQ, Hub-format model.

The config module imports no torch, so configs that take an encoding setting (`EncodingConfig`) stay light;
the model and the quantiser are imported on first use (PEP 562).
"""

import importlib

from lerobot_unidextok.tokenizer.configuration_unidextok import (
    DEFAULT_HAND_NAMES,
    FORMAT_VERSION,
    NEAREST_CODES,
    PRESETS,
    EncodingConfig,
    UniDexTokConfig,
)

_LAZY = {
    "UniDexTok": "lerobot_unidextok.tokenizer.modeling_unidextok",
    "UniDexTokOutput": "lerobot_unidextok.tokenizer.modeling_unidextok",
    "count_parameters": "lerobot_unidextok.tokenizer.modeling_unidextok",
    "FactorizedCosineVQ": "lerobot_unidextok.tokenizer.quantizer",
}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "DEFAULT_HAND_NAMES",
    "FORMAT_VERSION",
    "NEAREST_CODES",
    "PRESETS",
    "EncodingConfig",
    "FactorizedCosineVQ",
    "UniDexTok",
    "UniDexTokConfig",
    "UniDexTokOutput",
    "count_parameters",
]
