"""act_udt: a plugin ACT whose pre-processor holds the UniDexTok step, trained through lerobot-train."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from lerobot.configs.types import FeatureType, PolicyFeature
from linkerhand_udhm import subprocess_env

from lerobot_unidextok.constants import ACTION, OBS_HAND_TOKEN_FEATURES, OBS_STATE
from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig
from lerobot_unidextok.policies.act_udt.processor_act_udt import (
    make_act_udt_pre_post_processors,
)
from lerobot_unidextok.processor import NATIVE_STEP_NAME, STEP_NAME
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

BIN = Path(sys.executable).parent
TINY_ACT = ["--policy.chunk_size=4", "--policy.n_action_steps=4", "--policy.dim_model=32", "--policy.n_heads=2",
            "--policy.dim_feedforward=64", "--policy.n_encoder_layers=1", "--policy.n_decoder_layers=1",
            "--policy.use_vae=false"]  # fmt: skip


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(2)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    hands = ["human", "linkerhand_l10", "inspire_rh56_unitree"]
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=hands)).save_pretrained(path)
    return path


def _config(tok_dir, width: int = 44, **kw) -> ACTUdtConfig:
    return ACTUdtConfig(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, (width,))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, (width,))},
        udt_pretrained=str(tok_dir), device="cpu", **kw,
    )  # fmt: skip


def test_config_adds_env_state_of_the_tokenizer_width(tok_dir):
    cfg = _config(tok_dir, udt_hand_layout=["linkerhand_l10"])
    cfg.validate_features()
    assert cfg.udt_hand_layout == ["linkerhand_l10"] * 2  # one name broadcast to both blocks
    assert cfg.input_features[OBS_HAND_TOKEN_FEATURES] == PolicyFeature(FeatureType.ENV, (44,))
    emb = _config(tok_dir, udt_hand_layout=["linkerhand_l10"], udt_representation="embedding")
    emb.validate_features()
    assert emb.input_features[OBS_HAND_TOKEN_FEATURES].shape == (2 * 4 * 256,)  # H * N * codebook_dim


def test_config_errors_name_the_fix(tok_dir):
    with pytest.raises(ValueError, match="width 30, which matches no UDHM layout"):
        _config(tok_dir, width=30, udt_hand_layout=["human"]).validate_features()
    with pytest.raises(ValueError, match="udt_hand_layout"):
        _config(tok_dir).validate_features()


def test_processors_place_the_step_before_batching(tok_dir):
    cfg = _config(
        tok_dir,
        udt_hand_layout=["linkerhand_l10"],
        udt_command_hands=["linkerhand_l10"] * 2,
        udt_sides=["right", "left"],
    )
    cfg.validate_features()
    pre, post = make_act_udt_pre_post_processors(cfg)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("UniDexTokStateTokenizerStep") < names.index("AddBatchDimensionProcessorStep")
    out = pre({OBS_STATE: torch.zeros(44)})  # a single unbatched frame
    assert out[OBS_HAND_TOKEN_FEATURES].shape == (1, 44)  # batched after the step
    assert post(torch.zeros(3, 44)).shape == (3, 20)  # two L10 hands, native SDK units


@pytest.mark.slow
def test_lerobot_train_then_reload_in_fresh_process(tok_dir, g1_dataset, tmp_path):
    """Real G1 + Inspire episodes converted by unidextok-convert's pipeline -> lerobot-train -> reload."""
    out = tmp_path / "train"
    inspire = "inspire_rh56_unitree"
    args = [str(BIN / "lerobot-train"), "--policy.type=act_udt", "--policy.discover_packages_path=lerobot_unidextok",
            "--dataset.repo_id=test/g1_udhm", f"--dataset.root={g1_dataset}", "--policy.device=cpu",
            "--policy.push_to_hub=false", f"--policy.udt_pretrained={tok_dir}", "--steps=3", "--batch_size=4",
            f"--policy.udt_command_hands=[{inspire},{inspire}]",
            "--num_workers=0", f"--output_dir={out}", "--save_freq=3", "--log_freq=1", "--wandb.enable=false",
            *TINY_ACT]  # fmt: skip
    r = subprocess.run(args, env=subprocess_env(HF_HOME=str(tmp_path / "hf")), check=False, capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    ckpt = out / "checkpoints" / "000003" / "pretrained_model"
    pre_json = json.loads((ckpt / "policy_preprocessor.json").read_text())
    steps = [s["registry_name"] for s in pre_json["steps"]]
    assert steps.index(STEP_NAME) < steps.index("to_batch_processor")
    tok_cfg = next(s for s in pre_json["steps"] if s["registry_name"] == STEP_NAME)["config"]
    assert tok_cfg["hand_layout"] == [
        inspire,
        inspire,
    ]  # read from the dataset's hand_type column
    assert (ckpt / f"policy_preprocessor_step_1_{STEP_NAME}.safetensors").is_file()
    post_json = json.loads((ckpt / "policy_postprocessor.json").read_text())
    native = next(s for s in post_json["steps"] if s["registry_name"] == NATIVE_STEP_NAME)["config"]
    assert native["sides"] == ["left", "right"]  # block order of the converted dataset

    # a fresh process: plugin loaded by name (as LeRobot's CLIs do), then select_action on dataset frames
    check = f"""
import torch
from lerobot.configs.parser import load_plugin
load_plugin("lerobot_unidextok")
from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.factory import get_policy_class, make_pre_post_processors
from lerobot.datasets import LeRobotDataset
path = "{ckpt}"
cfg = PreTrainedConfig.from_pretrained(path)
policy = get_policy_class(cfg.type).from_pretrained(path).eval()
pre, post = make_pre_post_processors(cfg, pretrained_path=path)
ds = LeRobotDataset("test/g1_udhm", root="{g1_dataset}")
acts = []
for i in (0, 100, 700):
    frame = {{"observation.state": ds[i]["observation.state"]}}
    acts.append(post(policy.select_action(pre(frame))))
a = torch.stack(acts)
assert torch.isfinite(a).all() and a.min() >= 0 and a.max() <= 1, a  # Inspire (Unitree) native range
print(type(policy).__name__, tuple(a.shape))
"""
    r = subprocess.run([sys.executable, "-c", check], check=False, env=subprocess_env(HF_HOME=str(tmp_path / "hf2")),
                       capture_output=True, text=True, timeout=180)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip().splitlines()[-1] == "ACTUdtPolicy (3, 1, 12)"  # 2 Inspire hands x 6 native DoFs
