"""The scripted experts succeed on seeded episodes of every hand and task, and write LeRobot v3 datasets in the
hand's native units that the project's converter reads like a real robot's recording."""

import numpy as np
import pytest

from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.record import RecordConfig, expert_episode, record

HANDS = ("inspire_rh56_unitree", "shadow", "allegro")


@pytest.mark.parametrize("task", ["GraspLift-v0", "FingerPress-v0"])
@pytest.mark.parametrize("hand", HANDS)
def test_the_expert_succeeds_on_seeded_episodes(hand, task):
    """Five seeded episodes each (the measured rate over 100 is in benchmarks/README.md, bench_sim.py); the
    grasp seeds hold power-grasp (3003-3005) and pinch (3006, 3007) objects."""
    env = UniDexTokEnv(hand, task, render_mode=None)
    wins, kinds = 0, set()
    for i in range(3, 8):
        _, _, success = expert_episode(env, 3000 + i, 4000 + i, 50)
        wins += success
        kinds.add(getattr(env.task, "shape", None) and env.task.shape.grasp)
    assert wins >= 4, f"{hand} {task}: {wins}/5"
    if task == "GraspLift-v0":
        assert kinds == {"power", "pinch"}


@pytest.mark.parametrize("hand", ["leap", "xhand1", "linkerhand_l10", "linkerhand_l20", "linkerhand_l21",
                                  "linkerhand_l25", "linkerhand_o7", "brainco_revo1", "unitree_dex3_1"])  # fmt: skip
def test_the_expert_of_a_hand_built_from_its_urdf_succeeds(hand):
    """Four seeded episodes per task of every hand the simulator builds from its URDF, with no number tuned for
    it (the rates over 100 episodes: docs/tasks.md, bench_sim.py)."""
    from lerobot_env_unidextok import sim_hands

    if hand not in sim_hands.sim_hand_names():
        pytest.skip(f"{hand}'s URDF is not found (set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf)")
    for task in ("GraspLift-v0", "FingerPress-v0"):
        env = UniDexTokEnv(hand, task, render_mode=None)
        wins = sum(expert_episode(env, 3000 + i, 4000 + i, 50)[2] for i in range(3, 7))
        assert wins >= 3, f"{hand} {task}: {wins}/4"


def test_record_writes_a_native_dataset_the_converter_reads(tmp_path):
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.data.meta import UdhmDatasetMeta

    report = record(RecordConfig(hand="inspire_rh56_unitree", task="FingerPress-v0", episodes=2,
                                 root=str(tmp_path / "native")))  # fmt: skip
    assert report.episodes == 2 and report.attempts >= 2
    ds = LeRobotDataset("local/x", root=tmp_path / "native")
    names = ds.meta.features["observation.state"]["names"]
    assert names[-6:] == ["right_little", "right_ring", "right_middle", "right_index", "right_thumb_bend",
                          "right_thumb_rotation"]  # fmt: skip
    state = ds.hf_dataset.with_format("numpy")["observation.state"]
    assert 0 <= np.min(np.stack(state)[:, -6:]) and np.max(np.stack(state)[:, -6:]) <= 1  # Unitree's [0, 1]
    convert(ConvertOptions(source="lerobot", input=str(tmp_path / "native"), root=str(tmp_path / "udhm"),
                           source_options={"hands": {"right": "inspire_rh56_unitree:right_"}}, test_fraction=0.0,
                           progress=False))  # fmt: skip
    meta = UdhmDatasetMeta(tmp_path / "udhm")
    assert meta.hand_types == ["inspire_rh56_unitree"] or "inspire_rh56_unitree" in str(meta.hand_types)
    layout = meta.native_layout("observation.state")
    assert layout.native_names == names and layout.hands[0]["hand"] == "inspire_rh56_unitree"

