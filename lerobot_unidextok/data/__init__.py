"""Converted UDHM datasets: their metadata and conversion record read once (`UdhmDatasetMeta`,
`ConversionRecord`), and their rows as flat per-hand arrays (training, evaluation): in memory
(`load_udhm_frames`), in bounded pieces (`iter_udhm_frames`) or memory-mapped on disk (`open_row_store`)."""

from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.reader import (
    UdhmFrames,
    iter_udhm_frames,
    load_udhm_frames,
    split_episode_range,
    udhm_blocks,
)
from lerobot_unidextok.data.record import ConversionRecord, EpisodeRecord, RecordError, load_record, write_record
from lerobot_unidextok.data.rowstore import HandRows, HandRowStore, build_row_store, open_row_store
from lerobot_unidextok.data.splits import HOLDOUTS, SPLITS, EpisodeSplit, SplitError

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
    "UdhmDatasetMeta",
    "ConversionRecord",
    "EpisodeRecord",
    "RecordError",
    "load_record",
    "write_record",
    "split_episode_range",
    "udhm_blocks",
]
