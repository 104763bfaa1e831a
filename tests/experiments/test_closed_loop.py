"""experiments/closed_loop.py on a tiny configuration: each seed's expert episodes recorded and converted, mixed per
target and pool, a policy per arm trained by lerobot-train's own code with the user's flags, mixes bound by
unidextok-deploy, each scored by lerobot-eval's rollout in the simulator; the data protocol (each dataset holds
only the demonstrations its arm trains on, each seed its own recording and evaluation episodes), the pool rule,
the rendered user commands, the robustness summary and the CPU accounting."""

import dataclasses
import json
import shlex

import numpy as np
import pandas as pd
import pytest

from experiments import closed_loop as cl
from lerobot_unidextok.conversion.mix import budget_steps
from lerobot_unidextok.data import UdhmDatasetMeta

TINY = ["--seeds=[0]", "--demos=[2]", "--mix_demos=[2]", "--pool=3", "--steps=2", "--eval_episodes=2"]


def _frames(root) -> int:
    return json.loads((root / "meta" / "info.json").read_text())["total_frames"]


@pytest.mark.slow
def test_every_arm_trains_on_exactly_its_demonstrations_and_is_scored_in_closed_loop(tmp_path):
    argv = ["--tasks=[FingerPress-v0]", "--hands=[shadow,allegro]", *TINY,
            "--arms=[alone,alone_state,mix,mix_state,mix_rule,pooled,packed,tokens_nearest,zero_shot]",
            f"--output_root={tmp_path / 'out'}", f"--cache_dir={tmp_path / 'sim'}", f"--figure_to={tmp_path / 'fig.png'}"]  # fmt: skip
    cfg = cl.runtime.parse(cl.ClosedLoopConfig, argv)
    result = cl.run(cfg)
    runs = {(r["hand"], r["arm"]): r for r in result["runs"]}
    assert set(runs) == {(h, a) for h in ("shadow", "allegro")
                         for a in ("alone_2", "alone_state_2", "mix_2_pool2", "mix_state_2_pool2", "mix_rule_2_pool2",
                                   "pooled_2_pool2", "packed_2_pool2", "tokens_nearest_2_pool2", "zero_shot_pool2")}  # fmt: skip
    assert all(r["episodes"] == 2 and 0 <= r["successes"] <= 2 for r in runs.values())
    # the alone dataset: the target's 2 demonstrations and nothing else, LeRobot's statistics from their frames
    alone = tmp_path / "sim/FingerPress-v0/seed0/shadow/semantic_2"
    assert runs[("shadow", "alone_2")]["dataset"] == str(alone)
    assert UdhmDatasetMeta(alone).record.num_episodes == 2
    stats = json.loads((alone / "meta/stats.json").read_text())
    assert stats["action"]["count"] == [_frames(alone)]
    # the mix: the target's same 2 demonstrations and the other hand's pool of 3; per-hand statistics from them
    mix = tmp_path / runs[("shadow", "mix_2_pool2")]["dataset"]
    record = UdhmDatasetMeta(mix).record
    by_hand = {h: sum(e.hand_type.startswith(h) for e in record.episodes) for h in ("shadow", "allegro")}
    assert by_hand == {"shadow": 2, "allegro": 3} and [s.num_episodes for s in record.sources] == [2, 3]
    assert record.hand_stats["action"]["right"]["shadow"]["frames"] == _frames(alone)
    assert json.loads((mix / "meta/stats.json").read_text())["action"]["count"] == [_frames(mix)]
    shadow_alone = pd.read_parquet(next((alone / "data").rglob("*.parquet")))["action"]
    shadow_mixed = pd.read_parquet(next((mix / "data").rglob("*.parquet")))
    mixed_actions = np.stack(shadow_mixed[shadow_mixed["episode_index"] < 2]["action"].to_numpy())
    assert np.array_equal(np.stack(shadow_alone.to_numpy()), mixed_actions)  # byte-identical demonstrations
    # zero-shot from one other hand: that hand's converted recording of the pool, no mix
    assert runs[("shadow", "zero_shot_pool2")]["dataset"] == str(
        tmp_path / "sim/FingerPress-v0/seed0/allegro/semantic_3"
    )
    # the default recipe: the policy's own hand input and tokenizer; the mix's own shares (no --weights)
    folder = tmp_path / "out" / cl.NAME / "policies/FingerPress-v0/shadow/seed0"
    bound = json.loads((folder / "mix_2_pool2/bound/config.json").read_text())
    assert bound["udt_hand_vocabulary"] == ["allegro", "shadow"] and bound["udt_fixed_hand_ids"] == [1]
    assert bound["n_action_steps"] == 10 and bound["udt_relative_actions"] is False
    assert bound["udt_hand_input"] == "both" and bound["udt_pretrained"] == cl.DEFAULT_TOKENIZER
    assert bound["udt_hand_norm"] == "auto" and bound["udt_mask_slots"] is True and bound["udt_input_shares"]
    alone_cfg = json.loads((folder / "alone_2/checkpoints/last/pretrained_model/config.json").read_text())
    assert alone_cfg["udt_hand_input"] == "both" and alone_cfg["udt_pretrained"] == cl.DEFAULT_TOKENIZER
    # what lerobot-train saved is what the rendered user command asks for
    job = next(j for j in cl.jobs(cfg) if j["hand"] == "shadow" and j["arm"] == "mix_2_pool2")
    line = next(x for x in cl.user_commands(cfg, job) if x.startswith("lerobot-train "))
    flags = dict(a[2:].split("=", 1) for a in shlex.split(line)[3:])
    trained = json.loads((folder / "mix_2_pool2/checkpoints/last/pretrained_model/train_config.json").read_text())
    assert (
        trained["dataset"]["root"] == flags["dataset.root"] == str(mix) and trained["output_dir"] == flags["output_dir"]
    )
    assert [trained[k] for k in ("steps", "batch_size", "seed")] == [
        int(flags[k]) for k in ("steps", "batch_size", "seed")
    ]
    assert trained["policy"]["n_action_steps"] == 10 and trained["policy"]["udt_copy_start"] is False
    state = json.loads((folder / "mix_state_2_pool2/bound/config.json").read_text())
    assert state["udt_hand_input"] == "state" and state["udt_pretrained"] is None
    # the budget rule divides by the share the mix recorded
    share = cl.target_share_of(mix)
    assert 0 < share < 1 and runs[("shadow", "mix_rule_2_pool2")]["steps"] == budget_steps(2, share)
    assert runs[("shadow", "mix_2_pool2")]["target_share"] == pytest.approx(share, abs=1e-4)
    pooled = json.loads((folder / "pooled_2_pool2/bound/config.json").read_text())
    assert pooled["udt_hand_norm"] == "off" and pooled["udt_mask_slots"] is False and not pooled["udt_input_shares"]
    zero = json.loads((folder / "zero_shot_pool2/bound/config.json").read_text())
    assert zero["udt_hand_layout"] == ["shadow"] and zero["udt_allow_unknown"] is True  # bound zero-shot
    tokens = json.loads((folder / "tokens_nearest_2_pool2/bound/config.json").read_text())
    assert tokens["udt_hand_input"] == "tokens" and tokens["udt_encoding"]["rounds"] == 0
    assert UdhmDatasetMeta(tmp_path / runs[("shadow", "packed_2_pool2")]["dataset"]).record.mapping == "append_pad"
    costs = result["costs"]
    assert costs["data_cpu_s"] > 0 and costs["train_cpu_s"] > 0 and costs["eval_cpu_s"] > 0
    rob = result["robustness"]["FingerPress-v0"][2]
    assert set(rob["rows"]) == {"shadow", "allegro"} and rob["targets"] == 2
    text = cl.markdown(result)
    assert "the target's share of the sampled training frames, as the mix set it" in text
    assert "Every dataset holds only the demonstrations its arm trains on" in text  # this protocol's caption
    assert "protocol before issue 57" in cl.markdown({**result, "protocol": None})  # a result measured before
    assert "robustness at 2 target demonstrations" in text and "| scripted expert |" in text and "Goals:" in text
    assert "| mix, 2 demos, 2-hand pool |" in text and "| zero-shot (other hands only), 2-hand pool |" in text
    assert "lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu)" in text
    assert any("no more than 3 points below the hand alone" in g["goal"] for g in result["goals"])
    assert (tmp_path / "out" / cl.NAME / "closed_loop.png").stat().st_size > 10_000 and (tmp_path / "fig.png").is_file()
    assert (tmp_path / "out" / cl.NAME / "closed_loop_curves.png").is_file()


