"""Metric functions on known errors: degrees, active DoFs only, FK keypoint distances in mm."""

import math

import numpy as np
import pytest

from lerobot_unidextok.constants import FINGERTIP_INDICES, KEYPOINT_NAMES, UDHM_INDEX
from lerobot_unidextok.evaluation import (
    fingertip_error_mm,
    keypoint_errors_mm,
    mpjae_deg,
    mpjpe_mm,
    per_joint_mae_deg,
    reconstruction_metrics,
)


def _true(n: int = 6) -> np.ndarray:
    rng = np.random.default_rng(0)
    q = rng.uniform(0.0, 0.8, size=(n, 22))
    q[:, [UDHM_INDEX[k] for k in ("index_mcp_abd", "middle_mcp_abd", "ring_mcp_abd", "pinky_mcp_abd")]] *= 0.2
    return q


def test_mpjae_in_degrees_over_active_dofs_only():
    true = _true()
    pred = true + math.radians(2.0)
    mask = np.zeros_like(true, dtype=bool)
    mask[:, :5] = True
    pred[:, 5:] += 1.0  # large errors on inactive slots are ignored
    assert mpjae_deg(pred, true, mask) == pytest.approx(2.0)
    assert mpjae_deg(true, true) == 0.0
    table = per_joint_mae_deg(pred, true, mask)
    assert list(table) == ["thumb_cmc_flex", "thumb_cmc_spread", "thumb_mcp_flex", "thumb_mcp_abd", "thumb_ip_flex"]
    assert all(v == pytest.approx(2.0) for v in table.values())


def test_keypoint_errors_follow_forward_kinematics():
    """A DIP error of d moves only the index tip, by the chord 2 L sin(d / 2) of the distal bone."""
    from lerobot_unidextok import hands

    true = _true(4)
    pred = true.copy()
    d = math.radians(10.0)
    pred[:, UDHM_INDEX["index_dip_flex"]] += d
    hand_names = np.array(["human"] * 4)
    err = keypoint_errors_mm(pred, true, hand_names)  # (4, 21)
    tip = KEYPOINT_NAMES.index("index_tip")
    bone_mm = float(np.asarray(hands.get("human").skeleton().bone_lengths_m)[1, 2]) * 1000
    np.testing.assert_allclose(err[:, tip], 2 * bone_mm * math.sin(d / 2), rtol=1e-9)
    others = np.delete(err, tip, axis=1)
    np.testing.assert_allclose(others, 0.0, atol=1e-9)
    assert mpjpe_mm(pred, true, hand_names) == pytest.approx(err[:, tip].mean() / 21)
    assert fingertip_error_mm(pred, true, hand_names) == pytest.approx(err[:, tip].mean() / len(FINGERTIP_INDICES))


def test_inactive_slots_do_not_move_keypoints():
    true = _true(3)
    pred = true + 0.3
    mask = np.zeros_like(true, dtype=bool)
    assert mpjpe_mm(pred, true, np.array(["inspire_rh56"] * 3), mask) == 0.0


def test_robot_skeleton_is_used_per_hand():
    from lerobot_unidextok import hands

    true = _true(2)
    pred = true.copy()
    pred[:, UDHM_INDEX["index_dip_flex"]] += 0.2
    tip = KEYPOINT_NAMES.index("index_tip")
    for name in ("human", "allegro"):
        err = keypoint_errors_mm(pred, true, np.array([name] * 2))[:, tip]
        bone_mm = float(np.asarray(hands.get(name).skeleton().bone_lengths_m)[1, 2]) * 1000
        np.testing.assert_allclose(err, 2 * bone_mm * math.sin(0.1), rtol=1e-9)


def test_reconstruction_metrics_per_hand():
    true = _true(6)
    pred = true.copy()
    pred[:3] += math.radians(1.0)
    pred[3:] += math.radians(3.0)
    hand_names = np.array(["human"] * 3 + ["leap"] * 3)
    out = reconstruction_metrics(pred, true, hand_names, np.ones_like(true, bool))
    assert out["per_hand"]["human"]["mpjae_deg"] == pytest.approx(1.0)
    assert out["per_hand"]["leap"]["mpjae_deg"] == pytest.approx(3.0)
    assert out["overall"]["mpjae_deg"] == pytest.approx(2.0)
    assert out["overall"]["rows"] == 6 and len(out["overall"]["per_keypoint_mm"]) == 21
    assert out["per_hand"]["leap"]["mpjpe_mm"] > out["per_hand"]["human"]["mpjpe_mm"] > 0


