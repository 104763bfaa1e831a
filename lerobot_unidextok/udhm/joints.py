"""UDHM joint names, per-DoF joint limits and small helpers on (..., 22) angle arrays."""

from __future__ import annotations

import math

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM, UDHM_INDEX, UDHM_JOINT_NAMES

JOINT_NAMES: tuple[str, ...] = UDHM_JOINT_NAMES  # fixed order, never reorder

_DEG = math.pi / 180.0

# ---------------------------------------------------------------------------------------------
# Joint limits (rad), human active range of motion about the UDHM zero pose (flat hand, every
# finger perpendicular to the index-ring knuckle row, thumb lying in the palm plane alongside the index).
# Sources: AAOS "Joint Motion: Method of Measuring and Recording" (1965) and Hume et al. 1990
# (J Hand Surg 15A: functional ROM) for flexion/extension; abduction ranges add the ~±15 deg
# resting splay of each finger relative to the middle finger, because UDHM measures abduction
# from "parallel to the middle finger", not from the finger's own metacarpal. The ranges of the
# angles about the palm normal (thumb CMC spread, the four MCP abductions) were written about the
# wrist -> middle MCP line; the knuckle-row zero (frames.py) is turned 5.4 deg from it toward the
# little finger on the default hand, so they sit 5 deg further toward the thumb.
# Signs: flexion > 0 toward the palm, abduction > 0 toward the thumb (right-hand frame).
# ---------------------------------------------------------------------------------------------
_LIMITS_DEG: dict[str, tuple[float, float]] = {
    # Thumb CMC: palmar abduction 0..~80 deg (AAOS 0-70/80), a little retroposition below 0.
    "thumb_cmc_flex": (-20.0, 90.0),
    # Thumb CMC radial abduction measured from parallel to the fingers: 0..~80 deg (AAOS 0-80).
    "thumb_cmc_spread": (-10.0, 95.0),
    # Thumb MCP flexion 0-50 (AAOS) up to 90 in lax joints, hyperextension to ~30.
    "thumb_mcp_flex": (-30.0, 90.0),
    # Thumb MCP ab/adduction (also absorbs metacarpal pronation the 5-DoF thumb lacks): ~±30.
    "thumb_mcp_abd": (-40.0, 40.0),
    # Thumb IP flexion 0-80/90 (AAOS 0-80), hyperextension to ~35.
    "thumb_ip_flex": (-35.0, 90.0),
    # Index/middle/ring MCP abduction ±20 (AAOS) plus resting splay.
    "index_mcp_abd": (-25.0, 50.0),
    "index_mcp_flex": (-45.0, 100.0),  # AAOS 0-90 flexion, 0-45 hyperextension
    "index_pip_flex": (-10.0, 120.0),  # AAOS 0-100, functional studies to ~110-120
    "index_dip_flex": (-30.0, 100.0),  # AAOS 0-90, hyperextension to ~30
    "middle_mcp_abd": (-30.0, 40.0),
    "middle_mcp_flex": (-45.0, 100.0),
    "middle_pip_flex": (-10.0, 120.0),
    "middle_dip_flex": (-30.0, 100.0),
    "ring_mcp_abd": (-40.0, 35.0),
    "ring_mcp_flex": (-45.0, 100.0),
    "ring_pip_flex": (-10.0, 120.0),
    "ring_dip_flex": (-30.0, 100.0),
    # 4th/5th CMC mobility: the little-finger metacarpal flexes/rotates ~20-30 deg when cupping
    # (El-Shennawy et al. 2001); > 0 = cupping (the little finger curls toward the thumb).
    "pinky_metacarpal_twist": (-30.0, 45.0),
    "pinky_mcp_abd": (-50.0, 35.0),
    "pinky_mcp_flex": (-45.0, 100.0),
    "pinky_pip_flex": (-10.0, 120.0),
    "pinky_dip_flex": (-30.0, 100.0),
}
JOINT_LIMITS_RAD: np.ndarray = np.array([_LIMITS_DEG[n] for n in JOINT_NAMES], dtype=np.float64) * _DEG  # (22, 2)
JOINT_LIMITS_RAD.setflags(write=False)


def joint_index(name: str) -> int:
    """Position of a UDHM joint name in the 22-vector; ValueError lists the valid names."""
    if name not in UDHM_INDEX:
        raise ValueError(f"unknown UDHM joint {name!r}; valid names: {', '.join(JOINT_NAMES)}")
    return UDHM_INDEX[name]


def _check_angles(angles_rad: np.ndarray) -> np.ndarray:
    angles_rad = np.asarray(angles_rad)
    if angles_rad.shape[-1:] != (UDHM_DIM,):
        raise ValueError(f"angles_rad must have shape (..., {UDHM_DIM}), got {angles_rad.shape}")
    return angles_rad


def limit_violations(angles_rad: np.ndarray, tol_rad: float = 1e-3) -> np.ndarray:
    """Bool (..., 22): True where an angle lies more than `tol_rad` outside JOINT_LIMITS_RAD."""
    angles_rad = _check_angles(angles_rad)
    return (angles_rad < JOINT_LIMITS_RAD[:, 0] - tol_rad) | (angles_rad > JOINT_LIMITS_RAD[:, 1] + tol_rad)


def clip_to_limits(angles_rad: np.ndarray) -> np.ndarray:
    """Angles clipped into JOINT_LIMITS_RAD (NaN stays NaN)."""
    angles_rad = _check_angles(angles_rad)
    return np.clip(angles_rad, JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1])


def sample_angles(rng: np.random.Generator, shape: tuple[int, ...] = (), margin: float = 0.0) -> np.ndarray:
    """Uniform random angles (*shape, 22) inside the limits, shrunk by `margin` (fraction of range) per side."""
    lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
    pad = (hi - lo) * margin
    return rng.uniform(lo + pad, hi - pad, size=(*shape, UDHM_DIM))