def test_the_train_args_are_the_rendered_user_command_and_the_default_arms_add_no_hand_flag():
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], pools=[2, 3, 6], demos=[10], mix_demos=[10],
                              arms=["alone", "mix", "zero_shot", "mix_state", "mix_ft"])  # fmt: skip
    for job in cl.jobs(cfg):
        p = cl.plan(cfg, job)
        if job["kind"] == "mix_ft":
            _the_fine_tuned_arm_renders_both_of_its_trainings(cfg, job, p)
            continue
        args = cl.train_args(
            cfg, p["root"], cl.policy_dir(cfg, job), job["seed"], cl.arm_flags(cfg, job["kind"]), cfg.steps
        )
        lines = cl.user_commands(cfg, job)
        train = [line for line in lines if line.startswith("lerobot-train ")]
        assert len(train) == 1 and train[0].startswith(
            "lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) "
        )
        assert shlex.split(train[0])[3:] == args
        extra = [
            a for a in args if not a.startswith(("--dataset.", "--seed=", "--output_dir=", "--steps=", "--batch_size="))
        ]
        if job["kind"] == "mix_state":
            assert "--policy.udt_hand_input=state" in extra and "--policy.udt_pretrained=null" in extra
            continue
        assert extra == list(cl.USER_FLAGS)  # no hand input, tokenizer or share flag: the policy's defaults
        mix = [line for line in lines if line.startswith("unidextok-mix ")]
        assert all("--weights" not in line for line in mix)  # the mix's own default shares
        assert len(mix) == (job["kind"] == "mix" or job["pool"] > 2)
        records = [shlex.split(line) for line in lines if line.startswith("unidextok-sim-record ")]
        hands = [a.split("=", 1)[1] for r in records for a in r if a.startswith("--hand=")]
        pool = cl.pool_hands(cfg.hands, job["hand"], job["pool"]) if job["pool"] else [job["hand"]]
        assert hands[: len(pool) - (job["kind"] == "zero_shot")] == (pool[1:] if job["kind"] == "zero_shot" else pool)
        assert lines[-1].startswith("lerobot-eval ") and f"--seed={cl.eval_start(cfg, job['seed'])}" in lines[-1]


