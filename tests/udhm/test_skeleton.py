"""Skeleton: default, measurement from keypoints, scaling, validation."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok import udhm


def test_default_is_canonical_adult():
    sk = udhm.Skeleton.default()
    assert sk.palm_offsets_m.shape == (5, 3) and sk.bone_lengths_m.shape == (5, 3)
    assert 0.09 < np.linalg.norm(sk.palm_offsets_m[2]) < 0.11  # wrist -> middle MCP ~ 99 mm
    assert abs(sk.palm_offsets_m[1, 2] - sk.palm_offsets_m[3, 2]) < 1e-12  # z is perpendicular to the knuckle row
    y = sk.palm_offsets_m[:, 1]
    assert y[0] > 0 and y[1] > y[2] > y[3] > y[4]  # thumb on the radial side, knuckles in order across the palm
    # re-measuring the default hand gives the default back (it is expressed in its own palm frame)
    again = udhm.Skeleton.from_keypoints(udhm.forward_kinematics(np.zeros(22), sk))
    np.testing.assert_allclose(again.palm_offsets_m, sk.palm_offsets_m, atol=1e-12)
    np.testing.assert_allclose(again.bone_lengths_m, sk.bone_lengths_m, atol=1e-12)


def test_from_keypoints_per_frame_and_per_sequence(rng):
    sk = udhm.Skeleton.default()
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (6, 4)), sk)  # (6, 4, 21, 3)
    per_frame = udhm.Skeleton.from_keypoints(kp)
    assert per_frame.batch_shape == (6, 4)
    np.testing.assert_allclose(per_frame.bone_lengths_m, np.broadcast_to(sk.bone_lengths_m, (6, 4, 5, 3)), atol=1e-12)
    seq = udhm.Skeleton.from_keypoints(kp, per_frame=False)
    assert seq.batch_shape == ()
    np.testing.assert_allclose(seq.palm_offsets_m, sk.palm_offsets_m, atol=1e-12)


def test_from_left_keypoints_gives_the_mirror_right_skeleton(rng):
    sk = udhm.Skeleton.default().scaled(0.9)
    kp_left = udhm.forward_kinematics(udhm.sample_angles(rng, (3,)), sk, side="left")
    got = udhm.Skeleton.from_keypoints(kp_left, side="left")
    np.testing.assert_allclose(got.palm_offsets_m, np.broadcast_to(sk.palm_offsets_m, (3, 5, 3)), atol=1e-12)


def test_scaled():
    sk = udhm.Skeleton.default()
    np.testing.assert_allclose(sk.scaled(1.5).bone_lengths_m, sk.bone_lengths_m * 1.5)
    assert sk.scaled(2.0).hand_length_m() == pytest.approx(2.0 * sk.hand_length_m())
    with pytest.raises(ValueError, match="> 0"):
        sk.scaled(0.0)


def test_validation_errors():
    sk = udhm.Skeleton.default()
    bones = sk.bone_lengths_m.copy()
    bones[1, 2] = 0.0
    with pytest.raises(ValueError, match="zero or negative bone lengths"):
        udhm.Skeleton(sk.palm_offsets_m, bones)
    bones[1, 2] = -0.01
    with pytest.raises(ValueError, match="zero or negative bone lengths"):
        udhm.Skeleton(sk.palm_offsets_m, bones)
    # the bound itself: "every bone must be longer than 1e-6 m" (catches `<=` -> `<` at the boundary)
    bones[1, 2] = 1e-6
    with pytest.raises(ValueError, match="zero or negative bone lengths"):
        udhm.Skeleton(sk.palm_offsets_m, bones)
    bones[1, 2] = 2e-6
    assert udhm.Skeleton(sk.palm_offsets_m, bones).bone_lengths_m[1, 2] == 2e-6
    with pytest.raises(ValueError, match=r"\(\.\.\., 5, 3\)"):
        udhm.Skeleton(sk.palm_offsets_m[:4], sk.bone_lengths_m)
    with pytest.raises(ValueError, match="NaN"):
        udhm.Skeleton(sk.palm_offsets_m * np.nan, sk.bone_lengths_m)
    with pytest.raises(ValueError, match=r"\(\.\.\., 21, 3\)"):
        udhm.Skeleton.from_keypoints(np.zeros((20, 3)))
