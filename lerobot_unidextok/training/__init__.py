"""Tokenizer training (layer 5): config, per-hand rows, coverage mixing, episode splits, optimiser, loop, checkpoints."""

from lerobot_unidextok.training.arrays import HandStates, load_hand_states, subsample_episodes
from lerobot_unidextok.training.config import TrainConfig
from lerobot_unidextok.training.loop import TrainResult, build_model, evaluate_mae_deg, train_tokenizer

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