def _the_fine_tuned_arm_renders_both_of_its_trainings(cfg, job, p):
    """mix_ft's commands: the mix trained for half the updates, bound to the target, fine-tuned by the stock
    lerobot-train --policy.path= on the target's own dataset (the alone arm's) for the rest, then scored."""
    out, lines = cl.policy_dir(cfg, job), cl.user_commands(cfg, job)
    train = [line for line in lines if line.startswith("lerobot-train ")]
    assert len(train) == 2 and train[0].startswith(
        "lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) "
    )
    first, second = cl.fine_tune_steps(cfg)
    assert first + second == cfg.steps and first == cfg.steps // 2
    # measured on the recipe before the pool's prior: each hand's own statistics, so its runs stand
    assert cl.arm_flags(cfg, job["kind"]) == [cl.OWN_STATS]
    assert shlex.split(train[0])[3:] == cl.train_args(cfg, p["root"], out / "pooled", job["seed"], [cl.OWN_STATS],
                                                      first)  # fmt: skip
    bound = out / "bound"
    assert shlex.split(train[1])[1:] == cl.fine_tune_args(
        cfg, bound, p["robot"], out / "fine_tuned", job["seed"], second
    )
    alone = next(
        j for j in cl.jobs(cfg) if j["hand"] == job["hand"] and j["seed"] == job["seed"] and j["kind"] == "alone"
    )
    assert p["robot"] == cl.plan(cfg, alone)["root"]  # the fine-tune's dataset is the alone arm's, nothing more
    assert "--config_path" not in train[1] and f"--dataset.root={p['robot']}" in shlex.split(train[1])
    deploy = next(i for i, line in enumerate(lines) if line.startswith("unidextok-deploy "))
    assert lines.index(train[0]) < deploy < lines.index(train[1]) and f"--output={bound}" in lines[deploy]
    assert sum(line.startswith("unidextok-mix ") for line in lines) == 1
    tuned = out / "fine_tuned" / "checkpoints" / "last" / "pretrained_model"
    assert lines[-1].startswith(f"lerobot-eval --policy.path={tuned} ")


def test_the_pool_is_the_target_and_the_hands_after_it_cyclically():
    assert cl.pool_hands(cl.HANDS, "shadow", 2) == ["shadow", "allegro"]
    assert cl.pool_hands(cl.HANDS, "shadow", 3) == ["shadow", "allegro", "leap"]
    assert cl.pool_hands(cl.HANDS, "linkerhand_l10", 3) == ["linkerhand_l10", "inspire_rh56_unitree", "shadow"]
    assert sorted(cl.pool_hands(cl.HANDS, "leap", 6)) == sorted(cl.HANDS)
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], targets=["linkerhand_l10"], pools=[2, 6], demos=[10],
                              mix_demos=[10], seeds=[0])  # fmt: skip
    plans = {j["arm"]: cl.plan(cfg, j) for j in cl.jobs(cfg)}
    assert set(plans) == {"alone_10", "mix_10_pool2", "mix_10_pool6", "zero_shot_pool2", "zero_shot_pool6"}
    assert plans["mix_10_pool2"]["inputs"] == [("linkerhand_l10", 10), ("inspire_rh56_unitree", 50)]
    assert [h for h, _ in plans["zero_shot_pool6"]["inputs"]] == list(cl.HANDS[:5])
    assert plans["alone_10"]["inputs"] == [("linkerhand_l10", 10)] and plans["alone_10"]["robot"] is None
    # a mix with the mix's default shares is keyed by unidextok-mix's code (the default may change), and a run by
    # its dataset: a rerun after such a change mixes and trains again
    assert (
        plans["mix_10_pool6"]["root"].name.endswith(f"_default-{cl._mix_code()}")
        and not plans["mix_10_pool6"]["weights"]
    )
    assert plans["zero_shot_pool6"]["root"].name.endswith(f"_default-{cl._mix_code()}")
    # the key is the code's, not its prose's: a docstring or comment edited keeps the mixes, a changed line does not
    source = '"""Mix."""\nALPHA = 0.43  # pi0\n\n\ndef share(n):\n    """Its share."""\n    return n**ALPHA\n'
    assert cl.code_key(source) == cl.code_key(source.replace("Its share.", "The share, see docs/pooling.md.")
                                              .replace("# pi0", "# pi0's exponent").replace('"""Mix."""', '"""A mix."""'))
    assert cl.code_key(source) != cl.code_key(source.replace("0.43", "0.5"))
    # an asked share goes to the mixes only: the hand alone and zero-shot have no target share to set
    shared = {j["arm"]: cl.plan(cl.ClosedLoopConfig(**{**vars(cfg), "target_share": 0.25}), j) for j in cl.jobs(cfg)}
    assert shared["mix_10_pool2"]["weights"] == [0.25, 0.75] and shared["mix_10_pool2"]["root"].name.endswith("_s0.25")
    assert shared["alone_10"] == plans["alone_10"] and shared["zero_shot_pool6"] == plans["zero_shot_pool6"]
    assert cl.ClosedLoopConfig().pools == [6] and cl.ClosedLoopConfig(hands=["shadow", "leap"]).pools == [2]
    assert cl.parse_label("mix_10_pool2") == ("mix", 10, 2) and cl.parse_label("zero_shot_pool3") == ("zero_shot", 0, 3)
    assert cl.arm_title("mix_rule_10_pool3") == "mix, budget rule, 10 demos, 3-hand pool"


