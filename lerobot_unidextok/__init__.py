"""lerobot-unidextok: UDHM hand model, dataset converters and the UniDexTok hand-state tokenizer.

    from lerobot_unidextok import udhm, hands, UniDexTok

Importing the package is cheap: subpackages and the tokenizer are imported on first use. LeRobot
registration (the `<type>_udt` policy types, the `unidextok.*` processor steps) happens on import of
`lerobot_unidextok.policies` / `lerobot_unidextok.processor`, which LeRobot's CLIs import through the
`lerobot_policy_unidextok` plugin package (docs/lerobot.md).
"""

import importlib

from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_DIM, UDHM_JOINT_NAMES

__version__ = "0.1.0"

_LAZY_NAMES = {"UniDexTok": "lerobot_unidextok.tokenizer", "UniDexTokConfig": "lerobot_unidextok.tokenizer"}
_LAZY_SUBPACKAGES = ("udhm", "hands", "tokenizer")

__all__ = [*_LAZY_SUBPACKAGES, "KEYPOINT_NAMES", "UDHM_DIM", "UDHM_JOINT_NAMES", *_LAZY_NAMES, "__version__"]


def __getattr__(name: str):
    """PEP 562: `lerobot_unidextok.UniDexTok`, `lerobot_unidextok.udhm`, ... imported on first access."""
    if name in _LAZY_NAMES:
        value = getattr(importlib.import_module(_LAZY_NAMES[name]), name)
        globals()[name] = value
        return value
    if name in _LAZY_SUBPACKAGES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
