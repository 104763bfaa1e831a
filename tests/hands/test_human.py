"""The human hand spec: MANO-21 keypoints <-> UDHM through udhm IK / FK."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.udhm import forward_kinematics, limit_violations, sample_angles


@pytest.mark.parametrize("side", ["right", "left"])
def test_keypoints_udhm_keypoints_round_trip(side):
    spec = hands.get("human")
    angles = sample_angles(np.random.default_rng(0), (2, 3), margin=0.2)  # (2, 3, 22)
    kp = forward_kinematics(angles, spec.skeleton(), side=side)  # (2, 3, 21, 3) m
    state = spec.to_udhm(kp, side)
    assert state.shape == (2, 3, 22)
    back = spec.from_udhm(state, side)
    assert back.shape == kp.shape
    assert np.abs(back - kp).max() < 1e-3  # metres: sub-millimetre
    assert spec.active_mask.all()


def test_torch_keypoints():
    spec = hands.get("human")
    angles = sample_angles(np.random.default_rng(1), (4,), margin=0.2)
    kp = forward_kinematics(angles, spec.skeleton())
    state_t = spec.to_udhm(torch.tensor(kp, dtype=torch.float32))
    assert isinstance(state_t, torch.Tensor) and state_t.dtype == torch.float32
    np.testing.assert_allclose(state_t.numpy(), spec.to_udhm(kp), atol=1e-5)
    kp_t = spec.from_udhm(state_t)
    assert isinstance(kp_t, torch.Tensor) and kp_t.shape == (4, 21, 3)


def test_real_tracked_right_hand(real_data_dir):
    """dex-retargeting's MediaPipe recording: UDHM states within human limits, fist-like frames flex."""
    kp = np.load(real_data_dir / "dex-retargeting" / "human_joint_right.npy")[::20]  # (32, 21, 3) m
    state = hands.get("human").to_udhm(kp, "right")
    assert state.shape == (len(kp), 22)
    assert limit_violations(state, tol_rad=np.deg2rad(5)).mean() < 0.05
    # the recording opens and closes the hand: index MCP flexion spans a wide range
    flex = state[:, UDHM_INDEX["index_mcp_flex"]]
    assert np.ptp(flex) > np.deg2rad(30)