def test_a_kept_run_is_reused_only_on_its_dataset_and_with_its_recipe(tmp_path, monkeypatch):
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], targets=["shadow"], pools=[2], demos=[10], mix_demos=[10],
                              seeds=[0], arms=["mix", "mix_heads"], output_root=str(tmp_path))  # fmt: skip
    job = next(j for j in cl.jobs(cfg) if j["kind"] == "mix")
    settings = cl.recipe(cfg, "mix")
    # the recipe is the policy's udt_* defaults, then act_udt_cpu.yaml's policy section, then the flags
    assert settings["type"] == "act_udt" and settings["dim_model"] == 64 and settings["udt_hand_input"] == "both"
    assert settings["udt_relative_actions"] is False and settings["n_action_steps"] == 10  # USER_FLAGS, as YAML reads them
    assert settings["udt_hand_stats_prior_per_hand"] == 2  # act_udt_cpu.yaml's pool prior
    assert cl.recipe(cfg, "mix_own_stats") == {**settings, "udt_hand_stats_prior_per_hand": 0}
    assert cl.recipe(cfg, "mix_heads") == {**settings, "udt_hand_identity": "onehot", "udt_hand_stats_prior_per_hand": 0}
    assert cl.cached_run(cfg, job) is None  # nothing kept yet
    kept = {"dataset": str(cl.plan(cfg, job)["root"]), "recipe": settings, "successes": 7, "episodes": 50}
    cl.run_path(cfg, job).parent.mkdir(parents=True)
    cl.run_path(cfg, job).write_text(json.dumps(kept))
    assert cl.cached_run(cfg, job) == kept
    for changed in ({**kept, "recipe": {**settings, "udt_hand_heads": False}},  # a default changed since
                    {k: v for k, v in kept.items() if k != "recipe"},  # kept before runs recorded their recipe
                    {**kept, "dataset": kept["dataset"] + "_other"}):  # fmt: skip
        cl.run_path(cfg, job).write_text(json.dumps(changed))
        assert cl.cached_run(cfg, job) is None
    cl.run_path(cfg, job).write_text(json.dumps(kept))
    monkeypatch.setattr(cl, "USER_FLAGS", (*cl.USER_FLAGS, "--policy.udt_hand_heads=false"))
    assert cl.cached_run(cfg, job) is None  # the same file, the recipe it is compared with changed


def test_each_seed_draws_its_own_recording_and_evaluation_episodes(tmp_path):
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], hands=["shadow", "allegro"], seeds=[0, 1], pool=3, demos=[1],
                              mix_demos=[1], cache_dir=str(tmp_path))  # fmt: skip
    ranges = cl.seed_ranges(cfg)
    assert ranges["seed 0 recording"] != ranges["seed 1 recording"] and cl.eval_start(cfg, 1) != cl.eval_start(cfg, 0)
    assert {j["seed"] for j in cl.jobs(cfg)} == {0, 1}

    def actions(root):
        return np.stack(pd.read_parquet(next((root / "data").rglob("*.parquet")))["action"].to_numpy())

    one = {s: actions(cl.recorded(cfg, "GraspLift-v0", "shadow", s, 1)) for s in (0, 1)}
    assert one[0].shape != one[1].shape or not np.allclose(one[0], one[1])
    # the target's n demonstrations are the first n of the seed's recording (episode i from seed + attempts)
    two = cl.recorded(cfg, "GraspLift-v0", "shadow", 0, 2)
    frames = pd.read_parquet(next((two / "data").rglob("*.parquet")))
    first = np.stack(frames[frames["episode_index"] == 0]["action"].to_numpy())
    assert np.array_equal(first, one[0])
    with pytest.raises(ValueError, match="overlap"):
        cl.ClosedLoopConfig(seeds=[0, 10])  # seed 10's recording would be seed 0's expert noise
    with pytest.raises(ValueError, match="overlap"):
        cl.ClosedLoopConfig(eval_seed=100_000)  # evaluation episodes that are recorded demonstrations


def test_the_fingertips_recording_is_the_same_demonstrations_with_the_tips_in_a_cache_of_its_own(tmp_path):
    from lerobot_env_unidextok.columns import FINGERTIP_COLUMNS

    base = dict(tasks=["GraspLift-v0"], hands=["shadow", "allegro"], seeds=[0], pool=2, demos=[1], mix_demos=[1],
                cache_dir=str(tmp_path))  # fmt: skip
    plain, tips = cl.ClosedLoopConfig(**base), cl.ClosedLoopConfig(**base, fingertips=True)
    a, b = (cl.recorded(c, "GraspLift-v0", "allegro", 0, 1) for c in (plain, tips))
    assert a != b and b.parts[-4] == "GraspLift-v0_fingertips"
    names = [UdhmDatasetMeta(r).names("observation.state") for r in (a, b)]
    assert [n for n in names[1] if n not in FINGERTIP_COLUMNS] == names[0] and set(FINGERTIP_COLUMNS) <= set(names[1])

    def frames(root):
        return pd.read_parquet(next((root / "data").rglob("*.parquet")))

    np.testing.assert_array_equal(np.stack(frames(a)["action"]), np.stack(frames(b)["action"]))  # the same expert
    job = next(j for j in cl.jobs(tips) if j["kind"] == "mix" and j["hand"] == "shadow")
    lines = cl.user_commands(tips, job)
    assert all(line.endswith("--fingertips=true") for line in lines if line.startswith("unidextok-sim-record "))
    assert lines[-1].startswith("lerobot-eval ") and lines[-1].endswith("--env.fingertips=true")
    assert not any("-fingertips=" in line or "_fingertips/" in line for line in cl.user_commands(plain, job))
    assert set(cl.recordings(tips)) == {"GraspLift-v0/allegro/seed0/1"}


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
    with pytest.raises(ValueError, match="pools"):
        cl.ClosedLoopConfig(hands=["shadow", "allegro"], pools=[3])
    assert cl.ClosedLoopConfig(hands=["shadow"], arms=["alone"]).pools == [1]  # no mix: no pool to check
    with pytest.raises(ValueError, match="pool must be"):
        cl.ClosedLoopConfig(pool=2000)
    assert cl.ClosedLoopConfig(target_share=0.0).share is None and cl.ClosedLoopConfig(target_share=0.2).share == 0.2
    assert "default" in cl.share_words(400, None) and "2000" in cl.share_words(400, 0.2)
    with pytest.raises(ValueError, match=r"\['leap'\] are not among hands"):
        cl.ClosedLoopConfig(hands=["shadow", "allegro"], targets=["leap"])
    with pytest.raises(ValueError, match=r"\['leap'\] are not among hands"):
        cl.ClosedLoopConfig(hands=["shadow", "allegro"], ablation_targets=["leap"])


