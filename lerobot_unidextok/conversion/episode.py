"""What a source reader hands to the conversion pipeline: raw episodes in native units.

Readers under `converters/<source>/` only turn files into these objects; everything else
(UDHM mapping, validation, writing, splits, cards) is shared machinery in this package.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class HandStream:
    """One hand of one episode, in the source's native units."""

    side: str  # "right" | "left"
    hand: str  # hand spec name in the registry, e.g. "linkerhand_l10", "inspire_rh56_unitree", "human"
    # (T, D) native joint values for robot hands; (T, 21, 3) MANO-21 keypoints in metres for "human".
    state_native: np.ndarray
    action_native: np.ndarray | None = None  # same layout as state_native, where the source has commands
    valid: np.ndarray | None = None  # (T,) bool: frames where this hand is present / tracked


@dataclass
class RawEpisode:
    """One source episode: one or two hands sharing a clock."""

    source_file: str  # path (or path#key) the episode came from, quoted in error reports
    fps: float
    hands: list[HandStream]
    task: str = ""  # language instruction / task name where the source has one
    extra: dict = field(default_factory=dict)  # source-specific metadata kept for the card

    @property
    def num_frames(self) -> int:
        return int(self.hands[0].state_native.shape[0])
