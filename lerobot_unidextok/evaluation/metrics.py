"""Reconstruction metrics shared by UniDexTok and the baselines.

All functions take reconstructed vs true UDHM states (N, 22) in radians, the hand name of each row,
and the active-DoF masks; angles are scored on active DoFs only.

Which choices are the paper's and which are ours:
- MPJAE (deg) over active DoFs and MPJPE / fingertip error (mm) through forward kinematics: the paper's metrics.
- The keypoint set of MPJPE is not stated in the paper. UDHM forward kinematics keeps the wrist and the five
  finger bases (thumb CMC, index/middle/ring/pinky MCP) fixed on the palm, so their error is always 0 and an
  average over all 21 keypoints is about 15/21 of the average over the moving ones. We report both, labelled:
  `mpjpe_mm` (all 21 keypoints) and `mpjpe_fingers_mm` (the 15 moving finger keypoints, `FINGER_KEYPOINT_INDICES`).
- Inactive slots of a prediction are replaced by the true values before FK (they are not DoFs of the hand): ours.
"""

import logging

import numpy as np

from lerobot_unidextok import hands as hand_registry
from lerobot_unidextok.constants import (
    FINGERTIP_INDICES,
    KEYPOINT_NAMES,
    KEYPOINT_PARENTS,
    NUM_KEYPOINTS,
    UDHM_JOINT_NAMES,
)
from lerobot_unidextok.udhm.fk import forward_kinematics
from lerobot_unidextok.udhm.skeleton import Skeleton

logger = logging.getLogger(__name__)

# Keypoints the joint angles move: all but the wrist and the points fixed on the palm (children of the wrist).
FINGER_KEYPOINT_INDICES: tuple[int, ...] = tuple(
    k for k, parent in enumerate(KEYPOINT_PARENTS) if parent not in (-1, 0)
)  # 15 of 21


def _check(pred_rad: np.ndarray, true_rad: np.ndarray, masks: np.ndarray | None) -> np.ndarray:
    pred_rad, true_rad = np.asarray(pred_rad), np.asarray(true_rad)
    if pred_rad.shape != true_rad.shape or pred_rad.ndim != 2 or pred_rad.shape[1] != len(UDHM_JOINT_NAMES):
        raise ValueError(f"pred and true must both be (N, 22); got {pred_rad.shape} and {true_rad.shape}")
    if masks is None:
        return np.ones(true_rad.shape, dtype=bool)
    masks = np.asarray(masks, dtype=bool)
    if masks.shape != true_rad.shape:
        raise ValueError(f"masks must be {true_rad.shape}, got {masks.shape}")
    return masks


def joint_abs_error_deg(pred_rad: np.ndarray, true_rad: np.ndarray) -> np.ndarray:
    """(N, 22) absolute angle errors in degrees."""
    return np.degrees(np.abs(np.asarray(pred_rad, np.float64) - np.asarray(true_rad, np.float64)))


def mpjae_deg(pred_rad: np.ndarray, true_rad: np.ndarray, masks: np.ndarray | None = None) -> float:
    """Mean per-joint angle error (deg) over active DoFs of all rows."""
    m = _check(pred_rad, true_rad, masks)
    err = joint_abs_error_deg(pred_rad, true_rad)
    return float(err[m].mean()) if m.any() else float("nan")


def per_joint_mae_deg(pred_rad: np.ndarray, true_rad: np.ndarray, masks: np.ndarray | None = None) -> dict[str, float]:
    """Per UDHM joint MAE (deg) over rows where the joint is active (joints never active are omitted)."""
    m = _check(pred_rad, true_rad, masks)
    err = joint_abs_error_deg(pred_rad, true_rad)
    out = {}
    for j, name in enumerate(UDHM_JOINT_NAMES):
        if m[:, j].any():
            out[name] = float(err[m[:, j], j].mean())
    return out


# ---------------------------------------------------------------------------------------------
# keypoint space: UDHM forward kinematics with each hand's skeleton
# ---------------------------------------------------------------------------------------------
def hand_skeleton(name: str):
    """The `udhm.Skeleton` of a registered hand (a robot's measured from its URDF where the spec has one);
    the default human skeleton for unregistered names. `skeleton_source` says which one a figure used."""
    try:
        spec = hand_registry.get(name)
    except (KeyError, ValueError):
        logger.warning("hand %r is not in the hand registry; scoring keypoints with the default human skeleton", name)
        return Skeleton.default()
    return spec.skeleton()


