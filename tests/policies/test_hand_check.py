"""The tokenizer is asked about a dataset's hands only when its tokens are the policy's input (issue 55).

A robot with a Unitree Dex3-1 hand (registered, simulated) on a tokenizer that was not trained on it: the
documented `lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu)` stopped with "the tokenizer was
not trained on hands ['unitree_dex3_1']" also with `--policy.udt_hand_input=state` and `--policy.udt_pretrained=null`,
where no trained token reaches the policy. LeRobot's own `lerobot-train` code runs here in this process, two updates.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, UNIVERSAL_SMALL
from lerobot_unidextok.processor import STEP_NAME
from lerobot_unidextok.tokenizer import UniDexTokConfig

HAND = "unitree_dex3_1"
PREFIX = "r_dex3_"  # the robot's columns: r_dex3_<joint>, in the hand spec's joint order


@pytest.fixture(scope="module")
def dex3_robot(tmp_path_factory) -> Path:
    """A raw LeRobot v3.0 robot with a right Dex3-1 (moves between key poses inside its raw range), converted by
    the project's converter."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples.motion import key_pose_motion

    spec = hands.get(HAND)
    names = [f"{PREFIX}{j}" for j in spec.joint_names]
    lo, hi = spec.raw_range("right").T
    base = tmp_path_factory.mktemp("dex3")
    features = {key: {"dtype": "float32", "shape": (len(names),), "names": names}
                for key in ("observation.state", "action")}  # fmt: skip
    ds = LeRobotDataset.create(repo_id="test/dex3_robot", fps=30, features=features, root=base / "raw",
                               robot_type="unitree_dex3_1_right", use_videos=False)  # fmt: skip
    for ep in range(2):
        keys = np.random.default_rng(ep).uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), size=(4, len(names)))
        values = key_pose_motion(keys, 31, seed=ep).astype(np.float32)
        for state, action in zip(values[:-1], values[1:], strict=True):
            ds.add_frame({"observation.state": state, "action": action, "task": "grasp the cube"})
        ds.save_episode()
    ds.finalize()
    root = base / "udhm"
    convert(ConvertOptions(source="lerobot", input=base / "raw", root=root, repo_id="test/dex3_udhm",
                           source_options={"hands": {"right": f"{HAND}:{PREFIX}"}}, progress=False))  # fmt: skip
    return root


def _lerobot_train(root: Path, out: Path, flags: list[str]) -> Path:
    """The documented command (`act_udt_cpu.yaml`), two updates, through LeRobot's `lerobot-train` code."""
    import draccus
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.scripts.lerobot_train import train

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies, as LeRobot's CLIs discover them)
    from lerobot_unidextok.configs import resolve_config_path

    args = ["--dataset.repo_id=test/dex3_udhm", f"--dataset.root={root}", "--steps=2", "--batch_size=4",
            "--save_freq=2", "--log_freq=1", f"--output_dir={out}", *flags]  # fmt: skip
    train(draccus.parse(TrainPipelineConfig, config_path=resolve_config_path("lerobot/act_udt_cpu"), args=args))
    return out / "checkpoints" / "last" / "pretrained_model"


def test_the_tokenizer_does_not_know_the_hand():
    """The premise: universal-small (trained before the Dex3-1 was registered) has no trained row for it."""
    config = UniDexTokConfig.from_pretrained(UNIVERSAL_SMALL)
    assert HAND in hands.names() and HAND not in (config.trained_hands or config.hand_names)


@pytest.mark.parametrize("flags", [
    [f"--policy.udt_pretrained={UNIVERSAL_SMALL}", "--policy.udt_hand_input=state"],  # tokens held at zero
    ["--policy.udt_pretrained=null"],  # an untrained tokenizer: it knows no hand, so none is refused
], ids=["state_input", "untrained_tokenizer"])  # fmt: skip
def test_a_hand_the_tokenizer_does_not_know_trains_when_its_tokens_are_not_the_input(dex3_robot, tmp_path, flags):
    model = _lerobot_train(dex3_robot, tmp_path / "run", flags)
    assert (model / "model.safetensors").is_file()
    config = json.loads((model / "config.json").read_text())
    assert config["udt_hand_layout"] == [HAND] and config["udt_allow_unknown"] is False  # the user's setting, kept
    steps = json.loads((model / "policy_preprocessor.json").read_text())["steps"]
    tokenizer = next(s["config"] for s in steps if s.get("registry_name") == STEP_NAME)
    assert tokenizer["encode"] is (config["udt_hand_input"] != "state")  # the state alone: the tokenizer never runs


def test_the_documented_command_trains_the_hand_with_the_default_tokenizer(dex3_robot, tmp_path):
    """No flag at all: the default tokenizer knows the Dex3-1, and its tokens are the policy's input."""
    model = _lerobot_train(dex3_robot, tmp_path / "run", [])
    config = json.loads((model / "config.json").read_text())
    assert config["udt_pretrained"] == DEFAULT_TOKENIZER and config["udt_hand_input"] == "both"
    assert config["udt_hand_layout"] == [HAND] and config["udt_allow_unknown"] is False


def test_the_tokens_of_a_trained_tokenizer_still_refuse_a_hand_it_does_not_know(dex3_robot, tmp_path):
    """With the default hand input (`both`: the policy reads the tokens) the check holds, naming the fix."""
    with pytest.raises(ValueError, match=rf"not trained on hands \['{HAND}'\].*udt_allow_unknown=true"):
        _lerobot_train(dex3_robot, tmp_path / "run", [f"--policy.udt_pretrained={UNIVERSAL_SMALL}"])
