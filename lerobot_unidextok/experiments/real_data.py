"""Real recordings for the generalization experiments: where they are, converted / solved once, and the
8-bit binning reference on the same frames.

The recordings live beside the checkout in `../shared/data/real` (`UNIDEXTOK_REAL_DATA` points elsewhere);
they are never copied into the repository.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from lerobot_unidextok.training import HandStates, load_hand_states

REPO_ROOT = Path(__file__).resolve().parents[2]
G1_HANDS = {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}


def real_data_dir() -> Path:
    """`$UNIDEXTOK_REAL_DATA`, else `../shared/data/real` next to the checkout; a clear error when absent."""
    path = Path(os.environ.get("UNIDEXTOK_REAL_DATA", REPO_ROOT.parent / "shared" / "data" / "real"))
    if not path.is_dir():
        raise FileNotFoundError(
            f"real recordings not found at {path}; set UNIDEXTOK_REAL_DATA to a copy of shared/data/real or pass "
            "your own converted datasets / keypoint files"
        )
    return path


def converted_g1(cache_dir: str | Path) -> Path:
    """The real G1 + Inspire recordings (`g1-inspire`, LeRobot v2.1) converted to UDHM once into `cache_dir`."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    root = Path(cache_dir) / "g1_inspire_udhm"
    if (root / "meta" / "info.json").is_file() and any((root / "data").glob("chunk-*/file-*.parquet")):
        return root
    convert(ConvertOptions(source="lerobot", input=real_data_dir() / "g1-inspire", root=root, repo_id="local/g1_inspire_udhm",
                           source_options={"hands": G1_HANDS}, overwrite=True, progress=False))  # fmt: skip
    return root


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
def binning_reconstruction(data: HandStates, num_bins: int = 256) -> np.ndarray:
    """Per-joint uniform binning (RT-2 / OpenVLA, 8 bits at 256 bins) over each hand's registered range
    (human: the UDHM joint limits): decode(encode(x)) of every row."""
    from lerobot_unidextok import hands, udhm
    from lerobot_unidextok.baselines import BinningConfig, HandRange, UniformBinning

    out = np.zeros_like(data.states_rad)
    for hand in data.hand_names():
        spec = hands.get(hand)
        if spec.kind == "keypoints":
            limits = udhm.JOINT_LIMITS_RAD
        else:  # union over the hand's sides
            los, his = zip(*(spec.udhm_limits_rad(s) for s in spec.sides), strict=True)
            limits = np.stack([np.min(los, 0), np.max(his, 0)], axis=1)
        binning = UniformBinning({hand: HandRange.from_limits(limits, spec.active_mask)}, BinningConfig(num_bins))
        rows = data.hands == hand
        out[rows] = binning.decode(binning.encode(data.states_rad[rows], hand), hand).numpy()
    return out
