"""Reading converted UDHM datasets into flat per-hand arrays (training, evaluation): in memory
(`load_udhm_frames`), in bounded pieces (`iter_udhm_frames`) or memory-mapped on disk (`open_row_store`)."""

from lerobot_unidextok.data.reader import (
    UdhmFrames,
    iter_udhm_frames,
    load_udhm_frames,
    read_info,
    split_episode_range,
    udhm_blocks,
)
from lerobot_unidextok.data.rowstore import HandRows, HandRowStore, build_row_store, open_row_store
from lerobot_unidextok.data.splits import HOLDOUTS, SPLITS, EpisodeSplit, SplitError, resolve_split

__all__ = [
    "HOLDOUTS",
    "SPLITS",
    "EpisodeSplit",
    "HandRowStore",
    "HandRows",
    "SplitError",
    "UdhmFrames",
    "build_row_store",
    "iter_udhm_frames",
    "load_udhm_frames",
    "open_row_store",
    "read_info",
    "resolve_split",
    "split_episode_range",
    "udhm_blocks",
]
