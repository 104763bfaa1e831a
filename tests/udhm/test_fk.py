"""Forward kinematics: zero pose, sign conventions, batching, numpy/torch agreement, gradients, errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from lerobot_unidextok import udhm
from lerobot_unidextok.constants import FINGERTIP_INDICES, KEYPOINT_PARENTS
from lerobot_unidextok.udhm.joints import joint_index


def test_zero_pose_is_flat_hand_fingers_together():
    sk = udhm.Skeleton.default()
    kp = udhm.forward_kinematics(np.zeros(22), sk)  # (21, 3)
    assert kp.shape == (21, 3)
    np.testing.assert_allclose(kp[0], 0.0)
    for f in range(5):
        chain = kp[1 + 4 * f : 5 + 4 * f]
        # straight along +z from the base, no sideways or palmar drift
        np.testing.assert_allclose(chain[:, :2], np.repeat(chain[:1, :2], 4, axis=0), atol=1e-12)
        np.testing.assert_allclose(np.diff(chain[:, 2]), sk.bone_lengths_m[f], atol=1e-12)


def test_bone_lengths_are_preserved_for_any_pose(rng):
    sk = udhm.Skeleton.default()
    kp = udhm.forward_kinematics(udhm.sample_angles(rng, (64,)), sk)  # (64, 21, 3)
    seg = np.linalg.norm(kp[:, 1:] - kp[:, list(KEYPOINT_PARENTS[1:])], axis=-1).reshape(64, 5, 4)
    np.testing.assert_allclose(seg[..., 1:], np.broadcast_to(sk.bone_lengths_m, (64, 5, 3)), atol=1e-12)
    np.testing.assert_allclose(kp[:, [1, 5, 9, 13, 17]], np.broadcast_to(sk.palm_offsets_m, (64, 5, 3)), atol=1e-12)


@pytest.mark.parametrize("finger", ["index", "middle", "ring", "pinky"])
def test_flexion_moves_toward_palm_and_abduction_toward_thumb(finger):
    base = udhm.forward_kinematics(np.zeros(22))
    tip = FINGERTIP_INDICES[["thumb", "index", "middle", "ring", "pinky"].index(finger)]
    q = np.zeros(22)
    q[joint_index(f"{finger}_mcp_flex")] = 0.5
    assert udhm.forward_kinematics(q)[tip, 0] > base[tip, 0] + 0.02  # +x = palmar side
    q = np.zeros(22)
    q[joint_index(f"{finger}_mcp_abd")] = 0.3
    assert udhm.forward_kinematics(q)[tip, 1] > base[tip, 1] + 0.01  # +y = thumb side


def test_thumb_conventions():
    base = udhm.forward_kinematics(np.zeros(22))
    q = np.zeros(22)
    q[joint_index("thumb_cmc_flex")] = 0.6  # out of the palm plane, palm side
    assert udhm.forward_kinematics(q)[4, 0] > base[4, 0] + 0.03
    q = np.zeros(22)
    q[joint_index("thumb_cmc_spread")] = 0.6  # in the palm plane, away from the index
    tip = udhm.forward_kinematics(q)[4]
    assert tip[1] > base[4, 1] + 0.03 and abs(tip[0] - base[4, 0]) < 1e-9
    q = np.zeros(22)
    q[joint_index("thumb_ip_flex")] = 0.8  # across the palm toward the little finger
    assert udhm.forward_kinematics(q)[4, 1] < base[4, 1] - 0.015


def test_pinky_twist_keeps_mcp_and_cups_toward_thumb():
    q = np.zeros(22)
    q[joint_index("pinky_mcp_flex")] = 1.0
    flexed = udhm.forward_kinematics(q)
    q[joint_index("pinky_metacarpal_twist")] = 0.4
    cupped = udhm.forward_kinematics(q)
    np.testing.assert_allclose(cupped[17], flexed[17], atol=1e-12)
    assert cupped[20, 1] > flexed[20, 1] + 0.005


@pytest.mark.parametrize("lead", [(), (7,), (3, 4)])
def test_batching_shapes_numpy_and_torch(rng, lead):
    angles = udhm.sample_angles(rng, lead)
    kp = udhm.forward_kinematics(angles)
    assert isinstance(kp, np.ndarray) and kp.shape == (*lead, 21, 3)
    kp_t = udhm.forward_kinematics(torch.as_tensor(angles))
    assert isinstance(kp_t, torch.Tensor) and tuple(kp_t.shape) == (*lead, 21, 3)
    np.testing.assert_allclose(kp_t.numpy(), kp, atol=1e-12)
    # each frame equals its own unbatched FK
    flat = angles.reshape(-1, 22)
    np.testing.assert_allclose(kp.reshape(-1, 21, 3)[-1], udhm.forward_kinematics(flat[-1]), atol=1e-12)


def test_torch_with_per_frame_skeleton_matches_numpy(rng):
    """torch and numpy FK agree when the skeleton has its own leading dims (5, 2, 5, 3), not only with the
    default (5, 3) one. Catches normalising the palm-offset axes over the wrong dim in the torch branch
    (`dim=1` instead of `dim=-1` is invisible on a (5, 3) skeleton)."""
    angles = udhm.sample_angles(rng, (5, 2))
    sk = udhm.Skeleton.default()
    scales = rng.uniform(0.8, 1.2, size=(5, 2, 5, 1))
    per_frame = udhm.Skeleton(sk.palm_offsets_m * scales, sk.bone_lengths_m * scales)
    kp = udhm.forward_kinematics(angles, per_frame)
    kp_t = udhm.forward_kinematics(torch.as_tensor(angles), per_frame)
    np.testing.assert_allclose(kp_t.numpy(), kp, atol=1e-12)
    np.testing.assert_allclose(
        kp[4, 1],
        udhm.forward_kinematics(
            angles[4, 1], udhm.Skeleton(per_frame.palm_offsets_m[4, 1], per_frame.bone_lengths_m[4, 1])
        ),
        atol=1e-12,
    )


def test_per_frame_skeleton_and_wrist_pose_broadcast(rng):
    angles = udhm.sample_angles(rng, (5, 2))
    sk = udhm.Skeleton.default()
    scales = rng.uniform(0.8, 1.2, size=(5, 2))
    per_frame = udhm.Skeleton(sk.palm_offsets_m * scales[..., None, None], sk.bone_lengths_m * scales[..., None, None])
    rot = Rotation.random(10, random_state=3).as_matrix().reshape(5, 2, 3, 3)
    pos = rng.normal(size=(5, 2, 3))
    kp = udhm.forward_kinematics(angles, per_frame, (rot, pos))
    i, j = 3, 1
    single = udhm.forward_kinematics(angles[i, j], sk.scaled(scales[i, j]))
    np.testing.assert_allclose(kp[i, j], single @ rot[i, j].T + pos[i, j], atol=1e-12)


def test_torch_float32_and_gradients_match_finite_differences(rng):
    angles = udhm.sample_angles(rng, (4,))
    kp32 = udhm.forward_kinematics(torch.as_tensor(angles, dtype=torch.float32))
    assert kp32.dtype == torch.float32
    np.testing.assert_allclose(kp32.numpy(), udhm.forward_kinematics(angles), atol=1e-6)

    q = torch.tensor(angles, dtype=torch.float64, requires_grad=True)
    target = torch.as_tensor(udhm.forward_kinematics(udhm.sample_angles(rng, (4,))))
    loss = (udhm.forward_kinematics(q) - target).pow(2).sum()
    loss.backward()
    assert q.grad is not None and torch.isfinite(q.grad).all()
    eps = 1e-6
    for j in (0, 3, 6, 17, 21):
        dq = np.zeros_like(angles)
        dq[:, j] = eps
        up = ((udhm.forward_kinematics(angles + dq) - target.numpy()) ** 2).sum()
        down = ((udhm.forward_kinematics(angles - dq) - target.numpy()) ** 2).sum()
        assert q.grad[:, j].sum().item() == pytest.approx((up - down) / (2 * eps), rel=1e-5, abs=1e-9)


def test_left_side_is_the_mirror_image():
    q = udhm.sample_angles(np.random.default_rng(5))
    right = udhm.forward_kinematics(q)
    left = udhm.forward_kinematics(q, side="left")
    np.testing.assert_allclose(left, right * np.array([1.0, -1.0, 1.0]), atol=1e-15)


def test_fk_bad_input():
    with pytest.raises(ValueError, match=r"\(\.\.\., 22\)"):
        udhm.forward_kinematics(np.zeros(21))
    with pytest.raises(ValueError, match="unknown side"):
        udhm.forward_kinematics(np.zeros(22), side="up")
    with pytest.raises(ValueError, match="wrist_pose"):
        udhm.forward_kinematics(np.zeros(22), wrist_pose=(np.eye(3), np.zeros(2)))
    with pytest.raises(ValueError, match="Skeleton"):
        udhm.forward_kinematics(np.zeros(22), skeleton=np.zeros((5, 3)))
