"""IK on real tracked human hands (../shared/data/real; skipped when absent).

Figures measured at commit time (`pytest tests/udhm/test_ik_real.py`, default IK settings):
- dex-retargeting `human_joint_right.npy`, 621 MediaPipe frames, per-frame skeleton:
  mean keypoint error 1.20 mm (fingertips 1.59 mm, worst frame mean 3.4 mm), 0 joint-limit
  violations > 1e-3 rad (largest excess 0.04 deg), solved as a left hand instead: 3.80 mm.
- MediaPipe gesture world landmarks: mean errors 1.35-2.81 mm, 0 violations.
The bounds below sit slightly above these figures; the semantic checks use anatomical thresholds.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_unidextok import udhm
from lerobot_unidextok.udhm.joints import joint_index

CLIP_MEAN_ERROR_BOUND_M = 0.0013  # achieved 1.20 mm; issue target <= 2 mm
CLIP_VIOLATION_BOUND = 7  # entries > 1e-3 rad outside the limits (of 621 x 22); achieved 0
CURLED_RAD = np.radians(120.0)  # MCP + PIP + DIP flexion of a curled finger (a fist is ~ 200-260 deg)
EXTENDED_RAD = np.radians(45.0)  # ... of an extended finger


@pytest.fixture(scope="module")
def clip(real_data_dir) -> np.ndarray:
    return np.load(real_data_dir / "dex-retargeting" / "human_joint_right.npy")


@pytest.fixture(scope="module")
def gestures(real_data_dir) -> dict[str, np.ndarray]:
    raw = json.loads((real_data_dir / "mediapipe" / "mediapipe_hand_fixtures.json").read_text())
    return {
        name.removesuffix("_landmarks.pbtxt"): np.asarray(v["world_landmarks_m"], dtype=np.float64)
        for name, v in raw.items()
        if isinstance(v, dict) and "world_landmarks_m" in v
    }


def _total_flex(angles_rad: np.ndarray, finger: str) -> float:
    return float(sum(angles_rad[joint_index(f"{finger}_{j}_flex")] for j in ("mcp", "pip", "dip")))


def test_clip_reconstruction_error_and_limits(clip):
    assert clip.shape == (621, 21, 3)
    res = udhm.inverse_kinematics(clip)
    err_m = np.linalg.norm(res.keypoints_m() - clip, axis=-1)  # (621, 21)
    assert err_m.mean() <= CLIP_MEAN_ERROR_BOUND_M
    np.testing.assert_allclose(res.residual_m, err_m.mean(-1), atol=1e-12)
    assert err_m[:, [0, 1, 5, 9, 13, 17]].max() < 1e-9  # rigid palm measured per frame is exact
    assert int(res.limit_violations.sum()) <= CLIP_VIOLATION_BOUND
    # the clip is a right hand: the right model explains it much better than the mirrored one
    assert udhm.inverse_kinematics(clip, side="left").residual_m.mean() > 2 * err_m.mean()


def test_clip_angles_are_smooth_in_time(clip):
    """30 fps video: a well-posed IK gives small frame-to-frame angle changes for most frames."""
    angles = udhm.inverse_kinematics(clip).angles_rad
    step = np.abs(np.diff(angles, axis=0))
    assert np.median(step) < np.radians(2.0)  # achieved 0.78 deg


def test_gestures_fit_in_camera_frame(gestures):
    assert set(gestures) >= {"fist", "pointing_up", "victory", "thumb_up"}
    kp = np.stack(list(gestures.values()))  # (6, 21, 3) camera axes, origin not at the wrist
    assert np.linalg.norm(kp[:, 0], axis=-1).min() > 0.02
    res = udhm.inverse_kinematics(kp)
    assert res.residual_m.max() < 0.0035  # achieved <= 2.81 mm
    assert not res.limit_violations.any()
    np.testing.assert_allclose(res.wrist_position_m, kp[:, 0])
    assert (udhm.inverse_kinematics(kp, side="left").residual_m > res.residual_m).all()


def test_gesture_semantics(gestures):
    names = list(gestures)
    res = udhm.inverse_kinematics(np.stack([gestures[n] for n in names]))
    angles = dict(zip(names, res.angles_rad, strict=True))
    fingers = ("index", "middle", "ring", "pinky")
    for f in fingers:
        assert _total_flex(angles["fist"], f) > CURLED_RAD, f
        assert _total_flex(angles["thumb_up"], f) > CURLED_RAD, f
    assert _total_flex(angles["pointing_up"], "index") < EXTENDED_RAD
    for f in ("middle", "ring", "pinky"):
        assert _total_flex(angles["pointing_up"], f) > CURLED_RAD, f
    for f in ("index", "middle"):
        assert _total_flex(angles["victory"], f) < EXTENDED_RAD, f
    for f in ("ring", "pinky"):
        assert _total_flex(angles["victory"], f) > CURLED_RAD, f
    # thumb: folded over the fingers in a fist, straight in thumbs-up
    thumb = [joint_index("thumb_mcp_flex"), joint_index("thumb_ip_flex")]
    assert angles["fist"][thumb].sum() > angles["thumb_up"][thumb].sum() + np.radians(45.0)
    # the V of the victory sign: index and middle spread apart
    spread = angles["victory"][joint_index("index_mcp_abd")] - angles["victory"][joint_index("middle_mcp_abd")]
    assert spread > np.radians(5.0)  # achieved 8 deg (MediaPipe estimate)


def test_rotated_photo_gives_the_same_angles(gestures):
    """`_rotated` fixtures are the same photo rotated: angles must not depend on the camera frame."""
    for name in ("pointing_up", "thumb_up"):
        a = udhm.inverse_kinematics(gestures[name]).angles_rad
        b = udhm.inverse_kinematics(gestures[f"{name}_rotated"]).angles_rad
        assert np.abs(a - b).max() < np.radians(10.0), name  # tracker noise; achieved 3.3 / 3.6 deg
