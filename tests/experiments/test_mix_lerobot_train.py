"""experiments/mix_lerobot_train.py on the synthetic G1 sample (no ../shared): the other robots written as raw
LeRobot datasets and converted, mixed with the target, trained by the real `lerobot-train`, the mixed checkpoints
bound to the target by `unidextok-deploy` and scored by eval_policy.py next to copying the state. The `l10_only`
arm is the target-only path on the other robot's dataset, so it is left out here (one `lerobot-train` less)."""

import json

import numpy as np
import pytest

from experiments import mix_lerobot_train as mlt
from lerobot_unidextok.data import UdhmDatasetMeta


@pytest.mark.slow
def test_every_arm_trains_with_lerobot_train_and_is_scored_on_the_target(converted_g1, tmp_path):
    argv = [f"--target={converted_g1}", "--l10_poses=synthetic", "--target_episodes=[2]", "--seeds=[0]",
            "--arms=[target_only,mix_hand_scaled]", "--other_episodes=5", "--other_frames=30", "--steps=2",
            "--jobs=1", f"--output_root={tmp_path / 'out'}", f"--cache_dir={tmp_path / 'cache'}"]  # fmt: skip
    result = mlt.run(mlt.runtime.parse(mlt.MixTrainConfig, argv))
    runs = {r["arm"]: r for r in result["runs"]}
    assert sorted(runs) == ["mix_hand_scaled", "target_only"]
    assert runs["target_only"]["train_episodes"] == 2 and runs["mix_hand_scaled"]["train_episodes"] > 2
    # each robot scored on its own test episodes; the mixed policy on both, bound to each
    assert set(runs["target_only"]["errors"]) == {"g1"}
    assert set(runs["mix_hand_scaled"]["errors"]) == {"g1", "l10"}
    for r in runs.values():
        for scores in r["errors"].values():
            assert all(np.isfinite(scores[m]) and scores[m] >= 0 for m in mlt.METRICS)
    folder = tmp_path / "out" / mlt.NAME
    for robot in ("g1", "l10"):
        bound = json.loads((folder / f"mix_hand_scaled_2_s0_{robot}" / "config.json").read_text())
        assert bound["udt_fixed_hand_ids"] and bound["udt_action_delta_stats"]
    # the mix holds the target and both other robots, the target's chosen episodes repeated to half the frames,
    # and its per-hand scale is over the episodes trained on
    record = UdhmDatasetMeta(folder / "mix_2").record
    assert [s.robot_type for s in record.sources][1:] == ["linkerhand_l10_right", "xhand1_right"]
    assert record.sources[0].repeats > 1
    chosen_frames = sum(
        UdhmDatasetMeta(converted_g1).episode_lengths[e] for e in sorted(result["train_episode_order"][:2])
    )
    inspire = next(h for h in record.hand_vocabulary if h.startswith("inspire"))
    assert record.action_delta_stats["left"][inspire]["frames"] == chosen_frames * record.sources[0].repeats
    text = mlt.markdown(result)
    assert "| 2 | mix_hand_scaled |" in text and "| 2 | target_only |" in text and text.count("copy_state") == 2


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="unknown arms"):
        mlt.MixTrainConfig(arms=["target_only", "magic"])
    with pytest.raises(ValueError, match="l10_poses"):
        mlt.MixTrainConfig(l10_poses="made up")
