"""Synthetic hand motion for the sample datasets: smooth transitions between named gestures in UDHM.

Gestures are defined per finger (curl, PIP/DIP coupling ratios) plus explicit thumb angles, so PIP and
DIP follow MCP with per-gesture ratios instead of moving independently. A trajectory is a random
sequence of gestures with minimum-jerk transitions, per-finger onset lags, per-episode timing, per-visit
amplitude jitter, slow drift and sensor noise. Every frame carries the label of the gesture it is
moving to or holding. Everything here is SYNTHETIC and only exercises the converters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM, UDHM_INDEX
from lerobot_unidextok.udhm import clip_to_limits

# ---------------------------------------------------------------------------------------------
# gesture definitions
# ---------------------------------------------------------------------------------------------

MCP_FLEX_MAX_RAD = 1.45  # curl 1.0 of a long finger
LONG_FINGERS: tuple[str, ...] = ("index", "middle", "ring", "pinky")
# MCP abduction at full spread (rad, + = toward the thumb side of a right hand).
SPREAD_ABD_RAD: dict[str, float] = {"index": 0.22, "middle": 0.02, "ring": -0.14, "pinky": -0.28}
_THUMB_JOINTS = ("thumb_cmc_flex", "thumb_cmc_spread", "thumb_mcp_flex", "thumb_mcp_abd", "thumb_ip_flex")


@dataclass(frozen=True)
class Gesture:
    """A named static hand pose: per-finger curl in [0, 1] with coupling ratios, and thumb angles (rad)."""

    name: str
    curl: tuple[float, float, float, float]  # index, middle, ring, pinky MCP curl in [0, 1]
    thumb_rad: tuple[float, float, float, float, float]  # cmc_flex, cmc_spread, mcp_flex, mcp_abd, ip_flex
    spread: float = 0.0  # finger spread in [0, 1]
    pip_ratio: float = 1.1  # PIP flexion = pip_ratio * MCP flexion
    dip_ratio: float = 0.7  # DIP flexion = dip_ratio * PIP flexion

    def angles_rad(self) -> np.ndarray:
        """The gesture as a (22,) UDHM vector in radians."""
        q = np.zeros(UDHM_DIM)
        for finger, curl in zip(LONG_FINGERS, self.curl, strict=True):
            mcp = curl * MCP_FLEX_MAX_RAD
            pip = min(self.pip_ratio * mcp, 1.75)
            q[UDHM_INDEX[f"{finger}_mcp_flex"]] = mcp
            q[UDHM_INDEX[f"{finger}_pip_flex"]] = pip
            q[UDHM_INDEX[f"{finger}_dip_flex"]] = min(self.dip_ratio * pip, 1.3)
            q[UDHM_INDEX[f"{finger}_mcp_abd"]] = self.spread * SPREAD_ABD_RAD[finger] * (1.0 - 0.6 * curl)
        q[UDHM_INDEX["pinky_metacarpal_twist"]] = 0.25 * self.curl[3]  # palm cups as the pinky curls
        for name, value in zip(_THUMB_JOINTS, self.thumb_rad, strict=True):
            q[UDHM_INDEX[name]] = value
        return q


_THUMB_OPEN = (0.05, 0.55, 0.05, 0.0, 0.1)
_THUMB_TUCKED = (0.85, 0.25, 0.55, 0.05, 0.55)  # across the curled fingers
_THUMB_UP = (0.0, 0.35, 0.0, 0.0, 0.0)

GESTURES: dict[str, Gesture] = {
    g.name: g
    for g in (
        Gesture("open", (0.0, 0.0, 0.0, 0.0), _THUMB_OPEN, spread=0.8, pip_ratio=1.0, dip_ratio=0.6),
        Gesture("fist", (1.0, 1.0, 1.0, 1.0), _THUMB_TUCKED, pip_ratio=1.15, dip_ratio=0.75),
        Gesture("point", (0.0, 1.0, 1.0, 1.0), _THUMB_TUCKED, pip_ratio=1.15),  # = counting 1
        Gesture("pinch", (0.5, 0.3, 0.3, 0.3), (0.75, 0.75, 0.3, 0.1, 0.35), pip_ratio=0.8, dip_ratio=0.5),
        Gesture("thumbs_up", (1.0, 1.0, 1.0, 1.0), _THUMB_UP, pip_ratio=1.15, dip_ratio=0.75),
        Gesture("count_2", (0.0, 0.0, 1.0, 1.0), _THUMB_TUCKED, spread=0.8, pip_ratio=1.15),
        Gesture("count_3", (0.0, 0.0, 0.0, 1.0), _THUMB_TUCKED, spread=0.6, pip_ratio=1.15),
        Gesture("count_4", (0.0, 0.0, 0.0, 0.0), (0.95, 0.2, 0.5, 0.05, 0.5), spread=0.6),
        Gesture("ok", (0.55, 0.05, 0.05, 0.05), (0.7, 0.65, 0.35, 0.1, 0.45), spread=0.5, pip_ratio=1.3),
        Gesture("rock", (0.0, 1.0, 1.0, 0.0), _THUMB_TUCKED, spread=0.7, pip_ratio=1.15),
        Gesture("call", (1.0, 1.0, 1.0, 0.0), _THUMB_OPEN, spread=0.9, pip_ratio=1.15),
        Gesture("grasp_cylinder", (0.6, 0.65, 0.65, 0.7), (0.6, 0.7, 0.25, 0.0, 0.3), pip_ratio=1.0),
        Gesture("tripod", (0.45, 0.5, 0.9, 0.95), (0.7, 0.6, 0.3, 0.1, 0.4), pip_ratio=0.9, dip_ratio=0.5),
    )
}
GESTURE_ALIASES: dict[str, str] = {"count_1": "point", "count_5": "open", "victory": "count_2"}


# ---------------------------------------------------------------------------------------------
# trajectories
# ---------------------------------------------------------------------------------------------


@dataclass
class GestureTrack:
    """A synthetic UDHM trajectory with its per-frame gesture labels."""

    angles_rad: np.ndarray  # (T, 22)
    labels: list[str]  # (T,) gesture each frame moves to or holds
    holding: np.ndarray  # (T,) bool: True while the gesture is held (not in transition)


def _min_jerk(tau: np.ndarray) -> np.ndarray:
    tau = np.clip(tau, 0.0, 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def key_pose_motion(keys: np.ndarray, frames: int, seed: int, frames_per_move: int = 20) -> np.ndarray:
    """(frames, J) minimum-jerk moves between key poses drawn (with replacement) from `keys` (K, J), one move
    every `frames_per_move` frames, in the keys' own units (e.g. a robot's SDK values and its vendor presets)."""
    rng = np.random.default_rng(seed)
    num_keys = max(2, frames // frames_per_move + 2)
    drawn = np.asarray(keys, dtype=np.float64)[rng.integers(0, len(keys), num_keys)]
    t = np.linspace(0.0, num_keys - 1, frames)
    k = np.minimum(t.astype(int), num_keys - 2)
    s = _min_jerk(t - k)
    return drawn[k] + (drawn[k + 1] - drawn[k]) * s[:, None]


def _smooth_noise(rng: np.random.Generator, num_frames: int, dim: int, width: int, scale: float) -> np.ndarray:
    """Gaussian noise low-passed by a moving average of `width` frames, rescaled to std `scale`."""
    raw = rng.standard_normal((num_frames + width, dim))
    kernel = np.ones(width) / width
    smooth = np.stack([np.convolve(raw[:, d], kernel, mode="valid")[:num_frames] for d in range(dim)], axis=1)
    return smooth / max(float(smooth.std()), 1e-9) * scale


# UDHM slots moved by each finger's onset lag during a transition.
_FINGER_SLOTS: dict[str, list[int]] = {
    "thumb": [UDHM_INDEX[n] for n in _THUMB_JOINTS],
    **{f: [UDHM_INDEX[f"{f}_{j}"] for j in ("mcp_abd", "mcp_flex", "pip_flex", "dip_flex")] for f in LONG_FINGERS},
}
_FINGER_SLOTS["pinky"].append(UDHM_INDEX["pinky_metacarpal_twist"])


def gesture_track(
    rng: np.random.Generator,
    num_frames: int,
    fps: float,
    gestures: list[str] | None = None,
    noise_rad: float = 0.01,
) -> GestureTrack:
    """A (num_frames, 22) UDHM trajectory through random named gestures (see module docstring)."""
    if num_frames < 1:
        raise ValueError(f"num_frames must be >= 1, got {num_frames}")
    names = list(gestures) if gestures else list(GESTURES)
    unknown = [n for n in names if n not in GESTURES and n not in GESTURE_ALIASES]
    if unknown:
        raise ValueError(f"unknown gestures {unknown}; known: {sorted(GESTURES)} and aliases {GESTURE_ALIASES}")
    names = [GESTURE_ALIASES.get(n, n) for n in names]

    tempo = rng.uniform(0.75, 1.35)  # per-episode speed: slow and fast performers
    angles = np.zeros((num_frames, UDHM_DIM))
    labels: list[str] = []
    holding = np.zeros(num_frames, dtype=bool)

    current_name = str(rng.choice(names))
    current = GESTURES[current_name].angles_rad()
    frame = 0
    # start mid-hold of the first gesture
    hold = max(1, int(rng.uniform(0.2, 0.8) * tempo * fps))
    while frame < num_frames:
        n = min(hold, num_frames - frame)
        angles[frame : frame + n] = current
        labels += [current_name] * n
        holding[frame : frame + n] = True
        frame += n
        if frame >= num_frames:
            break
        # next gesture: a different one, with per-visit amplitude jitter
        choices = [g for g in names if g != current_name] or names
        target_name = str(rng.choice(choices))
        target = GESTURES[target_name].angles_rad() * rng.uniform(0.9, 1.05)
        target += rng.normal(0.0, 0.03, UDHM_DIM)
        duration = max(2, int(rng.uniform(0.35, 0.8) * tempo * fps))
        lags = {f: rng.uniform(0.0, 0.25) for f in _FINGER_SLOTS}  # fingers start at slightly different times
        n = min(duration, num_frames - frame)
        tau = np.arange(1, n + 1)[:, None] / duration
        block = np.repeat(current[None], n, axis=0)
        for finger, slots in _FINGER_SLOTS.items():
            s = _min_jerk((tau - lags[finger]) / (1.0 - lags[finger]))  # (n, 1)
            block[:, slots] = current[slots] + s * (target[slots] - current[slots])
        angles[frame : frame + n] = block
        labels += [target_name] * n
        frame += n
        current, current_name = target, target_name
        hold = max(1, int(rng.uniform(0.3, 1.1) * tempo * fps))

    width = max(2, int(0.3 * fps))
    angles += _smooth_noise(rng, num_frames, UDHM_DIM, width, 2.0 * noise_rad)  # slow drift
    angles += rng.normal(0.0, noise_rad * 0.3, angles.shape)  # sensor noise
    angles = clip_to_limits(angles)  # noise must not push joints past anatomical limits
    return GestureTrack(angles_rad=angles, labels=labels, holding=holding)


# ---------------------------------------------------------------------------------------------
# wrist motion
# ---------------------------------------------------------------------------------------------


def _rotation_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """(T, 3) axis-angle -> (T, 3, 3) rotation matrices (Rodrigues)."""
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)  # (T, 1)
    axis = rotvec / np.maximum(angle, 1e-12)
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    zero = np.zeros_like(x)
    k = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(-1, 3, 3)
    a = angle[..., None]  # (T, 1, 1)
    return np.eye(3)[None] + np.sin(a) * k + (1.0 - np.cos(a)) * (k @ k)


def wrist_track(
    rng: np.random.Generator, num_frames: int, fps: float, base_position_m: np.ndarray, base_rotvec: np.ndarray
) -> np.ndarray:
    """(T, 4, 4) smooth wrist poses wandering a few cm and some degrees around a base pose."""
    width = max(2, int(0.8 * fps))
    position = base_position_m[None] + _smooth_noise(rng, num_frames, 3, width, 0.04)
    rotvec = base_rotvec[None] + _smooth_noise(rng, num_frames, 3, width, 0.25)
    pose = np.tile(np.eye(4), (num_frames, 1, 1))
    pose[:, :3, :3] = _rotation_from_rotvec(rotvec)
    pose[:, :3, 3] = position
    return pose
