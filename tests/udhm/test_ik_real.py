"""IK on real tracked human hands (../shared/data/real; skipped when absent).

Figures measured at commit time (`pytest tests/udhm/test_ik_real.py`, default IK settings):
- dex-retargeting `human_joint_right.npy`, 621 MediaPipe frames, per-frame skeleton:
  mean keypoint error 1.21 mm (fingertips 1.62 mm, worst frame mean 3.0 mm), 1 joint-limit
  violation > 1e-3 rad (ring MCP abduction of a flexed finger, excess 0.07 deg), solved as a left
  hand instead: 3.84 mm. (With z = wrist -> middle MCP, before the knuckle-row frame: 1.20 mm, 0
  violations, largest excess 0.04 deg; the clip's ring finger reaches both of its abduction limits.)
- MediaPipe gesture world landmarks: mean errors 1.35-2.82 mm, 0 violations.
- MediaPipe reference landmarks of two open hands (2D): middle MCP abduction -2.4 / +0.2 deg.
The bounds below sit slightly above these figures; the semantic checks use anatomical thresholds.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_unidextok import udhm
from lerobot_unidextok.udhm.joints import joint_index

CLIP_MEAN_ERROR_BOUND_M = 0.0013  # achieved 1.21 mm; issue target <= 2 mm
CLIP_VIOLATION_BOUND = 7  # entries > 1e-3 rad outside the limits (of 621 x 22); achieved 1
CURLED_RAD = np.radians(120.0)  # MCP + PIP + DIP flexion of a curled finger (a fist is ~ 200-260 deg)
EXTENDED_RAD = np.radians(45.0)  # ... of an extended finger
MCP_ABD = [joint_index(f"{f}_mcp_abd") for f in ("index", "middle", "ring", "pinky")]


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


@pytest.fixture(scope="module")
def open_photos(real_data_dir) -> dict[str, np.ndarray]:
    """MediaPipe's reference landmarks of two open left hands (`left_hands.jpg`, pointing up and down): image
    landmarks on the photo's 720 x 382 px grid, no depth, lifted to z = 0 (the palm is the image plane) and
    scaled to a 97 mm wrist -> middle MCP, so each abduction is the angle seen in the photo."""
    raw = json.loads((real_data_dir / "mediapipe" / "mediapipe_hand_fixtures.json").read_text())
    photos = {}
    for view in ("up", "down"):
        px = np.asarray(raw[f"expected_left_{view}_hand_landmarks.prototxt"]["landmarks_2d_normalized"]) * (720, 382)
        kp = np.concatenate([px, np.zeros((21, 1))], axis=1)
        photos[view] = kp * 0.097 / np.linalg.norm(kp[9] - kp[0])
    return photos


def _total_flex(angles_rad: np.ndarray, finger: str) -> np.ndarray:
    """MCP + PIP + DIP flexion (rad) of a finger, (...) for angles (..., 22)."""
    return sum(angles_rad[..., joint_index(f"{finger}_{j}_flex")] for j in ("mcp", "pip", "dip"))


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
    assert np.median(step) < np.radians(2.0)  # achieved 0.80 deg


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


def test_open_hands_in_mediapipe_photos_read_the_middle_finger_near_zero(open_photos):
    """Issue 24: the middle finger of an open hand reads ~0. With z = wrist -> middle MCP these photos read
    -12.4 / -9.4 deg (MediaPipe's wrist landmark is not on the middle finger's line); achieved -2.4 / +0.2."""
    for view, kp in open_photos.items():
        abd = np.degrees(udhm.inverse_kinematics(kp, side="left").angles_rad[MCP_ABD])
        assert abs(abd[1]) < 4.0, view
        assert abd[0] > abd[1] > abd[2] > abd[3], view  # an open hand's fan: index to the thumb side, pinky away


def test_clip_abductions_do_not_follow_the_wrist_landmark(clip):
    """The wrist landmark moved 1 cm toward the little finger in the palm plane (+y of the clip's own frame is
    the thumb side, see ../shared/data/real/README.md), as trackers that put it on the forearm's twist axis do:
    the open-hand abductions stay (achieved: median change 0.04 deg); with z = wrist -> middle MCP they moved
    5.6 deg."""
    moved = clip.copy()
    moved[:, 0, 1] -= 0.01
    before, after = udhm.inverse_kinematics(clip).angles_rad, udhm.inverse_kinematics(moved).angles_rad
    extended = np.stack([_total_flex(before, f) < EXTENDED_RAD for f in ("index", "middle", "ring", "pinky")], -1)
    open_frames = extended.all(-1)
    assert open_frames.sum() >= 30  # achieved 63 of 621
    change_deg = np.degrees(np.abs(after[open_frames][:, MCP_ABD] - before[open_frames][:, MCP_ABD]))
    assert np.median(change_deg) < 0.3