def test_packed_runs_on_the_finger_task_only_and_ablations_on_their_targets():
    cfg = cl.ClosedLoopConfig(arms=["mix", "mix_rule", "pooled", "packed", "no_mask", "alone_no_frame"], seeds=[0],
                              demos=[10, 25], mix_demos=[10], ablation_targets=["shadow"])  # fmt: skip
    runs = {(j["task"], j["hand"], j["arm"]) for j in cl.jobs(cfg)}
    assert {a for t, _, a in runs if t == "GraspLift-v0"} == {"mix_10_pool6", "mix_rule_10_pool6", "pooled_10_pool6",
                                                               "no_mask_10_pool6", "alone_no_frame_10",
                                                               "alone_no_frame_25"}  # fmt: skip
    for pruned in (
        "no_mask_10_pool6",
        "mix_rule_10_pool6",
        "pooled_10_pool6",
        "alone_no_frame_10",
        "alone_no_frame_25",
    ):
        assert {h for _, h, a in runs if a == pruned} == {"shadow"}
    assert (
        {h for _, h, a in runs if a == "mix_10_pool6"}
        == set(cl.HANDS)
        == {h for t, h, a in runs if a == "packed_10_pool6"}
    )
    assert len(runs) == 2 * 6 + 6 + 2 * 5


def test_the_robustness_summary_pools_the_seeds_and_bounds_the_gain():
    runs = [{"task": "T", "hand": h, "arm": a, "successes": k, "episodes": 50}
            for h, alone, mix, zero in (("a", 20, 26, 5), ("b", 40, 36, 10), ("c", 25, 25, 30))
            for a, k in (("alone_10", alone), ("mix_10_pool2", mix), ("zero_shot_pool2", zero))]  # fmt: skip
    runs += [{"task": "T", "hand": h, "arm": "alone_25", "successes": 30, "episodes": 50} for h in "abc"]
    cfg = cl.ClosedLoopConfig(hands=["shadow", "allegro"], demos=[10, 25], mix_demos=[10])
    summary = cl.summarise(runs, cfg)
    rob = cl.robustness(summary, cfg)["T"][2]
    assert rob["rows"]["a"]["gain"] == pytest.approx(12) and rob["worst"] == ["b", pytest.approx(-8)]
    assert rob["median"] == pytest.approx(0) and rob["mean"] == pytest.approx(4 / 3)
    assert rob["never_worse"] == 2 and rob["above_zero_shot"] == 2
    low, high = rob["rows"]["a"]["gain_interval"]
    assert low < 0 < 12 < high < 40  # 40 % -> 52 % is not significant at 50 episodes each (Newcombe: -7 to +30)
    assert rob["rows"]["a"]["mix"]["rate"] == pytest.approx(52) and rob["rows"]["c"]["zero_shot"]["rate"] == 60
    goals = {g["goal"]: g for g in cl.goals({"summary": summary, "robustness": {"T": {2: rob}}, "experts": {}}, cfg)}
    assert (
        goals["T pool 2: the mix at 10 demos no more than 3 points below the hand alone on every target"]["met"]
        is False
    )
    assert goals["T pool 2: the mix never below zero-shot"]["why"] == "c 50 < 60"
    reach = goals["T pool 2: the mix at 10 demos reaches the hand alone at 25, on average over 3 targets"]
    assert reach["value"] == pytest.approx((52 + 72 + 50) / 3 - 60) and reach["met"] is False
    assert rob["with_zero_shot"] == 3
    # zero-shot from one other hand is judged at a third of the hand alone (c: 60 of 50); from four, at half
    assert goals["T pool 2: zero-shot at least 0.33 of the hand alone at 10 demos on every target"]["why"] == "short: a, b"
    five = {g["goal"] for g in cl.goals({"summary": summary, "robustness": {"T": {5: rob}}, "experts": {}}, cfg)}
    assert "T pool 5: zero-shot at least 0.5 of the hand alone at 10 demos on every target" in five
    # without zero-shot runs (a mix-only command) the goal is not judged, and the summary line does not count it
    mixes = [r for r in runs if not r["arm"].startswith("zero_shot")]
    summary = cl.summarise(mixes, cfg)
    alone = cl.robustness(summary, cfg)
    assert alone["T"][2]["with_zero_shot"] == 0
    assert not [g for g in cl.goals({"summary": summary, "robustness": alone, "experts": {}}, cfg) if "zero-shot" in g["goal"]]
    lines = cl.robustness_lines({"config": {"mix_demos": [10]}, "robustness": alone, "runs": mixes})
    assert not any("mix >= zero-shot" in line for line in lines)


