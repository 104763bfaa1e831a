"""The CPU recipe (configs/lerobot/act_udt_cpu.yaml) through the real `lerobot-train` for a few steps on a
synthetic whole-robot dataset in the converted contract, then `experiments/eval_policy.py` in a fresh process:
the checkpoint reloaded with the stock factory, scored open loop next to copying the state."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from linkerhand_udhm import subprocess_env
from robot_udhm import INSPIRE

from lerobot_unidextok.configs import shipped_config

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


@pytest.mark.slow
def test_cpu_recipe_trains_and_eval_policy_scores_it(g1_like, tmp_path):
    from experiments.policy_data import copy_state_prediction, load_frames, open_loop_errors
    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    torch.manual_seed(0)
    tok = tmp_path / "tok"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=[INSPIRE])).save_pretrained(tok)
    root, env = g1_like["root"], subprocess_env(HF_HOME=str(tmp_path / "hf"))
    train = [str(BIN / "lerobot-train"), f"--config_path={shipped_config('lerobot/act_udt_cpu')}",
             "--dataset.repo_id=test/g1_like_udhm", f"--dataset.root={root}", "--dataset.episodes=[0,1]",
             f"--policy.udt_pretrained={tok}", "--steps=2", "--save_freq=2", "--log_freq=1",
             f"--output_dir={tmp_path / 'act'}"]  # fmt: skip
    r = subprocess.run(train, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    ckpt = tmp_path / "act" / "checkpoints" / "last" / "pretrained_model"
    assert json.loads((ckpt / "config.json").read_text())["dim_model"] == 64
    out = tmp_path / "eval.json"
    r = subprocess.run([sys.executable, str(REPO / "experiments" / "eval_policy.py"), f"--checkpoint={ckpt}",
                        f"--dataset={root}", f"--output={out}"], env=env, capture_output=True, text=True,
                       timeout=300, check=False)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    result = json.loads(out.read_text())
    assert result["episodes"] == [2] and result["rows"] == 40  # the dataset's recorded test episode
    assert result["native_width"] == 26 and result["chunk_size"] == 10
    assert all(np.isfinite(v) and v > 0 for v in result["policy"].values())
    frames = load_frames(root)
    rows = np.flatnonzero(frames.episode == 2)
    assert result["copy_state"] == pytest.approx(open_loop_errors(copy_state_prediction(frames, rows, 10), frames, rows, 10))
    assert "| copy_state |" in r.stdout and "| mean_action |" in r.stdout
    assert all(v > 0 for v in result["mean_action"].values())


@pytest.mark.slow
def test_eval_policy_scores_a_simulator_dataset_whose_state_has_task_columns(tmp_path):
    """A simulator recording's state holds the task's object columns between the wrist and the hand, which no
    action has: the policy reads the whole state, copying the state copies the action's columns by name."""
    from experiments.policy_data import copy_state_prediction, load_frames
    from lerobot_env_unidextok.columns import TASK_COLUMNS
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.data import UdhmDatasetMeta

    native, root = tmp_path / "native", tmp_path / "udhm"
    record(RecordConfig(hand="inspire_rh56_unitree", task="GraspLift-v0", episodes=3, root=str(native)))
    convert(ConvertOptions(source="lerobot", input=str(native), root=str(root), repo_id="sim/inspire_grasp",
                           source_options={"hands": {"right": "inspire_rh56_unitree:right_"}}, progress=False))  # fmt: skip
    frames = load_frames(root)
    task = len(TASK_COLUMNS["GraspLift-v0"])
    assert frames.policy_input.shape[1] == frames.state.shape[1] + task == frames.action.shape[1] + task
    rows = np.arange(4)
    copied = copy_state_prediction(frames, rows, 2)
    state_names = UdhmDatasetMeta(root).names("observation.state")
    assert not set(TASK_COLUMNS["GraspLift-v0"]) & set(frames.names)
    np.testing.assert_array_equal(copied[:, 1], frames.policy_input[rows][:, [state_names.index(n) for n in frames.names]])
    env = subprocess_env(HF_HOME=str(tmp_path / "hf"))
    train = [str(BIN / "lerobot-train"), f"--config_path={shipped_config('lerobot/act_udt_cpu')}",
             "--dataset.repo_id=sim/inspire_grasp", f"--dataset.root={root}", "--policy.udt_relative_actions=false",
             "--policy.udt_copy_start=false", "--steps=2", "--save_freq=2", "--log_freq=1",
             f"--output_dir={tmp_path / 'act'}"]  # fmt: skip
    r = subprocess.run(train, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    ckpt = tmp_path / "act" / "checkpoints" / "last" / "pretrained_model"
    from experiments.eval_policy import EvalPolicyConfig, run  # in this process: the test above runs its CLI

    result = run(EvalPolicyConfig(checkpoint=str(ckpt), dataset=str(root), episodes=[2]))
    assert result["episodes"] == [2] and result["native_width"] == 6 + 6  # the wrist and the Inspire's 6 joints
    assert all(np.isfinite(v) for v in result["policy"].values())
