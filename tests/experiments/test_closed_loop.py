"""experiments/closed_loop.py on a tiny configuration: expert episodes recorded and converted, mixed per target,
a policy per arm trained by lerobot-train's own code, mixes bound by unidextok-deploy, each scored by lerobot-eval's
rollout in the simulator; the summary, goals and CPU accounting."""

import json

import pytest

from experiments import closed_loop as cl
from lerobot_unidextok.data import UdhmDatasetMeta


@pytest.mark.slow
def test_every_arm_is_trained_bound_and_scored_in_closed_loop(tmp_path):
    argv = ["--tasks=[FingerPress-v0]", "--hands=[shadow,allegro]", "--seeds=[0]", "--demos=[2]", "--mix_demos=[2]",
            "--pool=3", "--arms=[alone,mix,mix_rule,pooled,packed,tokens_nearest,zero_shot]", "--steps=2",
            "--eval_episodes=2", f"--output_root={tmp_path / 'out'}", f"--cache_dir={tmp_path / 'sim'}",
            f"--figure_to={tmp_path / 'fig.png'}"]  # fmt: skip
    result = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, argv))
    runs = {(r["hand"], r["arm"]): r for r in result["runs"]}
    assert set(runs) == {(h, a) for h in ("shadow", "allegro")
                         for a in ("alone_2", "mix_2", "mix_rule_2", "pooled_2", "packed_2", "tokens_nearest_2",
                                   "zero_shot")}  # fmt: skip
    assert all(r["episodes"] == 2 and 0 <= r["successes"] <= 2 for r in runs.values())
    assert runs[("shadow", "mix_rule_2")]["steps"] == 20 and runs[("shadow", "mix_2")]["steps"] == 2  # steps / 0.1
    folder = tmp_path / "out" / cl.NAME
    bound = json.loads((folder / "policies/FingerPress-v0/shadow/mix_2_seed0/bound/config.json").read_text())
    assert bound["udt_hand_vocabulary"] == ["allegro", "shadow"] and bound["udt_fixed_hand_ids"] == [1]
    assert bound["n_action_steps"] == 10 and bound["udt_hand_input"] == "state" and bound["udt_encoding"]["rounds"] == 0
    assert bound["udt_hand_norm"] == "auto" and bound["udt_mask_slots"] is True and bound["udt_input_shares"]
    assert bound["udt_grasp_centres_m"] == {}  # a press grasps nothing: its recordings carry no grasp centre
    pooled = json.loads((folder / "policies/FingerPress-v0/shadow/pooled_2_seed0/bound/config.json").read_text())
    assert pooled["udt_hand_norm"] == "off" and pooled["udt_mask_slots"] is False and not pooled["udt_input_shares"]
    assert pooled["udt_wrist_frame"] == "robot"
    zero = json.loads((folder / "policies/FingerPress-v0/shadow/zero_shot_seed0/bound/config.json").read_text())
    assert zero["udt_hand_vocabulary"] == ["allegro"] and zero["udt_extra_hands"] == ["shadow"]
    tokens = json.loads((folder / "policies/FingerPress-v0/allegro/tokens_nearest_2_seed0/bound/config.json").read_text())
    assert tokens["udt_hand_input"] == "tokens" and tokens["udt_encoding"]["rounds"] == 0
    assert tokens["udt_pretrained"] == cl.ClosedLoopConfig().tokenizer and bound["udt_pretrained"] is None
    # the mix for a target writes each episode once with the target's share; the pooled arm's writes its pool
    # target_weight times; the packed mix is append_pad
    mix = UdhmDatasetMeta(tmp_path / "sim/FingerPress-v0/mix_semantic_for_shadow_s0.1").record
    assert [s.repeats for s in mix.sources] == [1, 1] and [s.share for s in mix.sources] == [0.1, 0.9]
    copies = UdhmDatasetMeta(tmp_path / "sim/FingerPress-v0/mix_semantic_for_shadow_w10").record
    # whole repeats that bring the frame shares near 10:1 (9 or 10 with these episode lengths), no share recorded
    assert copies.sources[0].repeats in (9, 10) and copies.sources[1].repeats == 1
    assert [s.share for s in copies.sources] == [0.0, 0.0]
    assert UdhmDatasetMeta(tmp_path / "sim/FingerPress-v0/mix_packed_for_shadow_s0.1").record.mapping == "append_pad"
    costs = result["costs"]
    assert costs["data_cpu_s"] > 0 and costs["train_cpu_s"] > 0 and costs["eval_cpu_s"] > 0
    text = cl.markdown(result)
    assert "| scripted expert |" in text and "| zero-shot (other hands only) |" in text and "Goals:" in text
    assert "| mix, 2 demos |" in text and "| mix, pooled statistics (before 2026-12-05), 2 demos |" in text
    goals = [g["goal"] for g in result["goals"]]
    assert any("mix beats the hand alone by >= 10 points at 2 demos" in g for g in goals)
    assert any("zero-shot at least half the hand alone" in g for g in goals)
    assert (folder / "closed_loop.png").stat().st_size > 10_000 and (tmp_path / "fig.png").is_file()


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="unknown arms"):
        cl.ClosedLoopConfig(arms=["alone", "magic"])
    with pytest.raises(ValueError, match="at least two hands"):
        cl.ClosedLoopConfig(hands=["shadow"], arms=["mix"])
    with pytest.raises(ValueError, match="demos"):
        cl.ClosedLoopConfig(demos=[60])
    with pytest.raises(ValueError, match="mix_demos"):
        cl.ClosedLoopConfig(mix_demos=[0])
    with pytest.raises(ValueError, match="target_share"):
        cl.ClosedLoopConfig(target_share=1.0)
    # 0: no weights (the target at its frame share), and then no budget-rule arm to divide the updates by
    assert cl.ClosedLoopConfig(target_share=0.0, arms=["mix"]).target_share == 0
    with pytest.raises(ValueError, match="mix_rule needs a target share"):
        cl.ClosedLoopConfig(target_share=0.0, arms=["mix", "mix_rule"])
    assert "frame share" in cl.share_words(400, 0.0) and "800" in cl.share_words(400, 0.5)
    with pytest.raises(ValueError, match=r"targets \['leap'\] are not among hands"):
        cl.ClosedLoopConfig(hands=["shadow", "allegro"], targets=["leap"])
    with pytest.raises(ValueError, match=r"ablation_targets \['leap'\] are not among hands"):
        cl.ClosedLoopConfig(hands=["shadow", "allegro"], ablation_targets=["leap"])