def test_zero_shot_runs_only_on_its_pools_when_they_are_named():
    base = dict(tasks=["GraspLift-v0"], arms=["alone", "mix", "zero_shot"], pools=[2, 3, 6], seeds=[0], demos=[10],
                mix_demos=[10])  # fmt: skip
    every = {j["arm"] for j in cl.jobs(cl.ClosedLoopConfig(**base))}
    pruned = {j["arm"] for j in cl.jobs(cl.ClosedLoopConfig(**base, zero_shot_pools=[6]))}
    assert every - pruned == {"zero_shot_pool2", "zero_shot_pool3"} and "mix_10_pool2" in pruned
    with pytest.raises(ValueError, match=r"zero_shot_pools \[5\] must be among pools \[2, 3, 6\]"):
        cl.ClosedLoopConfig(**base, zero_shot_pools=[5])


def test_the_mechanism_arms_run_last_on_their_pools_and_each_take_one_out_of_the_recipe():
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], arms=["alone", "mix", "zero_shot", "mix_heads", "mix_morph",
                                                           "zero_shot_morph"],
                              pools=[2, 3, 6], mechanism_pools=[2, 6], seeds=[0], demos=[10], mix_demos=[10])  # fmt: skip
    order = [j["arm"] for j in cl.jobs(cfg)]
    table = {"alone_10", "mix_10_pool2", "mix_10_pool3", "mix_10_pool6", "zero_shot_pool2", "zero_shot_pool3",
             "zero_shot_pool6"}  # fmt: skip
    mechanisms = {"mix_heads_10_pool2", "mix_heads_10_pool6", "mix_morph_10_pool2", "mix_morph_10_pool6",
                  "zero_shot_morph_pool6"}  # fmt: skip
    assert set(order) == table | mechanisms and len(order) == 6 * len(table | mechanisms)
    assert set(order[: 6 * len(table)]) == table  # every hand's table arms before any mechanism arm
    # the recipe has both mechanisms (act_udt_cpu.yaml); each arm takes one out, mix_onehot both (the old recipe)
    assert cl.recipe(cfg, "mix")["udt_hand_identity"] == "morphology" and cl.recipe(cfg, "mix")["udt_hand_heads"] is True
    assert cl.arm_flags(cfg, "mix_heads") == ["--policy.udt_hand_identity=onehot", cl.OWN_STATS]
    # the arms measured on the recipe before the pool's prior keep each hand's own statistics; the recipe's do not
    assert cl.OWN_STATS == "--policy.udt_hand_stats_prior_per_hand=0"
    assert all(cl.OWN_STATS in cl.arm_flags(cfg, a) for a in ("mix_own_stats", "zero_shot_own_stats", "mix_morph",
                                                              "mix_onehot", "zero_shot_onehot", "zero_shot_morph",
                                                              "state_norm", "mix_ft", "mix_ft_state_norm"))
    assert not any(cl.OWN_STATS in cl.arm_flags(cfg, a) for a in ("alone", "mix", "mix_rule", "zero_shot"))
    # the shrunk arms' prior: 10 episodes unless --shrink_episodes says otherwise, the state arm's flag kept
    assert cl.arm_flags(cfg, "mix_shrink") == ["--policy.udt_hand_stats_prior=10"]
    small = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], shrink_episodes=2.5)
    assert cl.arm_flags(small, "mix_shrink") == cl.arm_flags(small, "zero_shot_shrink") == [
        "--policy.udt_hand_stats_prior=2.5"]
    assert cl.arm_flags(small, "state_norm_shrink") == ["--policy.udt_hand_norm_state=true",
                                                        "--policy.udt_hand_stats_prior=2.5"]  # fmt: skip
    assert cl.recipe(small, "mix_shrink")["udt_hand_stats_prior"] == 2.5
    with pytest.raises(ValueError, match="shrink_episodes must be > 0"):
        cl.ClosedLoopConfig(shrink_episodes=0)
    assert cl.arm_flags(cfg, "mix_morph") == cl.arm_flags(cfg, "zero_shot_morph") == [
        "--policy.udt_hand_heads=false", cl.OWN_STATS]
    assert cl.arm_flags(cfg, "mix_onehot") == cl.arm_flags(cfg, "zero_shot_onehot") == [
        "--policy.udt_hand_identity=onehot", "--policy.udt_hand_heads=false", cl.OWN_STATS
    ]
    assert cl.recipe(cfg, "mix_onehot") == {**cl.recipe(cfg, "mix"), "udt_hand_identity": "onehot", "udt_hand_heads": False,
                                            "udt_hand_stats_prior_per_hand": 0}  # fmt: skip
    fine = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], arms=["mix", "mix_ft"], pools=[2, 6], mechanism_pools=[6],
                               seeds=[0], demos=[10], mix_demos=[10])  # fmt: skip
    order = [j["arm"] for j in cl.jobs(fine)]
    assert order[:6] == ["mix_10_pool2", "mix_10_pool6"] * 3 and set(order[12:]) == {"mix_ft_10_pool6"}
    # the recipe before the pool's prior, trained in two stages
    assert len(order) == 18 and cl.arm_flags(fine, "mix_ft") == [cl.OWN_STATS]
    assert cl.arm_title("mix_ft_10_pool6").startswith("mix, then fine-tuned on the target")


