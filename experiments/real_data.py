"""The real recordings in ../shared/data/real as experiment data (the default when the folder is present).

- `g1-inspire/`: real Unitree G1 teleoperation, two Inspire hands (LeRobot v2.1), converted once with the
  `lerobot` source into a UDHM LeRobotDataset under `data_dir` and read back; the converter's episode split.
- `dex-retargeting/human_joint_right.npy`: one real right hand (MediaPipe world landmarks, 621 frames at
  30 fps) mapped to UDHM by the human hand spec (UDHM IK). One clip, so it is cut into consecutive segments
  of `human_segment_s` seconds that act as episodes; the held-out segments are chosen like the converter's
  episode split (`data.splits.split_order`, 20 % by sha1 of the segment key).
The clip's keypoints are also what `experiments.retargeted` retargets onto the robot hands (protocol b).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.config import ExperimentConfig
from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.converters.lerobot import G1_INSPIRE_HANDS as G1_HANDS
from lerobot_unidextok.training import HandStates, load_hand_states
from lerobot_unidextok.utils.files import fingerprint

logger = logging.getLogger(__name__)

HUMAN = "human"
G1_FOLDER = "g1-inspire"
HUMAN_CLIP = Path("dex-retargeting") / "human_joint_right.npy"
HUMAN_CLIP_FPS = 30.0  # upstream video, see ../shared/data/real/README.md
SEGMENT_EPISODE_BASE = 100_000  # human segment episode ids, apart from the G1 episode ids


def real_available(cfg: ExperimentConfig) -> bool:
    return (cfg.real_dir / G1_FOLDER / INFO_PATH).is_file() and (cfg.real_dir / HUMAN_CLIP).is_file()


@dataclass
class RealHuman:
    """The real human clip as UDHM, cut into segments."""

    keypoints_m: np.ndarray  # (T, 21, 3)
    states_rad: np.ndarray  # (T, 22) human UDHM
    segment: np.ndarray  # (T,) segment id
    test: np.ndarray  # (T,) bool: frame in a held-out segment

    def human_states(self, test: bool) -> HandStates:
        rows = self.test == test
        return HandStates(self.states_rad[rows], np.full(rows.sum(), HUMAN), np.ones((rows.sum(), 22), bool),
                          SEGMENT_EPISODE_BASE + self.segment[rows])  # fmt: skip


def segment_split(num_frames: int, segment_frames: int, test_fraction: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """(segment id per frame, test flag per frame): consecutive segments, the last short one merged."""
    from lerobot_unidextok.data.splits import split_order

    n_seg = max(1, num_frames // segment_frames)
    segment = np.minimum(np.arange(num_frames) // segment_frames, n_seg - 1)
    _, test_ids = split_order([f"{HUMAN_CLIP.as_posix()}#segment{i:03d}" for i in range(n_seg)], test_fraction)
    return segment, np.isin(segment, test_ids)


def real_human(cfg: ExperimentConfig) -> RealHuman:
    from lerobot_unidextok import hands

    kp = np.load(cfg.real_dir / HUMAN_CLIP).astype(np.float64)  # (T, 21, 3) m
    states = np.asarray(hands.get(HUMAN).to_udhm(kp, "right"), dtype=np.float64)  # (T, 22) rad
    segment, test = segment_split(len(kp), max(1, round(cfg.human_segment_s * HUMAN_CLIP_FPS)))
    return RealHuman(kp, states, segment, test)


def g1_inspire(cfg: ExperimentConfig, mapping: str = "semantic") -> Path:
    """The real G1 + Inspire recordings converted to a UDHM dataset with `mapping` (once; reused while valid)."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    src = cfg.real_dir / G1_FOLDER
    stamp = fingerprint(json.dumps(sorted((p.name, p.stat().st_size) for p in src.rglob("*") if p.is_file())).encode())
    root = Path(cfg.data_dir) / f"real_g1_inspire_{mapping}_{stamp}"
    if not (root / INFO_PATH).is_file():
        convert(ConvertOptions(source="lerobot", input=src, root=root, repo_id="local/real_g1_inspire",
                               source_options={"hands": G1_HANDS}, mapping=mapping, overwrite=True, progress=False))  # fmt: skip
    return root


def real_train_test(
    cfg: ExperimentConfig, mapping: str = "semantic"
) -> tuple[HandStates, HandStates, list[str], RealHuman]:
    """UniDexTok's real data: G1 Inspire (both hands) + the human clip segments; (train, test, sources, clip).
    The human hand fills all 22 slots, so its rows are the same under either mapping."""
    root = g1_inspire(cfg, mapping)
    clip = real_human(cfg)
    train = HandStates.concat([load_hand_states([str(root)], "train"), clip.human_states(test=False)])
    test = HandStates.concat([load_hand_states([str(root)], "test"), clip.human_states(test=True)])
    sources = [
        f"{G1_FOLDER} (converted: {root})",
        f"{HUMAN_CLIP.as_posix()} (UDHM IK, {cfg.human_segment_s:g} s segments)",
    ]
    return train, test, sources, clip