def test_bad_inputs_raise():
    true = _true(2)
    with pytest.raises(ValueError, match=r"\(N, 22\)"):
        mpjae_deg(true[:, :21], true[:, :21])
    with pytest.raises(ValueError, match="masks must be"):
        mpjae_deg(true, true, np.ones((2, 21), bool))
    with pytest.raises(ValueError, match="one hand per row"):
        keypoint_errors_mm(true, true, np.array(["human"]))


@pytest.mark.parametrize("hand", ["human", "inspire_rh56_unitree", "xhand1"])
def test_finger_keypoints_are_exactly_the_ones_the_joints_move(hand):
    """FK of any angle error moves the 15 finger keypoints and never the wrist or the 5 finger bases, so the
    21-keypoint MPJPE is exactly 15/21 of the finger MPJPE (the dilution the paper's figure may or may not
    contain; catches a finger set that includes a palm point or misses a moving one)."""
    from lerobot_unidextok.evaluation.metrics import FINGER_KEYPOINT_INDICES, mpjpe_fingers_mm

    rng = np.random.default_rng(1)
    true = _true(40)
    pred = true + rng.normal(0, 0.2, true.shape)
    hands = np.array([hand] * 40)
    kp = keypoint_errors_mm(pred, true, hands)
    moving = np.flatnonzero(kp.max(0) > 1e-6)
    assert moving.tolist() == list(FINGER_KEYPOINT_INDICES) and len(moving) == 15
    assert mpjpe_fingers_mm(pred, true, hands) * 15 == pytest.approx(mpjpe_mm(pred, true, hands) * 21, rel=1e-9)
    rep = reconstruction_metrics(pred, true, hands)["overall"]
    assert rep["mpjpe_fingers_mm"] == pytest.approx(mpjpe_fingers_mm(pred, true, hands))
    assert rep["mpjpe_fingers_mm"] > rep["mpjpe_mm"]


def test_per_joint_and_active_dofs_follow_each_row_mask():
    """A joint active in some rows only is averaged over those rows; a hand's active DoFs are the joints
    active in ANY of its rows; rows without any active joint give nan, not an error.

    Catches `any` -> `all` in the per-joint table, in `active_dofs` and in the empty-mask guard."""
    true = _true(4)
    pred = true.copy()
    pred[:, 0] += np.radians([1.0, 3.0, 5.0, 7.0])  # thumb_cmc_flex errors per row
    pred[:, 1] += math.radians(2.0)
    mask = np.zeros_like(true, dtype=bool)
    mask[:2, 0] = True  # thumb_cmc_flex active in rows 0 and 1 only
    mask[:, 1] = True  # thumb_cmc_spread active everywhere
    table = per_joint_mae_deg(pred, true, mask)
    assert table == pytest.approx({"thumb_cmc_flex": 2.0, "thumb_cmc_spread": 2.0})
    out = reconstruction_metrics(pred, true, np.array(["leap"] * 4), mask)
    assert out["per_hand"]["leap"]["active_dofs"] == 2
    assert out["overall"]["mpjae_deg"] == pytest.approx((1.0 + 3.0 + 4 * 2.0) / 6)
    empty = np.zeros_like(mask)
    assert math.isnan(mpjae_deg(pred, true, empty))
    assert per_joint_mae_deg(pred, true, empty) == {}
    assert math.isnan(reconstruction_metrics(pred, true, np.array(["leap"] * 4), empty)["overall"]["mpjae_deg"])


def test_each_shape_check_alone_raises():
    """Each of the three shape conditions raises on its own (catches `or` -> `and` between them)."""
    true = _true(3)
    with pytest.raises(ValueError, match=r"\(N, 22\)"):
        mpjae_deg(true[:2], true)  # rows differ, both (N, 22)
    with pytest.raises(ValueError, match=r"\(N, 22\)"):
        mpjae_deg(true[0], true[0])  # same shape, 1-D
    with pytest.raises(ValueError, match=r"\(N, 22\)"):
        mpjae_deg(np.zeros((3, 21)), np.zeros((3, 21)))  # same shape, 2-D, wrong width
