"""What a source reader hands to the conversion pipeline: raw episodes in native units.

Readers (`converters/<source>.py`) only turn files into these objects; everything else
(UDHM mapping, validation, writing, splits, cards) is shared machinery in this package.

A robot episode carries the whole robot, not only its hands (converted-dataset contract in
`docs/architecture.md`): `passthrough` holds the non-hand columns of the source state / action
(arms, grippers, base) with their source names and values, `native_names` every source column name in
source order (to decode back to the robot's own vector), `copied` the other source features (images,
other observations) as unchanged Arrow columns and `videos` the source video segments (copied, never
re-encoded).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

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
    # Source column names of this hand's native values (native layout); None for keypoint hands.
    state_columns: tuple[str, ...] | None = None
    action_columns: tuple[str, ...] | None = None


@dataclass
class Passthrough:
    """Non-hand columns of a source vector (arms, grippers, base): names and values, source order."""

    names: tuple[str, ...]
    values: np.ndarray  # (T, P), kept in the source dtype (float32 in LeRobot datasets: bit-identical)

    def __post_init__(self):
        self.names = tuple(self.names)
        if self.values.ndim != 2 or self.values.shape[1] != len(self.names):
            raise ValueError(f"passthrough values {self.values.shape} do not match {len(self.names)} names")


@dataclass
class VideoSegment:
    """One episode's frames inside a source video file: [from_s, to_s) of `path` (copied as is)."""

    path: str
    from_s: float
    to_s: float


@dataclass
class RawEpisode:
    """One source episode: one or two hands sharing a clock, plus the rest of the robot."""

    source_file: str  # path (or path#key) the episode came from, quoted in error reports
    fps: float
    hands: list[HandStream]
    task: str = ""  # language instruction / task name where the source has one
    extra: dict = field(default_factory=dict)  # source-specific metadata kept for the card
    # -- whole robot (empty for hands-only sources) ------------------------------------------------
    # {"observation.state": Passthrough, "action": Passthrough}: non-hand columns of the source vectors
    passthrough: dict[str, Passthrough] = field(default_factory=dict)
    # {"observation.state": [every source column name, source order], "action": [...]}
    native_names: dict[str, list[str]] = field(default_factory=dict)
    # {"observation.state": "states"}: source feature key of each output vector when it differs
    native_keys: dict[str, str] = field(default_factory=dict)
    # {"observation.state": [...]}: source columns the conversion leaves out (a hand that was never recorded):
    # neither hand nor passthrough, zero when the robot's own vector is rebuilt
    dropped: dict[str, list[str]] = field(default_factory=dict)
    # other source features copied unchanged: key -> (T,) pyarrow array, and their LeRobot feature specs
    copied: dict[str, Any] = field(default_factory=dict)
    copied_features: dict[str, dict] = field(default_factory=dict)
    copied_stats: dict[str, dict] = field(default_factory=dict)  # source per-episode stats (images, videos)
    videos: dict[str, VideoSegment] = field(default_factory=dict)
    video_features: dict[str, dict] = field(default_factory=dict)
    # where the episode came from, recorded per episode in meta/unidextok_conversion.json
    source_episode: dict = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return int(self.hands[0].state_native.shape[0])
