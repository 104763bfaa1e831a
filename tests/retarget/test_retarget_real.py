"""Retargeting real human motion onto robot hands with their URDFs (dex-retargeting)."""

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.retarget import HandRetargeter, URDFError, palm_frame


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize("hand", ["linkerhand_l10", "linkerhand_l20", "xhand1", "inspire_rh56_unitree"])
def test_real_clip_onto_robot_hand(hand, urdf_dir, human_clip):
    """A short real human clip (90 frames, 3 s) retargeted onto a robot hand: the robot's wrist-to-fingertip
    vectors follow the human ones within a few centimetres, the robot fingers flex when the human's do, and
    the result is the hand spec's native units and UDHM state."""
    kp = human_clip[:90]
    res = HandRetargeter(hand, urdf_dir, "right").retarget(kp)
    spec = hands.get(hand)
    assert res.native.shape == (90, spec.num_native) and res.udhm_rad.shape == (90, 22)
    lo, hi = spec.raw_range("right").T
    assert (res.native >= lo - 1e-6).all() and (res.native <= hi + 1e-6).all()
    np.testing.assert_allclose(res.udhm_rad, np.asarray(spec.to_udhm(res.native, "right")), atol=1e-9)
    assert (res.udhm_rad[:, ~spec.active_mask] == 0).all()
    assert res.mean_target_error_mm < 30.0, res.target_error_mm.mean(0)
    human = np.asarray(hands.get("human").to_udhm(kp, "right"))
    moving = 0
    for finger in ("index", "middle", "ring", "pinky"):
        h = human[:, UDHM_INDEX[f"{finger}_mcp_flex"]] + human[:, UDHM_INDEX[f"{finger}_pip_flex"]]
        if h.std() < 0.3:  # this finger hardly moves in these 3 s: its correlation would be noise
            continue
        moving += 1
        r = res.udhm_rad[:, UDHM_INDEX[f"{finger}_mcp_flex"]]
        assert np.corrcoef(h, r)[0, 1] > 0.5, (finger, np.corrcoef(h, r)[0, 1])
    assert moving >= 1


def test_result_does_not_depend_on_the_keypoint_frame(urdf_dir, human_clip):
    """Keypoints in a rotated and shifted frame (a camera frame) give the same robot motion: the palm frames
    are matched per frame, not assumed (catches a retargeter that uses raw coordinates)."""
    kp = human_clip[100:130]
    moved = kp @ _rotation(3).T + np.array([0.3, -0.2, 1.1])
    r = HandRetargeter("xhand1", urdf_dir, "right")
    a, b = r.retarget(kp), r.retarget(moved)
    np.testing.assert_allclose(a.urdf_qpos_rad, b.urdf_qpos_rad, atol=2e-3)


def test_palm_frame_is_a_rotation_and_equivariant():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(4, 3))
    f = palm_frame(*pts)
    np.testing.assert_allclose(f.T @ f, np.eye(3), atol=1e-12)
    assert np.linalg.det(f) == pytest.approx(1.0)
    rot = _rotation(1)
    np.testing.assert_allclose(palm_frame(*(pts @ rot.T)), rot @ f, atol=1e-12)


def test_left_hand_and_missing_urdf(urdf_dir, human_clip, tmp_path):
    """The left side has its own URDF and joint names; a folder without the file is a clear error."""
    mirrored = human_clip[:20] * np.array([1.0, -1.0, 1.0])  # a left hand (mirror image of the right)
    res = HandRetargeter("inspire_rh56_unitree", urdf_dir, "left").retarget(mirrored)
    assert res.urdf_joint_names[0].startswith("L_") and res.mean_target_error_mm < 40.0
    with pytest.raises(URDFError, match="no linkerhand_l10_right.urdf under"):
        HandRetargeter("linkerhand_l10", tmp_path, "right")
    with pytest.raises(ValueError, match="MANO-21 keypoints"):
        HandRetargeter("xhand1", urdf_dir, "right").retarget(human_clip[:5, :20])