def skeleton_source(name: str) -> str:
    """Which skeleton keypoint metrics of hand `name` use (printed next to MPJPE / fingertip figures)."""
    try:
        return hand_registry.get(name).skeleton_spec.describe()
    except (KeyError, ValueError):
        return "default human skeleton (hand not in the registry)"


def keypoint_errors_mm(
    pred_rad: np.ndarray, true_rad: np.ndarray, hands: np.ndarray, masks: np.ndarray | None = None
) -> np.ndarray:
    """(N, 21) keypoint distances (mm) between FK(pred) and FK(true), each row with its hand's skeleton.

    Inactive slots of `pred` are replaced by the true values (they are not DoFs of that hand).
    """
    m = _check(pred_rad, true_rad, masks)
    hands = np.asarray(hands).astype(str)
    if hands.shape != (len(true_rad),):
        raise ValueError(f"hands must name one hand per row: expected ({len(true_rad)},), got {hands.shape}")
    pred = np.where(m, np.asarray(pred_rad, np.float64), np.asarray(true_rad, np.float64))
    true = np.asarray(true_rad, np.float64)
    out = np.empty((len(true), NUM_KEYPOINTS))
    for name in np.unique(hands):
        rows = hands == name
        skel = hand_skeleton(str(name))
        kp_pred = forward_kinematics(pred[rows], skel)  # (n, 21, 3) m
        kp_true = forward_kinematics(true[rows], skel)  # (n, 21, 3) m
        out[rows] = np.linalg.norm(kp_pred - kp_true, axis=-1) * 1000.0
    return out


def mpjpe_mm(pred_rad: np.ndarray, true_rad: np.ndarray, hands: np.ndarray, masks: np.ndarray | None = None) -> float:
    """Mean per-keypoint position error (mm) over all 21 keypoints (6 of which sit fixed on the palm)."""
    return float(keypoint_errors_mm(pred_rad, true_rad, hands, masks).mean())


def mpjpe_fingers_mm(
    pred_rad: np.ndarray, true_rad: np.ndarray, hands: np.ndarray, masks: np.ndarray | None = None
) -> float:
    """Mean per-keypoint position error (mm) over the 15 finger keypoints the joints move."""
    return float(keypoint_errors_mm(pred_rad, true_rad, hands, masks)[:, list(FINGER_KEYPOINT_INDICES)].mean())


def fingertip_error_mm(
    pred_rad: np.ndarray, true_rad: np.ndarray, hands: np.ndarray, masks: np.ndarray | None = None
) -> float:
    """Mean fingertip position error (mm) over the five tips."""
    return float(keypoint_errors_mm(pred_rad, true_rad, hands, masks)[:, list(FINGERTIP_INDICES)].mean())


def reconstruction_metrics(
    pred_rad: np.ndarray, true_rad: np.ndarray, hands: np.ndarray, masks: np.ndarray | None = None
) -> dict:
    """Overall and per-hand MPJAE (deg), MPJPE over all 21 keypoints and over the 15 finger keypoints (mm),
    fingertip error (mm) and per-joint MAE tables."""
    m = _check(pred_rad, true_rad, masks)
    hands = np.asarray(hands).astype(str)
    ang = joint_abs_error_deg(pred_rad, true_rad)  # (N, 22)
    kp = keypoint_errors_mm(pred_rad, true_rad, hands, m)  # (N, 21)
    tips = list(FINGERTIP_INDICES)
    fingers = list(FINGER_KEYPOINT_INDICES)

    def _summary(rows: np.ndarray) -> dict:
        mr = m[rows]
        return {
            "rows": int(rows.sum()),
            "active_dofs": int(mr.any(0).sum()),
            "mpjae_deg": float(ang[rows][mr].mean()) if mr.any() else float("nan"),
            "mpjpe_mm": float(kp[rows].mean()),
            "mpjpe_fingers_mm": float(kp[rows][:, fingers].mean()),
            "fingertip_mm": float(kp[rows][:, tips].mean()),
            "per_joint_deg": per_joint_mae_deg(np.asarray(pred_rad)[rows], np.asarray(true_rad)[rows], mr),
            "per_keypoint_mm": {n: float(v) for n, v in zip(KEYPOINT_NAMES, kp[rows].mean(0), strict=True)},
        }

    everything = np.ones(len(hands), dtype=bool)
    return {
        "overall": _summary(everything),
        "per_hand": {str(h): _summary(hands == h) | {"skeleton": skeleton_source(str(h))} for h in np.unique(hands)},
    }
