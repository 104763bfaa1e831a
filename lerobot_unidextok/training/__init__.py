"""Tokenizer training (layer 5): config, per-hand rows, coverage mixing, episode splits, optimiser, loop, checkpoints.

Names are imported lazily, so `lerobot_unidextok.training.config` (what `unidextok-train --help` needs)
imports without torch.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "HandStates": "arrays",
    "load_hand_states": "arrays",
    "subsample_episodes": "arrays",
    "TrainConfig": "config",
    "TrainResult": "loop",
    "build_model": "loop",
    "evaluate_mae_deg": "loop",
    "train_tokenizer": "loop",
}

__all__ = [
    "HandStates",
    "TrainConfig",
    "TrainResult",
    "build_model",
    "evaluate_mae_deg",
    "load_hand_states",
    "subsample_episodes",
    "train_tokenizer",
]


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