def test_packed_runs_on_the_finger_task_only_and_ablations_on_their_targets():
    cfg = cl.ClosedLoopConfig(arms=["mix", "mix_rule", "pooled", "packed", "no_mask", "alone_no_frame"], seeds=[0],
                              demos=[10, 25], mix_demos=[10], ablation_targets=["shadow"])  # fmt: skip
    runs = {(j["task"], j["hand"], j["arm"]) for j in cl.jobs(cfg)}
    assert {a for t, _, a in runs if t == "GraspLift-v0"} == {"mix_10", "mix_rule_10", "pooled_10", "no_mask_10",
                                                               "alone_no_frame_10", "alone_no_frame_25"}  # fmt: skip
    # 10x the updates at a tenth, the old recipe, the hand alone in the robot's frame (at `demos`): pruned too
    for pruned in ("no_mask_10", "mix_rule_10", "pooled_10", "alone_no_frame_10", "alone_no_frame_25"):
        assert {h for _, h, a in runs if a == pruned} == {"shadow"}
    assert {h for _, h, a in runs if a == "mix_10"} == set(cl.HANDS) == {h for t, h, a in runs if a == "packed_10"}
    assert len(runs) == 2 * 6 + 6 + 2 * 5
    assert cl.arm_title("alone_no_frame_25") == "alone without the grasp-centre frame, 25 demos"


def test_the_both_arm_reads_the_hands_as_the_default_policy_does():
    """The `<type>_udt` default view: the UDHM state and the given tokenizer's tokens in its own encoding."""
    cfg = cl.ClosedLoopConfig(arms=["both"], demos=[10], tokenizer="unidextok/universal-small")
    assert {j["arm"] for j in cl.jobs(cfg)} == {"both_10"}
    flags = cl.arm_flags(cfg, "both", "GraspLift-v0")
    assert flags[:2] == ["--policy.udt_hand_input=both", "--policy.udt_pretrained=unidextok/universal-small"]
    assert not [f for f in flags if "udt_encoding" in f]  # the tokenizer's own encoding
    assert cl.arm_title("both_10") == "alone, state and tokens (the default view), 10 demos"


@pytest.mark.slow
def test_targets_restrict_the_pairs_and_an_ablation_turns_one_mechanism_off(tmp_path):
    """--targets scores one hand of the pool (its mix still pools every hand); an ablation arm trains the mix with
    one mechanism off, in its own folders, reusing the runs already done."""
    common = ["--tasks=[GraspLift-v0]", "--hands=[shadow,allegro]", "--targets=[shadow]", "--seeds=[0]", "--demos=[2]",
              "--mix_demos=[2]", "--pool=3", "--steps=2", "--eval_episodes=2", f"--output_root={tmp_path / 'out'}",
              f"--cache_dir={tmp_path / 'sim'}"]  # fmt: skip
    first = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, [*common, "--arms=[alone,mix]"]))
    second = cl.run(cl.runtime.parse(cl.ClosedLoopConfig, [*common, "--arms=[mix,no_mask]"]))
    assert {(r["hand"], r["arm"]) for r in first["runs"]} == {("shadow", "alone_2"), ("shadow", "mix_2")}
    assert {r["arm"] for r in second["runs"]} == {"mix_2", "no_mask_2"}
    assert [r for r in second["runs"] if r["arm"] == "mix_2"] == [r for r in first["runs"] if r["arm"] == "mix_2"]
    assert all(r["episodes"] == 2 and 0 <= r["successes"] <= 2 for r in first["runs"] + second["runs"])
    assert set(first["experts"]) == {"GraspLift-v0/shadow"}
    # nothing is made for the hand that is not a target, nor the mixes of arms not asked for
    assert not (tmp_path / "sim/GraspLift-v0/mix_semantic_for_allegro_s0.5").exists()
    assert not (tmp_path / "sim/GraspLift-v0/mix_semantic_for_shadow_w10").exists()
    folder = tmp_path / "out" / cl.NAME
    ablated = json.loads((folder / "policies/GraspLift-v0/shadow/no_mask_2_seed0/bound/config.json").read_text())
    assert ablated["udt_hand_norm"] == "auto" and ablated["udt_mask_slots"] is False
    assert (folder / "runs/GraspLift-v0__shadow__no_mask_2__seed0.json").is_file()
    assert '--targets=["shadow"]' in second["command"] and '--arms=["mix","no_mask"]' in second["command"]
