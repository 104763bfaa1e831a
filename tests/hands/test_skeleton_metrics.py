"""Keypoint metrics of a robot hand use that robot's skeleton (from its URDF) and say so."""

from __future__ import annotations

import numpy as np

from lerobot_unidextok import hands
from lerobot_unidextok.evaluation import metrics
from lerobot_unidextok.udhm import Skeleton, forward_kinematics


def test_robot_keypoint_errors_use_the_measured_skeleton():
    """MPJPE of LEAP rows is FK with LEAP's URDF-measured skeleton, not a scaled human one (old behaviour:
    `scale: 1.5` times the human default), and the report names the skeleton."""
    rng = np.random.default_rng(0)
    spec = hands.get("leap")
    true = np.zeros((20, 22))
    true[:, spec.active_mask] = rng.uniform(0.0, 0.8, size=(20, int(spec.active_mask.sum())))
    pred = true + spec.active_mask * rng.normal(0, 0.05, size=true.shape)
    err = metrics.keypoint_errors_mm(pred, true, np.array(["leap"] * 20))
    skel = spec.skeleton()
    want = 1000 * np.linalg.norm(forward_kinematics(pred, skel) - forward_kinematics(true, skel), axis=-1)
    np.testing.assert_allclose(err, want)
    human = Skeleton.default().scaled(1.5)
    scaled = 1000 * np.linalg.norm(forward_kinematics(pred, human) - forward_kinematics(true, human), axis=-1)
    assert np.abs(err - scaled).max() > 1.0  # mm: the robot's proportions are not a scaled human's
    report = metrics.reconstruction_metrics(pred, true, np.array(["leap"] * 20))
    assert report["per_hand"]["leap"]["skeleton"].startswith("measured: dexsuite/dex-urdf")
    assert "approximation" in metrics.skeleton_source("linkerhand_l6")
