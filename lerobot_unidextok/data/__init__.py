"""Reading converted UDHM datasets into flat per-hand arrays (training, evaluation)."""

from lerobot_unidextok.data.reader import (
    UdhmFrames,
    load_udhm_frames,
    read_info,
    split_episode_range,
    udhm_blocks,
)
from lerobot_unidextok.data.splits import HOLDOUTS, SPLITS, EpisodeSplit, SplitError, resolve_split

__all__ = [
    "HOLDOUTS",
    "SPLITS",
    "EpisodeSplit",
    "SplitError",
    "UdhmFrames",
    "load_udhm_frames",
    "read_info",
    "resolve_split",
    "split_episode_range",
    "udhm_blocks",
]