@pytest.mark.slow
def test_the_fine_tuned_arm_pools_then_trains_on_the_targets_own_dataset_with_its_statistics(tmp_path):
    """mix_ft: the mix for half the updates, bound, then the stock lerobot-train --policy.path= on the alone arm's
    dataset for the rest; the fine-tune's episode map and LeRobot's statistics are the target dataset's, and the
    per-hand statistics it keeps are those of the same demonstrations. The action's passthrough (wrist) columns keep
    the mix's statistics (the per-hand step's state; lerobot-train overrides only LeRobot's normaliser)."""
    from safetensors.numpy import load_file

    from lerobot_unidextok.blocks import passthrough_indices
    from lerobot_unidextok.conversion.hand_stats import hand_stats, training_episodes
    from lerobot_unidextok.data.share_sampler import episode_map_key

    argv = ["--tasks=[FingerPress-v0]", "--hands=[shadow,allegro]", "--targets=[shadow]", *TINY, "--steps=3",
            "--arms=[alone,mix_ft]", f"--output_root={tmp_path / 'out'}", f"--cache_dir={tmp_path / 'sim'}"]  # fmt: skip
    cfg = cl.runtime.parse(cl.ClosedLoopConfig, argv)
    result = cl.run(cfg)
    runs = {r["arm"]: r for r in result["runs"]}
    alone = tmp_path / "sim/FingerPress-v0/seed0/shadow/semantic_2"
    tuned_run = runs["mix_ft_2_pool2"]
    assert runs["alone_2"]["dataset"] == tuned_run["fine_tune_dataset"] == str(alone)
    assert (tuned_run["pool_steps"], tuned_run["fine_tune_steps"], tuned_run["steps"]) == (1, 2, 3)  # matched compute
    assert tuned_run["dataset"] != str(alone) and tuned_run["episodes"] == 2
    folder = tmp_path / "out" / cl.NAME / "policies/FingerPress-v0/shadow/seed0/mix_ft_2_pool2"
    model = folder / "fine_tuned/checkpoints/last/pretrained_model"
    # what lerobot-train saved is what the rendered fine-tune command asks for
    job = next(j for j in cl.jobs(cfg) if j["kind"] == "mix_ft")
    line = [x for x in cl.user_commands(cfg, job) if x.startswith("lerobot-train ")][1]
    flags = dict(a[2:].split("=", 1) for a in shlex.split(line)[1:])
    trained = json.loads((model / "train_config.json").read_text())
    assert trained["policy"]["pretrained_path"] == flags["policy.path"] == str(folder / "bound")
    assert trained["dataset"]["root"] == flags["dataset.root"] == str(alone)
    assert [trained[k] for k in ("steps", "batch_size", "seed", "num_workers")] == [
        int(flags[k]) for k in ("steps", "batch_size", "seed", "num_workers")
    ]
    pooled = json.loads((folder / "pooled/checkpoints/last/pretrained_model/train_config.json").read_text())
    assert pooled["steps"] == 1 and pooled["dataset"]["root"] == tuned_run["dataset"]
    # the episode map made anew for the target's dataset: one robot, no shares
    tuned = json.loads((model / "config.json").read_text())
    assert tuned["udt_episode_map_of"] == episode_map_key(UdhmDatasetMeta(alone)) and tuned["udt_input_shares"] == []
    assert tuned["udt_fixed_hand_ids"] and tuned["n_action_steps"] == 10 and tuned["udt_relative_actions"] is False
    # LeRobot's statistics (the state's normaliser): the target dataset's, not the mix's
    stats = json.loads((alone / "meta/stats.json").read_text())
    mixed = json.loads((tmp_path / tuned_run["dataset"] / "meta/stats.json").read_text())
    normaliser = load_file(next(model.glob("policy_preprocessor_step_*_normalizer_processor.safetensors")))
    assert np.allclose(normaliser["observation.state.mean"], stats["observation.state"]["mean"], atol=1e-6)
    assert not np.allclose(normaliser["observation.state.mean"], mixed["observation.state"]["mean"], atol=1e-6)
    # the per-hand statistics stay the checkpoint's; the target's are those of the same demonstrations
    own = hand_stats(alone, training_episodes(UdhmDatasetMeta(alone)))["action"]["right"]["shadow"]
    kept = tuned["udt_hand_stats"]["action"]["right"]["shadow"]
    assert kept["frames"] == own["frames"] == _frames(alone)
    assert all(np.allclose(kept[k], own[k], atol=1e-6) for k in ("mean", "std"))
    # the action's wrist columns: the mix's statistics, kept by the per-hand step
    step = load_file(next(model.glob("policy_preprocessor_step_*_unidextok.hand_normalizer.safetensors")))
    wrist = list(passthrough_indices(UdhmDatasetMeta(alone).names("action")))
    assert np.allclose(step["action.passthrough.mean"], np.asarray(mixed["action"]["mean"])[wrist], atol=1e-6)
    text = cl.markdown(result)
    assert "The fine-tuned arm's commands after its mix" in text and f"--policy.path={folder / 'bound'}" in text


