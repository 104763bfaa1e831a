"""`--env.type=unidextok` refuses, before anything runs, a checkpoint that does not fit the simulator, naming what
differs: another task (before: a GraspLift-v0 policy on FingerPress-v0 ran to its first step and was told "it
was trained on another robot or hand ... bind it with unidextok-deploy"), a mix never bound to a hand (before: a
KeyError traceback at the first step), a policy bound to another hand."""

import json
import sys

import pytest

from lerobot_env_unidextok.columns import TASK_COLUMNS, WRIST_NAMES
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
from lerobot_env_unidextok.errors import SimInputError
from lerobot_unidextok.blocks import udhm_state_names


def _checkpoint(folder, task: str | None, **fields):
    """A `<type>_udt` checkpoint's config.json with the fields lerobot-train and unidextok-deploy write."""
    folder.mkdir()
    names = [*WRIST_NAMES, *(TASK_COLUMNS[task] if task else ("arm_0", "arm_1")), *udhm_state_names(["right"])]
    (folder / "config.json").write_text(json.dumps({"type": "act_udt", "udt_state_names": names, **fields}))
    return folder


def _env(monkeypatch, ckpt, task="FingerPress-v0", hand="shadow") -> UniDexTokEnvConfig:
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={ckpt}", "--env.type=unidextok"])
    return UniDexTokEnvConfig(task=task, hand=hand)


@pytest.mark.parametrize(("trained", "runs"), [("GraspLift-v0", "FingerPress-v0"), ("FingerPress-v0", "GraspLift-v0")])
def test_a_policy_of_another_task_is_named_as_such(tmp_path, monkeypatch, trained, runs):
    ckpt = _checkpoint(tmp_path / "ckpt", trained, udt_native_state_layout={"hands": [{"hand": "shadow"}]})
    with pytest.raises(SimInputError) as err:
        _env(monkeypatch, ckpt, task=runs)
    said = str(err.value)
    assert said.startswith(f"the policy {ckpt} was trained on the simulator's {trained} task") and TASK_COLUMNS[trained][0] in said
    assert f"--env.task={runs}" in said and f"pass --env.task={trained}" in said
    assert "another robot or hand" not in said


def test_a_mix_never_bound_is_told_to_bind_to_the_envs_hand(tmp_path, monkeypatch):
    mix = {"udt_hand_vocabulary": ["inspire_rh56_unitree", "shadow"], "udt_fixed_hand_ids": []}
    ckpt = _checkpoint(tmp_path / "mix", "FingerPress-v0", **mix)
    with pytest.raises(SimInputError) as err:
        _env(monkeypatch, ckpt)
    said = str(err.value)
    assert "is a mix of hands (inspire_rh56_unitree, shadow) never bound to one" in said and "--env.hand=shadow" in said
    assert f"unidextok-deploy --checkpoint={ckpt} --robot=<a converted dataset of shadow" in said
    assert "--zero_shot" not in said
    with pytest.raises(SimInputError, match="--zero_shot=true \\(it never had this hand\\)"):
        _env(monkeypatch, ckpt, hand="allegro")


def test_a_policy_bound_to_another_hand_names_both_hands(tmp_path, monkeypatch):
    bound = {"udt_hand_vocabulary": ["inspire_rh56_unitree", "shadow"], "udt_fixed_hand_ids": [0],
             "udt_native_state_layout": {"hands": [{"side": "right", "hand": "inspire_rh56_unitree"}]}}  # fmt: skip
    ckpt = _checkpoint(tmp_path / "bound", "FingerPress-v0", **bound)
    with pytest.raises(SimInputError) as err:
        _env(monkeypatch, ckpt)
    said = str(err.value)
    assert f"the policy {ckpt} reads the native state of inspire_rh56_unitree" in said
    assert "trained on another robot or hand than --env.hand=shadow" in said and "--env.hand=inspire_rh56_unitree" in said
    assert _env(monkeypatch, ckpt, hand="inspire_rh56_unitree").hand == "inspire_rh56_unitree"


def test_a_policy_that_fits_or_cannot_be_read_passes(tmp_path, monkeypatch):
    fits = _checkpoint(tmp_path / "same", "FingerPress-v0", udt_native_state_layout={"hands": [{"hand": "shadow"}]})
    robot = _checkpoint(tmp_path / "robot", None)
    for ckpt in (fits, robot, "lab/some-hub-repo"):  # a Hub id is not read
        assert _env(monkeypatch, ckpt).task == "FingerPress-v0"
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "config.json").write_text("[1, 2")
    assert _env(monkeypatch, tmp_path / "broken").hand == "shadow"  # LeRobot's own loading says what is wrong


def test_a_policy_trained_with_or_without_the_fingertips_is_told_the_env_flag(tmp_path, monkeypatch):
    from lerobot_env_unidextok.columns import FINGERTIP_COLUMNS

    layout = {"udt_native_state_layout": {"hands": [{"hand": "shadow"}]}}
    plain = _checkpoint(tmp_path / "plain", "FingerPress-v0", **layout)
    tips = tmp_path / "tips"
    tips.mkdir()
    names = [*WRIST_NAMES, *TASK_COLUMNS["FingerPress-v0"], *FINGERTIP_COLUMNS, *udhm_state_names(["right"])]
    (tips / "config.json").write_text(json.dumps({"type": "act_udt", "udt_state_names": names, **layout}))
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={tips}", "--env.type=unidextok"])
    with pytest.raises(SimInputError, match=r"trained with the fingertips' columns .* pass --env.fingertips=true$"):
        UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow")
    env = UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow", fingertips=True)
    assert env.gym_kwargs["fingertips"] is True
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={plain}", "--env.type=unidextok"])
    without = UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow")
    assert env.features["agent_pos"].shape[0] == without.features["agent_pos"].shape[0] + 15
    with pytest.raises(SimInputError, match="trained without the fingertips' columns .* pass --env.fingertips=false$"):
        UniDexTokEnvConfig(task="FingerPress-v0", hand="shadow", fingertips=True)
