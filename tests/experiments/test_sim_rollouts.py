"""experiments/sim_rollouts.py: the scripted expert on seeded episodes of FingerSequence-v0, PinchPlace-v0 and PinchLift-v0 (each
episode's end as the task says it, and the task's own measures), the same success as closed_loop.py's expert path;
a checkpoint trained on other task columns refused in one line; and (slow) a 2-update policy trained by
closed_loop.py run through LeRobot's rollout, its successes those closed_loop.py's lerobot-eval rollout counted."""

import json

import pytest

from experiments import sim_rollouts as sr


def _run(tmp_path, task: str, checkpoint: str = sr.EXPERT, episodes: int = 3, **flags) -> dict:
    out = tmp_path / f"{task}.json"
    argv = [f"--checkpoint={checkpoint}", f"--task={task}", "--hand=shadow", f"--episodes={episodes}", f"--output={out}",
            *[f"--{k}={v}" for k, v in flags.items()]]  # fmt: skip
    result = sr.run(sr.runtime.parse(sr.SimRolloutsConfig, argv))
    assert json.loads(out.read_text())["summary"] == result["summary"]
    return result


def _expert_episode_successes(task: str, episodes: int) -> list[bool]:
    """What closed_loop.py's `expert_success` runs on its seed 0's episodes."""
    from lerobot_env_unidextok.env import UniDexTokEnv
    from lerobot_env_unidextok.record import expert_episode

    env = UniDexTokEnv("shadow", task, render_mode=None)
    return [expert_episode(env, 1000 + i, sr.EXPERT_NOISE_SEED + i, 50)[2] for i in range(episodes)]


def test_the_expert_presses_the_three_in_order_and_its_trace_says_so(tmp_path):
    result = _run(tmp_path, "FingerSequence-v0")
    s = result["summary"]
    assert s["episodes"] == 3 and s["successes"] == 3 and s["failure_reasons"] == {}
    assert s["first_press"] == {"due": 3, "another of the three": 0, "not in the order": 0, "none": 0}
    assert s["presses_done"] == {"0": 0, "1": 0, "2": 0, "3": 3}
    assert [e["seed"] for e in result["episodes"]] == [1000, 1001, 1002]
    for e in result["episodes"]:
        assert len(set(e["order"])) == 3 and e["first_press"] == e["order"][:1] and e["done"] == 3
    assert [e["success"] for e in result["episodes"]] == _expert_episode_successes("FingerSequence-v0", 3)
    text = sr.markdown(result)
    assert "| success | 3/3 |" in text and "| first press: due | 3 |" in text and "scripted expert" in text


def test_the_expert_pinches_lifts_and_sets_the_cylinder_down_in_the_target(tmp_path):
    result = _run(tmp_path, "PinchPlace-v0")
    s = result["summary"]
    assert s["successes"] == 3 and s["lifted"] == 3 and s["never_lifted"] == 0 and s["released"] == 3
    assert s["knocked_over"] == s["dropped"] == 0 and s["released_on_table"] == s["released_standing"] == 3
    assert s["let_go_mm_median"] < 20 and s["closest_lifted_mm_median"] < 20  # the target's radius
    assert 60 <= s["start_mm_median"] <= 90 and s["carry_along_mm_median"] > 50 and s["final_tilt_deg_median"] < 20
    assert "chunk_phase_progress_mm" not in s  # the expert has no action chunk
    for e in result["episodes"]:
        assert e["finger"] in ("index", "middle") and e["reason"] == "" and e["final_mm"] <= 20
        assert all(gain is not None for _, gain in e["held_up_progress_mm"])
    assert [e["success"] for e in result["episodes"]] == _expert_episode_successes("PinchPlace-v0", 3)
    assert "| lifted (>= 15 mm) | 3 |" in sr.markdown(result)


def test_the_expert_pinches_the_cylinder_with_the_named_finger_and_lifts_it(tmp_path):
    result = _run(tmp_path, "PinchLift-v0")
    s = result["summary"]
    assert s["successes"] == 3 and s["pinch"] == {"none": 0, "one finger": 0, "both, not lifted": 0, "lifted": 3}
    assert s["another_finger_touched"] == 0 and s["max_up_mm_median"] >= 40  # the task's goal: 4 cm
    for e in result["episodes"]:
        assert e["lifted"] and e["touched_by"] == sorted(["thumb", e["finger"]])
    assert [e["success"] for e in result["episodes"]] == _expert_episode_successes("PinchLift-v0", 3)
    assert "| pinch: lifted | 3 |" in sr.markdown(result)


def test_another_task_reports_success_and_failure_reasons_only(tmp_path):
    result = _run(tmp_path, "FingerPress-v0", episodes=2)
    assert set(result["summary"]) == {"episodes", "successes", "failure_reasons"}
    assert set(result["episodes"][0]) == {"seed", "success", "reason", "steps"}


def test_bad_options_and_a_checkpoint_of_other_columns_are_named(tmp_path):
    with pytest.raises(ValueError, match="give --checkpoint"):
        sr.SimRolloutsConfig()
    with pytest.raises(ValueError, match="unknown task"):
        sr.SimRolloutsConfig(checkpoint=sr.EXPERT, task="Juggle-v0")
    with pytest.raises(ValueError, match="holds no config.json"):
        sr.SimRolloutsConfig(checkpoint=str(tmp_path))
    # a FingerSequence-v0 policy of the columns before 3b2141c (the due finger alone): refused, not run to zero
    old = ["wrist_x", "panel_x", "panel_y", "panel_z", "due_index", "due_middle", "due_ring", "due_little",
           "presses_done"]  # fmt: skip
    (tmp_path / "config.json").write_text(json.dumps({"type": "act_udt", "udt_state_names": old}))
    with pytest.raises(ValueError, match="has no next_index.*trained on other FingerSequence-v0 columns"):
        sr.check_fits(str(tmp_path), "FingerSequence-v0", "shadow")


@pytest.mark.slow
def test_a_trained_policy_runs_through_lerobots_rollout_as_closed_loop_scores_it(tmp_path):
    from experiments import closed_loop as cl

    argv = ["--tasks=[PinchPlace-v0]", "--hands=[shadow]", "--arms=[alone]", "--seeds=[0]", "--demos=[2]",
            "--mix_demos=[2]", "--pool=2", "--steps=2", "--eval_episodes=3", f"--output_root={tmp_path / 'out'}",
            f"--cache_dir={tmp_path / 'sim'}"]  # fmt: skip
    cfg = cl.runtime.parse(cl.ClosedLoopConfig, argv)
    run = cl.run(cfg)["runs"][0]
    checkpoint = cl.policy_dir(cfg, cl.jobs(cfg)[0]) / "checkpoints" / "last" / "pretrained_model"
    # 2 batches of 2 envs: the last batch's extra env dropped
    result = _run(tmp_path, "PinchPlace-v0", str(checkpoint), batch_size=2)
    s = result["summary"]
    assert s["episodes"] == 3 and s["successes"] == run["successes"]
    assert result["n_action_steps"] == 10 and len(s["chunk_phase_progress_mm"]) == 10
    assert s["lifted"] + s["never_lifted"] == 3 and sum(s["failure_reasons"].values()) == 3 - s["successes"]
