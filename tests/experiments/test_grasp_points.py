"""experiments/grasp_points.py: the grasp centre's offset from the object at the lift frame, in the object's frame."""

import numpy as np
import pytest

from experiments import grasp_points as gp

NAMES = ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw", "object_x", "object_y", "object_z",
         "object_yaw", "object_half_x", "object_half_y", "object_half_z", "goal_z", "finger"]  # fmt: skip


def episode(wrist: list[float], obj_xyz: list[float], obj_yaw: float, half_x: float, lift_at: int) -> np.ndarray:
    state = np.zeros((8, len(NAMES)))
    state[:, :6] = wrist
    state[:, 6:9] = obj_xyz
    state[:, 9] = obj_yaw
    state[:, 10:13] = half_x
    state[lift_at:, 8] += 0.03  # the object rises 3 cm from frame `lift_at` on
    return state


def test_the_offset_is_the_grasp_centre_from_the_object_in_its_own_frame():
    # the wrist pitched 90 degrees down: the centre 5 cm along the wrist's x points straight down (world -z)
    state = episode([0.10, 0.02, 0.20, 0.0, np.pi / 2, 0.0], [0.10, 0.0, 0.10], np.pi / 2, 0.025, lift_at=5)
    point = gp.grasp_point(state, NAMES, np.array([0.05, 0.0, 0.0]), lift_m=0.01)
    # world offset at frame 5: (0, 0.02, 0.20 - 0.05 - 0.13); in the frame of the object, yawed 90 degrees, world y is its x
    np.testing.assert_allclose(point["offset_m"], [0.02, 0.0, 0.02], atol=1e-12)
    assert point["kind"] == "power" and point["pitch_rad"] == np.pi / 2


def test_a_small_object_is_a_pinch_and_an_object_never_lifted_gives_nothing():
    pinch = episode([0.0, 0.0, 0.1, 0.0, 0.0, 0.0], [0.0, 0.0, 0.05], 0.0, 0.015, lift_at=3)
    assert gp.grasp_point(pinch, NAMES, np.zeros(3), lift_m=0.01)["kind"] == "pinch"
    assert gp.grasp_point(pinch, NAMES, np.zeros(3), lift_m=0.05) is None  # it rose 3 cm, not 5


def test_an_unknown_frame_and_a_hand_never_recorded_are_named(tmp_path):
    with pytest.raises(ValueError, match=r"frame must be one of \('grasp_centre', 'wrist'\)"):
        gp.GraspPointsConfig(frame="palm")
    cfg = gp.GraspPointsConfig(cache_dir=str(tmp_path), hands=["shadow"])
    with pytest.raises(FileNotFoundError, match=r"no recorded GraspLift-v0 dataset .* for shadow; record it with "
                                                r"experiments/closed_loop.py --tasks='\[GraspLift-v0\]'"):  # fmt: skip
        gp.run(cfg)
    with pytest.raises(ValueError, match=r"task must be one of \('GraspLift-v0', 'PinchLift-v0'\)"):
        gp.GraspPointsConfig(task="FingerPress-v0")


def test_a_pinch_lift_episode_is_kept_by_its_named_finger_in_the_world_axes():
    """PinchLift's columns: no yaw (an upright cylinder) and no half widths; the kind is the thumb's partner."""
    names = ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw", "object_x", "object_y",
             "object_z", "object_radius", "object_half_height", "pinch_index", "pinch_middle"]  # fmt: skip
    state = np.zeros((6, len(names)))
    state[:, :6] = [0.10, 0.03, 0.12, 0.0, 0.0, 0.0]
    state[:, 6:9] = [0.08, 0.0, 0.016]
    state[:, 12] = 1.0  # the middle finger
    state[4:, 8] += 0.02
    point = gp.grasp_point(state, names, np.array([0.01, 0.0, -0.05]), lift_m=0.01)
    np.testing.assert_allclose(point["offset_m"], [0.03, 0.03, 0.034], atol=1e-12)
    assert point["kind"] == "middle"


def test_a_hands_posture_is_compared_with_the_others_mean_over_the_slots_both_move():
    nan = np.nan
    postures = {"a": np.array([10.0, 20.0, nan]), "b": np.array([30.0, nan, 5.0]), "c": np.array([50.0, 40.0, 15.0])}
    d = gp.from_others_deg(postures)
    assert d["a"] == pytest.approx((abs(10 - 40) + abs(20 - 40)) / 2)  # its third slot it lacks
    assert d["b"] == pytest.approx((abs(30 - 30) + abs(5 - 15)) / 2)  # its second slot it lacks
    assert d["c"] == pytest.approx((abs(50 - 20) + abs(40 - 20) + abs(15 - 5)) / 3)
    assert np.isnan(gp.from_others_deg({"a": np.array([nan]), "b": np.array([1.0])})["a"])  # nothing in common
