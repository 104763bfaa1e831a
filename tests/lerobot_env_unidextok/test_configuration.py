"""`--env.type=unidextok` refuses, before anything runs, a checkpoint trained on another task of the simulator.
Before, a GraspLift-v0 policy on FingerPress-v0 ran until its first step and was told "it was trained on another
robot or hand ... bind it with unidextok-deploy": the hand was right, the task was not."""

import json
import sys

import pytest

from lerobot_env_unidextok.columns import TASK_COLUMNS, WRIST_NAMES
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
from lerobot_env_unidextok.errors import SimInputError
from lerobot_unidextok.blocks import udhm_state_names


def _checkpoint(folder, task: str | None):
    """A `<type>_udt` checkpoint's config.json as lerobot-train writes it: the converted state's column names."""
    folder.mkdir()
    names = [*WRIST_NAMES, *(TASK_COLUMNS[task] if task else ("arm_0", "arm_1")), *udhm_state_names(["right"])]
    (folder / "config.json").write_text(json.dumps({"type": "act_udt", "udt_state_names": names}))
    return folder


@pytest.mark.parametrize(("trained", "runs"), [("GraspLift-v0", "FingerPress-v0"), ("FingerPress-v0", "GraspLift-v0")])
def test_a_policy_of_another_task_is_named_as_such(tmp_path, monkeypatch, trained, runs):
    ckpt = _checkpoint(tmp_path / "ckpt", trained)
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={ckpt}", "--env.type=unidextok"])
    with pytest.raises(SimInputError) as err:
        UniDexTokEnvConfig(task=runs, hand="shadow")
    said = str(err.value)
    assert said.startswith(f"the policy {ckpt} was trained on the simulator's {trained} task") and f"{TASK_COLUMNS[trained][0]}" in said
    assert f"--env.task={runs}" in said and f"pass --env.task={trained}" in said
    assert "another robot or hand" not in said


def test_a_policy_of_this_task_or_of_a_real_robot_passes(tmp_path, monkeypatch):
    for name, task in (("same", "FingerPress-v0"), ("robot", None)):
        ckpt = _checkpoint(tmp_path / name, task)
        monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={ckpt}"])
        assert UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow").task == "FingerPress-v0"
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", "--policy.path=lab/some-hub-repo"])  # not a folder: not read
    assert UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow").task == "FingerPress-v0"
