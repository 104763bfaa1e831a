"""Reading converted UDHM datasets into flat per-hand arrays (training, evaluation)."""

from lerobot_unidextok.data.reader import (
    UdhmFrames,
    load_udhm_frames,
    read_info,
    split_episode_range,
)

__all__ = ["UdhmFrames", "load_udhm_frames", "read_info", "split_episode_range"]