def test_the_mechanism_table_gives_each_arms_gain_over_the_hand_alone():
    def arm(mean):
        return {"mean": mean}

    summary = {"GraspLift-v0": {
        "shadow": {"alone_10": arm(50), "mix_10_pool2": arm(40), "mix_heads_10_pool2": arm(55), "zero_shot_pool6": arm(24),
                   "zero_shot_own_stats_pool6": arm(20), "zero_shot_morph_pool6": arm(10), "mix_morph_10_pool2": arm(48)},
        "leap": {"alone_10": arm(40), "mix_10_pool2": arm(60), "mix_heads_10_pool2": arm(50), "zero_shot_pool6": arm(40),
                 "zero_shot_own_stats_pool6": arm(30), "zero_shot_morph_pool6": arm(36), "mix_morph_10_pool2": arm(70)},
    }}  # fmt: skip
    # the mix's and the hand alone's runs per seed (successes of 50): the per-seed column is the targets' mean gain
    runs = [{"task": "GraspLift-v0", "hand": hand, "arm": label, "seed": seed, "successes": k, "episodes": 50}
            for hand, label, by_seed in (("shadow", "alone_10", (24, 26)), ("shadow", "mix_10_pool2", (20, 20)),
                                         ("leap", "alone_10", (20, 20)), ("leap", "mix_10_pool2", (28, 32)))
            for seed, k in enumerate(by_seed)]  # fmt: skip
    text = "\n".join(cl.mechanism_lines({"config": {"mix_demos": [10], "pools": [2, 6], "seeds": [0, 1]},
                                         "summary": summary, "runs": runs}))  # fmt: skip
    # seed 0: (40 - 48 + 56 - 40) / 2; seed 1: (40 - 52 + 64 - 40) / 2
    assert "| mix, 10 demos, 2-hand pool | -10 | +20 | +5.0 | +4.0 / +6.0 | shadow -10 | 1/2 |" in text
    assert "| mix, one-hot identity (heads, no morphology), 10 demos, 2-hand pool | +5 | +10 | +7.5 | - | shadow +5 | 2/2 |" in text
    assert "| mix, no per-hand heads (morphology only), 10 demos, 2-hand pool | -2 | +30 | +14.0 | - | shadow -2 | 2/2 |" in text
    # the zero-shot arms against the zero-shot of the recipe before the pool's prior, the recipe's zero-shot too
    assert "| zero-shot, no per-hand heads (morphology only), 6-hand pool | -10 | +6 | -2.0 | - | shadow -10 | 1/2 |" in text
    assert "| zero-shot (other hands only), 6-hand pool | +4 | +10 | +7.0 | - | shadow +4 | 2/2 |" in text


def test_a_run_standing_for_two_arms_is_paid_for_once():
    run = {"task": "T", "hand": "h", "seed": 0}
    a = {**run, "arm": "zero_shot_pool2", "train_cpu_s": 10.0}
    b = {**run, "arm": "zero_shot_own_stats_pool2", "same_policy_as": "zero_shot_pool2", "train_cpu_s": 10.0}
    other_seed = {**b, "seed": 1}  # its twin is not among the runs: paid
    assert cl.paid_runs([a, b, other_seed]) == [a, other_seed]


def test_the_nearest_slots_arm_binds_the_zero_shot_policy_with_the_deploy_flag_and_trains_nothing_new():
    """zero_shot_nearest is `zero_shot`'s policy (the same training command, output folder and recipe) bound with
    `unidextok-deploy --zero_shot=true --zero_shot_slots=nearest` into a folder of its own."""
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], pools=[6], demos=[10], arms=["zero_shot", "zero_shot_nearest"],
                              seeds=[0])  # fmt: skip
    by_kind = {j["kind"]: j for j in cl.jobs(cfg) if j["hand"] == "shadow"}
    plain, near = by_kind["zero_shot"], by_kind["zero_shot_nearest"]
    assert cl.jobs(cfg)[-1]["kind"] == "zero_shot_nearest"  # a mechanism: after the table's arms
    assert cl.trained_dir(cfg, near) == cl.policy_dir(cfg, plain) != cl.policy_dir(cfg, near)
    assert cl.recipe(cfg, "zero_shot_nearest") == cl.recipe(cfg, "zero_shot")
    lines, plain_lines = cl.user_commands(cfg, near), cl.user_commands(cfg, plain)
    train = [x for x in lines if x.startswith("lerobot-train ")]
    assert train == [x for x in plain_lines if x.startswith("lerobot-train ")]
    deploy = next(x for x in lines if x.startswith("unidextok-deploy "))
    assert deploy.endswith(" --zero_shot=true --zero_shot_slots=nearest")
    assert f"--output={cl.policy_dir(cfg, near) / 'bound'}" in deploy
    assert lines[-1].startswith(f"lerobot-eval --policy.path={cl.policy_dir(cfg, near) / 'bound'} ")


def test_a_policy_bound_a_second_way_pays_its_evaluation_not_its_training():
    """The costs line: zero_shot_nearest's runs add their evaluation (a binding and 50 episodes of their own) but
    no policy and no training to the zero-shot runs whose policy they bind."""
    cfg = cl.ClosedLoopConfig(tasks=["GraspLift-v0"], pools=[6], demos=[10], arms=["zero_shot", "zero_shot_nearest"],
                              seeds=[0])  # fmt: skip
    base = {"task": "GraspLift-v0", "hand": "shadow", "seed": 0, "successes": 10, "episodes": 50, "wall_s": 60.0}
    runs = [{**base, "arm": "zero_shot_pool6", "kind": "zero_shot", "train_cpu_s": 30.0, "eval_cpu_s": 6.0},
            {**base, "arm": "zero_shot_nearest_pool6", "kind": "zero_shot_nearest", "same_policy_as": "zero_shot_pool6",
             "train_cpu_s": 0.5, "eval_cpu_s": 6.0}]  # fmt: skip
    costs = cl.run_costs(runs)
    assert costs == {"train_cpu_s": 30.0, "eval_cpu_s": 12.0, "evaluations": 2, "runs_wall_s": 120.0, "policies": 1}
    assert cl.run_costs(runs[1:])["policies"] == 1  # without its twin among the runs, it is the policy paid for
    result = {"config": dataclasses.asdict(cfg), "runs": runs, "summary": cl.summarise(runs, cfg), "protocol": cl.PROTOCOL,
              "costs": {"data_cpu_s": 0.0, "expert_cpu_s": 0.0, **costs}, "experts": {}, "goals": []}  # fmt: skip
    text = cl.markdown(result)
    assert "for 1 policies (2 runs: a run standing for two arms is one policy)" in text
    assert "per policy 0.50 training and per evaluation 0.10: 2 evaluations" in text
