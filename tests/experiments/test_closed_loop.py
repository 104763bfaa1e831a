"""experiments/closed_loop.py on a tiny configuration: expert episodes recorded and converted, mixed per target,
a policy per arm trained by lerobot-train's own code, mixes bound by unidextok-deploy, each scored by lerobot-eval's
rollout in the simulator; the summary, goals and CPU accounting."""

import json

import pytest

from experiments import closed_loop as cl
from lerobot_unidextok.data import UdhmDatasetMeta


@pytest.mark.slow
def test_every_arm_is_trained_bound_and_scored_in_closed_loop(tmp_path):
    argv = ["--tasks=[GraspLift-v0]", "--hands=[shadow,allegro]", "--seeds=[0]", "--demos=[2]", "--pool=3",
            "--arms=[alone,mix,packed,tokens_nearest,zero_shot]", "--steps=2", "--eval_episodes=2",
            f"--output_root={tmp_path / 'out'}", f"--cache_dir={tmp_path / 'sim'}"]  # fmt: skip
    result = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, argv))
    runs = {(r["hand"], r["arm"]): r for r in result["runs"]}
    assert set(runs) == {(h, a) for h in ("shadow", "allegro")
                         for a in ("alone_2", "mix", "packed", "tokens_nearest", "zero_shot")}  # fmt: skip
    assert all(r["episodes"] == 2 and 0 <= r["successes"] <= 2 for r in runs.values())
    folder = tmp_path / "out" / cl.NAME
    bound = json.loads((folder / "policies/GraspLift-v0/shadow/mix_seed0/bound/config.json").read_text())
    assert bound["udt_hand_vocabulary"] == ["allegro", "shadow"] and bound["udt_fixed_hand_ids"] == [1]
    assert bound["n_action_steps"] == 10 and bound["udt_hand_input"] == "state" and bound["udt_encoding"]["rounds"] == 0
    zero = json.loads((folder / "policies/GraspLift-v0/shadow/zero_shot_seed0/bound/config.json").read_text())
    assert zero["udt_hand_vocabulary"] == ["allegro"] and zero["udt_extra_hands"] == ["shadow"]
    tokens = json.loads((folder / "policies/GraspLift-v0/allegro/tokens_nearest_seed0/bound/config.json").read_text())
    assert tokens["udt_hand_input"] == "tokens" and tokens["udt_encoding"]["rounds"] == 0
    assert tokens["udt_pretrained"] == "unidextok/universal-small" and bound["udt_pretrained"] is None
    # the mix for a target writes its pool target_weight times; the packed mix is append_pad
    mix = UdhmDatasetMeta(tmp_path / "sim/GraspLift-v0/mix_semantic_for_shadow_w10").record
    assert mix.sources[0].repeats == 10 and mix.sources[1].repeats == 1
    assert UdhmDatasetMeta(tmp_path / "sim/GraspLift-v0/mix_packed_for_shadow_w10").record.mapping == "append_pad"
    costs = result["costs"]
    assert costs["data_cpu_s"] > 0 and costs["train_cpu_s"] > 0 and costs["eval_cpu_s"] > 0
    text = cl.markdown(result)
    assert "| scripted expert |" in text and "| zero-shot (other hands only) |" in text and "Goals:" in text
    assert any("zero-shot success above 0" in g["goal"] for g in result["goals"])


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="unknown arms"):
        cl.ClosedLoopConfig(arms=["alone", "magic"])
    with pytest.raises(ValueError, match="at least two hands"):
        cl.ClosedLoopConfig(hands=["shadow"], arms=["mix"])
    with pytest.raises(ValueError, match="demos"):
        cl.ClosedLoopConfig(demos=[60])
    with pytest.raises(ValueError, match=r"targets \['leap'\] are not among hands"):
        cl.ClosedLoopConfig(targets=["leap"])


@pytest.mark.slow
def test_targets_restrict_the_pairs_and_both_recipes_run(tmp_path):
    """--targets scores one hand of the pool (its mix still pools every hand), and the per_hand recipe (per-hand
    normalisation, masked slots) trains, binds and scores beside the pooled one, in its own folders."""
    common = ["--tasks=[GraspLift-v0]", "--hands=[shadow,allegro]", "--targets=[shadow]", "--seeds=[0]", "--demos=[2]",
              "--pool=3", "--steps=2", "--eval_episodes=2", f"--output_root={tmp_path / 'out'}",
              f"--cache_dir={tmp_path / 'sim'}"]  # fmt: skip
    pooled = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, [*common, "--arms=[alone,mix]"]))
    per_hand = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, [*common, "--arms=[mix]", "--recipe=per_hand"]))
    assert {(r["hand"], r["arm"]) for r in pooled["runs"]} == {("shadow", "alone_2"), ("shadow", "mix")}
    assert {(r["hand"], r["arm"]) for r in per_hand["runs"]} == {("shadow", "mix")}
    assert all(r["episodes"] == 2 and 0 <= r["successes"] <= 2 for r in pooled["runs"] + per_hand["runs"])
    assert set(pooled["experts"]) == {"GraspLift-v0/shadow"}
    # the mix pools both hands; nothing is made for the hand that is not a target, nor the packed arm not asked for
    mix = UdhmDatasetMeta(tmp_path / "sim/GraspLift-v0/mix_semantic_for_shadow_w10").record
    assert [s.repeats for s in mix.sources] == [10, 1]
    assert not (tmp_path / "sim/GraspLift-v0/mix_semantic_for_allegro_w10").exists()
    assert not (tmp_path / "sim/GraspLift-v0/mix_packed_for_shadow_w10").exists()
    folder = tmp_path / "out" / cl.NAME
    old = json.loads((folder / "policies/GraspLift-v0/shadow/mix_seed0/bound/config.json").read_text())
    new = json.loads((folder / "policies_per_hand/GraspLift-v0/shadow/mix_seed0/bound/config.json").read_text())
    assert old["udt_hand_norm"] == "off" and old["udt_mask_slots"] is False
    assert new["udt_hand_norm"] == "auto" and new["udt_mask_slots"] is True
    assert (folder / "runs_per_hand/GraspLift-v0__shadow__mix__seed0.json").is_file()
    assert "--targets=[\"shadow\"]" in per_hand["command"] and "--recipe=\"per_hand\"" in per_hand["command"]
