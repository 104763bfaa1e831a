"""The IK's building blocks against their stated contracts, written from first principles.

The round-trip tests in test_ik.py cannot see these bugs: the Levenberg-Marquardt loop converges (more
slowly) with a slightly wrong Jacobian, and the twin choice by joint limits absorbs a wrong branch fold.
"""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok.udhm import Skeleton
from lerobot_unidextok.udhm.fk import AXIAL_PRONATION_RAD, CHAIN_ACTIVE
from lerobot_unidextok.udhm.ik import SLOT_LIMITS_RAD, _abd_flex, _best_branch, _residuals


def _blocks(rng: np.random.Generator, n: int, spread_rad: float):
    """n frames x 5 fingers as (M, ...) blocks, M = 5n: random slots, a random target, the default skeleton."""
    sk = Skeleton.default()
    m = 5 * n
    act = np.broadcast_to(CHAIN_ACTIVE, (n, 5, 6)).reshape(m, 6)
    slots = np.where(act, rng.uniform(-spread_rad, spread_rad, size=(m, 6)), 0.0)
    return dict(
        slots=slots,
        target=rng.normal(scale=0.05, size=(m, 3, 3)),
        offsets=np.broadcast_to(np.asarray(sk.palm_offsets_m), (n, 5, 3)).reshape(m, 3),
        bones=np.broadcast_to(np.asarray(sk.bone_lengths_m), (n, 5, 3)).reshape(m, 3),
        pron=np.broadcast_to(AXIAL_PRONATION_RAD, (n, 5)).reshape(m),
        active=act,
        lo=np.broadcast_to(SLOT_LIMITS_RAD[..., 0], (n, 5, 6)).reshape(m, 6),
        hi=np.broadcast_to(SLOT_LIMITS_RAD[..., 1], (n, 5, 6)).reshape(m, 6),
    )


@pytest.mark.parametrize("spread_rad", [0.5, 3.0])  # inside the limits / well outside many of them
def test_residual_jacobian_matches_central_differences(rng, spread_rad):
    """Catches any wrong axis, sign or pivot in the geometric Jacobian (e.g. the twist column starting at
    the PIP instead of the MCP: `(twist_axis, 0, 0)` -> `(twist_axis, 0, 1)`), and a limit row that is off."""
    b = _blocks(rng, 20, spread_rad)
    weight = 0.7

    def res(slots):
        r, _ = _residuals(slots, b["target"], b["offsets"], b["bones"], b["pron"], b["active"], b["lo"], b["hi"],
                          weight, False)  # fmt: skip
        return r

    _, jac = _residuals(b["slots"], b["target"], b["offsets"], b["bones"], b["pron"], b["active"], b["lo"], b["hi"],
                        weight, True)  # fmt: skip
    assert jac.shape == (100, 15, 6)
    h = 1e-6
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        numeric = (res(b["slots"] + e) - res(b["slots"] - e)) / (2 * h)  # (M, 15)
        act = b["active"][:, j]
        # keypoint rows: the derivative where the slot is a real DoF, zero (held fixed) where it is not
        np.testing.assert_allclose(jac[act, :9, j], numeric[act, :9], atol=1e-7)
        assert not jac[~act, :9, j].any()
        # limit rows: limit_weight on the slot's own row exactly where it is outside its limits
        outside = (b["slots"][:, j] < b["lo"][:, j]) | (b["slots"][:, j] > b["hi"][:, j])
        np.testing.assert_allclose(jac[:, 9 + j, j], weight * outside)
        np.testing.assert_allclose(jac[act, 9:, j], numeric[act, 9:], atol=1e-7)
    if spread_rad > 1:
        assert (b["slots"] > b["hi"]).any() and (b["slots"] < b["lo"]).any()  # both limit branches ran


def test_abd_flex_inverts_the_joint_rotation_on_the_half_plane_branch(rng):
    """_abd_flex(d) = (a, f) with Rot_x(-a) Rot_y(f) e_z = d and |a| <= pi/2, for directions all round the
    sphere. Rot_y(f) e_z = (sin f, 0, cos f); Rot_x(-a) maps it to (sin f, sin a cos f, cos a cos f).
    Catches a fold of the abduction at the wrong angle (pi/3 instead of pi/2: |a| > pi/2 comes out) and a
    flexion that ignores the fold."""
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    a, f = _abd_flex(d)
    assert np.abs(a).max() <= np.pi / 2 + 1e-12
    assert np.abs(a).max() > 1.5  # the sample reaches the fold
    rebuilt = np.stack([np.sin(f), np.sin(a) * np.cos(f), np.cos(a) * np.cos(f)], axis=-1)
    np.testing.assert_allclose(rebuilt, d, atol=1e-12)


def test_best_branch_turns_a_twin_back_into_the_in_limit_solution(rng):
    """Rot_x(-a) Rot_y(f) = Rot_x(-(a + pi)) Rot_y(pi - f) Rot_z(pi): the twin of the first 2-DoF joint (a + pi,
    pi - f, every later slot negated) poses the finger identically. Given that twin of an in-limit pose,
    `_best_branch` must return the in-limit pose, and both must give the same keypoints. Catches a twin
    built from the wrong slot (`c[..., j + 1]` -> `c[..., j + 2]`) or without the later sign flip."""
    from lerobot_unidextok.udhm.fk import finger_chain
    from lerobot_unidextok.udhm.ik import _wrap

    n = 200
    lo, hi = SLOT_LIMITS_RAD[..., 0], SLOT_LIMITS_RAD[..., 1]  # (5, 6)
    lo_f, hi_f = np.where(np.isfinite(lo), lo, 0.0), np.where(np.isfinite(hi), hi, 0.0)
    pad = 0.05 * (hi_f - lo_f)
    q = np.where(CHAIN_ACTIVE, rng.uniform(lo_f + pad, hi_f - pad, size=(n, 5, 6)), 0.0)  # inside the limits
    twin = q.copy()
    twin[..., 1] = _wrap(q[..., 1] + np.pi)
    twin[..., 2] = _wrap(np.pi - q[..., 2])
    twin[..., 3:] = -q[..., 3:]
    sk = Skeleton.default()
    off = np.broadcast_to(np.asarray(sk.palm_offsets_m), (n, 5, 3))
    bones = np.broadcast_to(np.asarray(sk.bone_lengths_m), (n, 5, 3))
    pose = finger_chain(q, off, bones, AXIAL_PRONATION_RAD).points
    np.testing.assert_allclose(finger_chain(twin, off, bones, AXIAL_PRONATION_RAD).points, pose, atol=1e-12)
    best = _best_branch(twin, slice(None))
    np.testing.assert_allclose(_wrap(best - q), 0.0, atol=1e-12)
