"""Inverse kinematics on FK-generated hands: exact round trip, invariances, masks, chunks, errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lerobot_unidextok import udhm


def _random_wrist(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    return Rotation.random(n, random_state=int(rng.integers(1 << 31))).as_matrix(), rng.normal(scale=0.5, size=(n, 3))


def test_fk_ik_fk_round_trip_recovers_angles_and_keypoints(rng):
    n = 3000
    angles = udhm.sample_angles(rng, (n,))
    sk = udhm.Skeleton.default().scaled(1.1)
    rot, pos = _random_wrist(rng, n)
    kp = udhm.forward_kinematics(angles, sk, (rot, pos))
    res = udhm.inverse_kinematics(kp)
    assert np.abs(res.angles_rad - angles).max() < 1e-4  # rad
    assert np.abs(res.keypoints_m() - kp).max() < 1e-6  # 1e-3 mm
    np.testing.assert_allclose(res.wrist_rotation, rot, atol=1e-9)
    np.testing.assert_allclose(res.wrist_position_m, pos, atol=1e-12)
    assert res.residual_m.max() < 1e-6
    assert not res.limit_violations.any()
    # the documented public one-liner reproduces the input too
    again = udhm.forward_kinematics(res.angles_rad, res.skeleton, (res.wrist_rotation, res.wrist_position_m))
    np.testing.assert_allclose(again, kp, atol=1e-6)


def test_round_trip_with_a_fixed_skeleton(rng):
    angles = udhm.sample_angles(rng, (200,))
    sk = udhm.Skeleton.default()
    rot, pos = _random_wrist(rng, 200)
    kp = udhm.forward_kinematics(angles, sk, (rot, pos))
    res = udhm.inverse_kinematics(kp, skeleton=sk)
    assert res.skeleton is sk
    assert np.abs(res.angles_rad - angles).max() < 1e-4
    np.testing.assert_allclose(res.wrist_rotation, rot, atol=1e-9)


def test_left_hands_round_trip_in_their_own_frame_and_mirror_the_right(rng):
    n = 300
    angles = udhm.sample_angles(rng, (n,))
    rot, pos = _random_wrist(rng, n)
    kp_left = udhm.forward_kinematics(angles, None, (rot, pos), side="left")
    res = udhm.inverse_kinematics(kp_left, side="left")
    assert res.side == "left"
    assert np.abs(res.angles_rad - angles).max() < 1e-4
    np.testing.assert_allclose(res.keypoints_m(), kp_left, atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(res.wrist_rotation), 1.0, atol=1e-9)  # proper rotations
    # mirror symmetry: a right hand reflected in any plane is a left hand with the same angles
    kp_right = udhm.forward_kinematics(angles, None, (rot, pos))
    reflect = np.diag([1.0, 1.0, -1.0])
    mirrored = udhm.inverse_kinematics(kp_right @ reflect, side="left")
    np.testing.assert_allclose(mirrored.angles_rad, udhm.inverse_kinematics(kp_right).angles_rad, atol=1e-9)


def _non_default_skeleton(rng: np.random.Generator) -> udhm.Skeleton:
    """A canonical skeleton unlike the default (scaled, each bone stretched differently)."""
    base = udhm.Skeleton.default()
    stretch = rng.uniform(0.85, 1.2, size=(5, 3))
    return udhm.Skeleton(base.palm_offsets_m * 1.07, base.bone_lengths_m * stretch).canonicalized()


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("mode", ["per_frame", "fixed", "sequence"])
def test_round_trip_every_side_and_skeleton_mode(rng, side, mode):
    """FK -> IK -> FK is exact for both sides with a measured, a given and a sequence skeleton.

    Catches: the left-hand mirror dropped in the fixed-skeleton palm fit (`_kabsch_palm`), which gives
    ~145 deg errors on left hands with a given skeleton while the per-frame path stays right; a given
    skeleton ignored (the default used instead); a left sequence skeleton measured in the right frame."""
    n = 150
    angles = udhm.sample_angles(rng, (n,))
    truth = _non_default_skeleton(rng)
    rot, pos = _random_wrist(rng, n)
    kp = udhm.forward_kinematics(angles, truth, (rot, pos), side=side)
    skeleton = {"per_frame": None, "fixed": truth,
                "sequence": udhm.Skeleton.from_keypoints(kp, per_frame=False, side=side)}[mode]  # fmt: skip
    res = udhm.inverse_kinematics(kp, side=side, skeleton=skeleton)
    assert res.side == side
    assert np.abs(res.angles_rad - angles).max() < 1e-4  # rad
    assert np.abs(res.keypoints_m() - kp).max() < 1e-6  # m
    np.testing.assert_allclose(res.wrist_rotation, rot, atol=1e-8)
    np.testing.assert_allclose(res.wrist_position_m, pos, atol=1e-10)
    if mode != "per_frame":
        np.testing.assert_allclose(res.skeleton.bone_lengths_m, truth.bone_lengths_m, atol=1e-9)


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("mode", ["per_frame", "fixed"])
def test_analytic_initialisation_alone_is_exact_on_exact_keypoints(rng, side, mode):
    """With `iterations=0` (no Levenberg-Marquardt) the analytic initialisation already recovers the angles
    of noise-free FK keypoints (measured: ~1e-11 rad). Catches bugs in the initialisation that the 100 LM
    iterations of the round-trip tests hide (they only cost iterations): the abduction branch fold of
    `_abd_flex` (|abd| <= pi/2), the thumb-MCP abduction slot (the only active `abd2`), and the twin choice
    of `_best_branch` (a twin outside the joint limits)."""
    n = 400
    angles = udhm.sample_angles(rng, (n,))
    truth = _non_default_skeleton(rng)
    rot, pos = _random_wrist(rng, n)
    kp = udhm.forward_kinematics(angles, truth, (rot, pos), side=side)
    res = udhm.inverse_kinematics(kp, side=side, skeleton=truth if mode == "fixed" else None, iterations=0)
    assert np.abs(res.angles_rad - angles).max() < 1e-8  # rad


@pytest.mark.parametrize("lead", [(), (5,), (2, 3)])
def test_batch_shapes(rng, lead):
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, lead))
    res = udhm.inverse_kinematics(kp)
    assert res.angles_rad.shape == (*lead, 22)
    assert res.wrist_rotation.shape == (*lead, 3, 3)
    assert res.wrist_position_m.shape == (*lead, 3)
    assert res.residual_m.shape == lead
    assert res.limit_violations.shape == (*lead, 22)
    assert res.skeleton.batch_shape == lead
    assert res.keypoints_m().shape == (*lead, 21, 3)


def test_chunking_gives_identical_results(rng):
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (103,)))
    kp = kp + rng.normal(scale=0.002, size=kp.shape)  # noisy, so the fit is not exact
    whole = udhm.inverse_kinematics(kp)
    chunked = udhm.inverse_kinematics(kp, chunk_size=10, progress=False)
    np.testing.assert_array_equal(chunked.angles_rad, whole.angles_rad)
    np.testing.assert_array_equal(chunked.residual_m, whole.residual_m)
    single = udhm.inverse_kinematics(kp[:4], chunk_size=1, progress=False)  # the smallest chunk is allowed
    np.testing.assert_array_equal(single.angles_rad, whole.angles_rad[:4])


def test_noisy_keypoints_fit_denoises_with_a_sequence_skeleton(rng):
    angles = udhm.sample_angles(rng, (500,), margin=0.1)
    kp = udhm.forward_kinematics(angles)
    noisy = kp + rng.normal(scale=0.001, size=kp.shape)  # 1 mm per coordinate
    noise_m = np.linalg.norm(noisy - kp, axis=-1).mean()
    per_frame = udhm.inverse_kinematics(noisy)
    assert per_frame.residual_m.mean() < noise_m  # least squares never fits worse than the truth
    seq = udhm.inverse_kinematics(noisy, skeleton=udhm.Skeleton.from_keypoints(noisy, per_frame=False))
    # with one skeleton for the sequence, FK(IK(noisy)) is closer to the clean hand than the input was
    assert np.linalg.norm(seq.keypoints_m() - kp, axis=-1).mean() < 0.9 * noise_m
    assert np.abs(udhm.clip_to_limits(seq.angles_rad) - seq.angles_rad).max() < np.radians(0.5)


def test_rotation_and_translation_invariance(rng):
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (20,)))
    kp = kp + rng.normal(scale=0.002, size=kp.shape)
    rot = Rotation.random(random_state=7).as_matrix()
    a = udhm.inverse_kinematics(kp).angles_rad
    b = udhm.inverse_kinematics(kp @ rot.T + np.array([1.0, -2.0, 0.5])).angles_rad
    np.testing.assert_allclose(a, b, atol=1e-7)


def test_missing_frames_need_a_mask(rng):
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (4, 6)))
    kp[1, 2, 7] = np.nan
    kp[3, 0, 0, 1] = np.inf
    with pytest.raises(ValueError, match=r"NaN/inf in frames \[\(1, 2\), \(3, 0\)\].*mask"):
        udhm.inverse_kinematics(kp)
    mask = np.isfinite(kp).all(axis=(-1, -2))
    res = udhm.inverse_kinematics(kp, mask=mask)
    assert np.isnan(res.angles_rad[1, 2]).all() and np.isnan(res.angles_rad[3, 0]).all()
    assert np.isnan(res.residual_m[~mask]).all() and np.isnan(res.wrist_rotation[~mask]).all()
    assert np.isfinite(res.angles_rad[mask]).all()
    assert np.isfinite(res.skeleton.bone_lengths_m).all()  # missing frames borrow the median skeleton
    bad_mask = mask.copy()
    bad_mask[1, 2] = True
    with pytest.raises(ValueError, match=r"\[\(1, 2\)\] that mask marks present"):
        udhm.inverse_kinematics(kp, mask=bad_mask)
    with pytest.raises(ValueError, match="mask must be a bool array"):
        udhm.inverse_kinematics(kp, mask=mask.astype(int))


def test_bad_input_errors(rng):
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (3,)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 21, 3\)"):
        udhm.inverse_kinematics(kp[:, :20])
    with pytest.raises(ValueError, match=r"\(\.\.\., 21, 3\)"):
        udhm.inverse_kinematics(kp.reshape(3, 63))
    with pytest.raises(ValueError, match="unknown side"):
        udhm.inverse_kinematics(kp, side="both")
    dup = kp.copy()
    dup[2, 7] = dup[2, 6]  # index DIP on top of PIP
    with pytest.raises(ValueError, match=r"zero-length bones .*frames \[2\]"):
        udhm.inverse_kinematics(dup)
    flat = kp.copy()
    flat[1] = 0.0
    with pytest.raises(ValueError, match=r"frames \[1\]"):
        udhm.inverse_kinematics(flat)
    with pytest.raises(ValueError, match="does not broadcast"):
        udhm.inverse_kinematics(kp, skeleton=udhm.Skeleton.from_keypoints(kp[:2]))


def test_float32_input_and_many_chunks(rng):
    angles = udhm.sample_angles(rng, (40,))
    kp = udhm.forward_kinematics(angles).astype(np.float32)
    res = udhm.inverse_kinematics(kp, chunk_size=7, progress=False)
    assert res.angles_rad.dtype == np.float64
    # float32 rounding (~1e-8 m) limits the recovery, not the solver
    assert np.abs(res.angles_rad - angles).max() < 1e-3
    assert res.residual_m.max() < 1e-6
