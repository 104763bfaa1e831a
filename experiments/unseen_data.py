"""Data of the generalization experiments (`unseen_episodes`, `unseen_human`): the real recordings
(`experiments.real_data`: ../shared/data/real beside the checkout, `UNIDEXTOK_REAL_DATA` elsewhere; never
copied into the repository), human keypoint files solved by UDHM IK, and the 8-bit binning reference.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lerobot_unidextok.training import HandStates, load_hand_states


def real_data_dir() -> Path:
    """The real recordings folder; a clear error when it is absent."""
    from experiments.config import default_real_data_dir

    path = Path(default_real_data_dir())
    if not path.is_dir():
        raise FileNotFoundError(
            f"real recordings not found at {path}; set UNIDEXTOK_REAL_DATA to a copy of shared/data/real or pass "
            "your own converted datasets / keypoint files"
        )
    return path


def converted_g1(cache_dir: str | Path) -> Path:
    """The real G1 + Inspire recordings (`g1-inspire`, LeRobot v2.1) converted to UDHM once into `cache_dir`."""
    from experiments.config import ExperimentConfig
    from experiments.real_data import g1_inspire

    return g1_inspire(ExperimentConfig(data_dir=str(cache_dir), real_data_dir=str(real_data_dir())))


def all_episodes(datasets: list[str]) -> HandStates:
    """Every episode of the datasets (train and test splits pooled, for k-fold)."""
    return load_hand_states([str(d) for d in datasets], split=None)


# ---------------------------------------------------------------------------------------------
# human keypoint recordings -> UDHM rows (UDHM IK)
# ---------------------------------------------------------------------------------------------
def human_rows_from_keypoints(keypoints_m: np.ndarray, episode: int = 0, side: str = "right") -> HandStates:
    """(T, 21, 3) MANO-21 keypoints in metres -> human UDHM rows (all 22 DoFs active)."""
    from lerobot_unidextok import hands

    keypoints_m = np.asarray(keypoints_m, dtype=np.float64)
    if keypoints_m.ndim != 3 or keypoints_m.shape[1:] != (21, 3):
        raise ValueError(f"keypoints must be (T, 21, 3) metres in MANO-21 order, got {keypoints_m.shape}")
    q = np.asarray(hands.get("human").to_udhm(keypoints_m, side=side), dtype=np.float32)
    n = len(q)
    return HandStates(q, np.full(n, "human"), np.ones((n, 22), bool), np.full(n, episode), np.zeros(n))


def load_keypoints(path: str | Path) -> dict[str, np.ndarray]:
    """Named (T, 21, 3) keypoint arrays from a `.npy` (one recording) or a MediaPipe fixtures JSON (one
    array per entry with `world_landmarks_m`, as `mediapipe_hand_fixtures.json`)."""
    path = Path(path)
    if path.suffix == ".npy":
        return {path.stem: np.load(path)}
    if path.suffix == ".json":
        raw = json.loads(path.read_text())
        out = {k.removesuffix(".pbtxt"): np.asarray(v["world_landmarks_m"], np.float64)[None]
               for k, v in raw.items() if isinstance(v, dict) and "world_landmarks_m" in v}  # fmt: skip
        if not out:
            raise ValueError(f"{path}: no entries with world_landmarks_m")
        return out
    raise ValueError(f"{path}: expected a .npy of (T, 21, 3) keypoints or a MediaPipe fixtures .json")


# ---------------------------------------------------------------------------------------------
# the no-training reference
# ---------------------------------------------------------------------------------------------
def hand_binning(hand: str, num_bins: int = 256, spec=None):
    """Per-joint uniform binning of `hand` over its range (human: the UDHM joint limits; a robot: the union over
    its sides), `num_bins` bins per active joint. `spec`: a `HandSpec` of a hand that is not registered (e.g.
    loaded with `hands.load_spec`), else the registered one."""
    from lerobot_unidextok import hands, udhm
    from lerobot_unidextok.baselines import BinningConfig, HandRange, UniformBinning

    spec = spec or hands.get(hand)
    if spec.kind == "keypoints":
        limits = udhm.JOINT_LIMITS_RAD
    else:  # union over the hand's sides
        los, his = zip(*(spec.udhm_limits_rad(s) for s in spec.sides), strict=True)
        limits = np.stack([np.min(los, 0), np.max(his, 0)], axis=1)
    return UniformBinning({hand: HandRange.from_limits(limits, spec.active_mask)}, BinningConfig(num_bins))


def binning_reconstruction(data: HandStates, num_bins: int = 256, specs: dict | None = None) -> np.ndarray:
    """Per-joint uniform binning (RT-2 / OpenVLA, 8 bits at 256 bins) over each hand's range (`hand_binning`):
    decode(encode(x)) of every row. A hand's spec is `specs[name]` (`HandSpec`s of hands that are not
    registered), else the registered one."""
    out = np.zeros_like(data.states_rad)
    for hand in data.hand_names():
        binning = hand_binning(hand, num_bins, (specs or {}).get(hand))
        rows = data.hands == hand
        out[rows] = binning.decode(binning.encode(data.states_rad[rows], hand), hand).numpy()
    return out
