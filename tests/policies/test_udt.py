"""`<type>_udt`: stock LeRobot policies on UniDexTok hand tokens from lerobot-train flags or a config file.

The slow tests run the real `lerobot-train` CLI in subprocesses on a synthetic whole-robot dataset in the
converted contract (tests/fixtures/robot_udhm.py: 14 G1 arm joints + two Inspire hands), resume with
`--policy.path`, and reload every checkpoint in a fresh process with LeRobot's stock factory.
"""

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from lerobot.configs.policies import PreTrainedConfig
from lerobot.configs.types import FeatureType, PolicyFeature
from linkerhand_udhm import subprocess_env
from robot_udhm import INSPIRE, NATIVE_NAMES, STATE_NAMES, to_converted

from lerobot_unidextok.configs import shipped_config
from lerobot_unidextok.constants import ACTION, OBS_HAND_TOKEN_FEATURES, OBS_HAND_TOKENS, OBS_STATE
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.policies import UDT_CONFIGS, ACTUdtConfig, DiffusionUdtConfig
from lerobot_unidextok.policies.act_udt import make_act_udt_pre_post_processors
from lerobot_unidextok.policies.diffusion_udt import make_diffusion_udt_pre_post_processors
from lerobot_unidextok.processor import NATIVE_TO_UDHM_STEP_NAME, STEP_NAME, UDHM_TO_NATIVE_STEP_NAME
from lerobot_unidextok.tokenizer import EncodingConfig, UniDexTok, UniDexTokConfig

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
TINY_ACT = ["--policy.chunk_size=4", "--policy.n_action_steps=4", "--policy.dim_model=32", "--policy.n_heads=2",
            "--policy.dim_feedforward=64", "--policy.n_encoder_layers=1", "--policy.n_decoder_layers=1",
            "--policy.use_vae=false"]  # fmt: skip
TINY_DIFFUSION = ["--policy.down_dims=[16,32]", "--policy.horizon=8", "--policy.n_action_steps=4",
                  "--policy.num_inference_steps=2", "--policy.diffusion_step_embed_dim=16"]  # fmt: skip


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(2)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=["human", "linkerhand_l10", INSPIRE])
    UniDexTok(cfg).save_pretrained(path)
    return path


class _Meta:
    """What make_policy hands the config: the dataset metadata (LeRobotDatasetMetadata)."""

    def __init__(self, root: Path):
        from lerobot.datasets import LeRobotDatasetMetadata

        self._meta = LeRobotDatasetMetadata("test/g1_like_udhm", root=root)
        self.root, self.features = self._meta.root, self._meta.features


def _config(cls, tok_dir, width: int = 44, **kw):
    return cls(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, (width,))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, (width,))},
        udt_pretrained=str(tok_dir), device="cpu", **kw,
    )  # fmt: skip


def _from_dataset(cls, tok_dir, root: Path, **kw):
    cfg = _config(cls, tok_dir, width=len(STATE_NAMES), **kw)
    cfg._runtime_dataset_meta = _Meta(root)
    cfg.validate_features()
    return cfg


def test_every_wrapped_type_resolves_through_the_stock_factory():
    from lerobot.policies.factory import _make_processors_from_policy_config, get_policy_class

    assert {"act_udt", "diffusion_udt", "vqbet_udt"} <= set(UDT_CONFIGS)
    for udt_type, cls in UDT_CONFIGS.items():
        base = udt_type.removesuffix("_udt")
        assert PreTrainedConfig.get_choice_class(udt_type) is cls
        assert isinstance(cls(), PreTrainedConfig.get_choice_class(base))
        policy_cls = get_policy_class(udt_type)
        assert policy_cls.__name__ == cls.__name__.replace("Config", "Policy")
        assert issubclass(policy_cls, get_policy_class(base)) and policy_cls.name == udt_type
    cfg = _config(ACTUdtConfig, None, udt_hand_layout=[INSPIRE])
    cfg.udt_pretrained = None
    cfg.udt_preset = "tiny"
    cfg.validate_features()
    pre, _ = _make_processors_from_policy_config(cfg)  # LeRobot resolves make_act_udt_pre_post_processors
    assert STEP_NAME in [getattr(type(s), "_registry_name", "") for s in pre.steps]


def test_the_default_tokenizer_is_the_shipped_universal_one_and_a_preset_only_when_asked():
    from lerobot_unidextok.hub.card import _policy_tokenizer
    from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER
    from lerobot_unidextok.tokenizer import UniDexTok

    cfg = ACTUdtConfig(device="cpu")
    assert cfg.udt_pretrained == DEFAULT_TOKENIZER and cfg.untrained_preset() is None
    assert cfg.tokenizer_config() == UniDexTok.from_pretrained(DEFAULT_TOKENIZER).config
    assert _policy_tokenizer({"udt_pretrained": DEFAULT_TOKENIZER, "udt_preset": None}) == DEFAULT_TOKENIZER
    tiny = ACTUdtConfig(device="cpu", udt_preset="tiny")  # explicit request: untrained
    assert tiny.untrained_preset() == "tiny" and tiny.tokenizer_config().num_tokens == 4
    assert _policy_tokenizer({"udt_pretrained": DEFAULT_TOKENIZER, "udt_preset": "tiny"}) == "untrained preset tiny"
    assert ACTUdtConfig(device="cpu", udt_pretrained=None).untrained_preset() == "small"  # as saved before
    assert ACTUdtConfig(device="cpu", udt_pretrained="lab/tok", udt_preset="small").untrained_preset() is None


def test_config_adds_env_state_of_the_tokenizer_width(tok_dir):
    cfg = _config(ACTUdtConfig, tok_dir, udt_hand_layout=[INSPIRE])
    cfg.validate_features()
    assert cfg.udt_hand_layout == [INSPIRE] * 2  # one name broadcast to both blocks
    assert cfg.input_features[OBS_HAND_TOKEN_FEATURES] == PolicyFeature(FeatureType.ENV, (44,))
    emb = _config(ACTUdtConfig, tok_dir, udt_hand_layout=[INSPIRE], udt_representation="embedding")
    emb.validate_features()
    assert emb.input_features[OBS_HAND_TOKEN_FEATURES].shape == (2 * 4 * 256,)  # H * N * codebook_dim


def test_config_errors_name_the_fix(tok_dir, g1_like):
    with pytest.raises(ValueError, match="width 30, which matches no UDHM layout"):
        _config(ACTUdtConfig, tok_dir, width=30, udt_hand_layout=["human"]).validate_features()
    with pytest.raises(ValueError, match="udt_hand_layout"):
        _config(ACTUdtConfig, tok_dir).validate_features()
    with pytest.raises(ValueError, match="udt_range_check must be one of"):
        ACTUdtConfig(udt_range_check="sometimes")
    with pytest.raises(ValueError, match="encoding.rounds must be >= 0"):
        ACTUdtConfig(udt_encoding={"rounds": -1})
    with pytest.raises(ValueError, match="set udt_encoding only"):
        ACTUdtConfig(udt_search_rounds=1, udt_encoding=EncodingConfig(rounds=0))
    meta = _Meta(g1_like["root"])
    meta.features = {**meta.features, OBS_HAND_TOKEN_FEATURES: {"dtype": "float32", "shape": (3,), "names": None}}
    cfg = _config(ACTUdtConfig, tok_dir, width=58)
    cfg._runtime_dataset_meta = meta
    with pytest.raises(ValueError, match="already has 'observation.environment_state'"):
        cfg.validate_features()


def test_whole_robot_layout_comes_from_the_dataset(tok_dir, g1_like):
    """act_udt demanded a hands-only state: a G1 state (14 arms + 2 blocks) must train and decode to 26."""
    cfg = _from_dataset(DiffusionUdtConfig, tok_dir, g1_like["root"])
    assert cfg.udt_hand_layout == [INSPIRE, INSPIRE] and cfg.udt_sides == ["left", "right"]
    assert cfg.udt_state_names == STATE_NAMES
    assert cfg.udt_native_layout["native_names"] == NATIVE_NAMES
    assert cfg.input_features[OBS_HAND_TOKEN_FEATURES].shape == (44,)
    pre, post = make_diffusion_udt_pre_post_processors(cfg)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("AddBatchDimensionProcessorStep") < names.index("UniDexTokStateTokenizerStep")
    assert names.index("UniDexTokStateTokenizerStep") < names.index("NormalizerProcessorStep")
    state = torch.from_numpy(to_converted(g1_like["native_state"][:6])).float()
    tokens = 2 * 4 * 8  # 2 hands x 4 tokens x 8 groups (tiny preset)
    out = pre({OBS_STATE: state[0]})  # one unbatched frame, as at inference
    # every output of the full pre-processor has the batch dimension the state got (the tokens were (64,))
    assert out[OBS_STATE].shape == (1, 58) and out[OBS_HAND_TOKEN_FEATURES].shape == (1, 44)
    assert out[OBS_HAND_TOKENS].shape == (1, tokens) and out[OBS_HAND_TOKENS].dtype == torch.int64
    stacked = pre({OBS_STATE: state.reshape(3, 2, 58)})  # (B, n_obs_steps, D) as diffusion trains
    assert stacked[OBS_HAND_TOKEN_FEATURES].shape == (3, 2, 44) and stacked[OBS_HAND_TOKENS].shape == (3, 2, tokens)
    assert torch.equal(stacked[OBS_HAND_TOKENS][0, 0], out[OBS_HAND_TOKENS][0])
    actions = torch.from_numpy(to_converted(g1_like["native_action"][:2])).float()  # (2, 58) converted
    normalised = pre({OBS_STATE: state[:2], ACTION: actions})[ACTION]  # per hand (unidextok.hand_normalizer)
    assert (normalised - actions).abs().max() > 0.1
    native = post(normalised)
    assert native.shape == (2, 26)
    torch.testing.assert_close(native, torch.from_numpy(g1_like["native_action"][:2]).float(), atol=1e-5, rtol=0)
    assert post.steps[-1]._registry_name == UDHM_TO_NATIVE_STEP_NAME
    off = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"], udt_native_action=False)
    assert make_act_udt_pre_post_processors(off)[1](torch.zeros(2, 58)).shape == (2, 58)


def test_pre_processor_takes_the_robots_native_state(tok_dir, g1_like):
    """The robot's 26-wide state was refused ("width 26, but this step was set up for 58 columns"): the
    pre-processor maps it to the converted layout first, so both give the same policy inputs."""
    from lerobot.configs.types import PipelineFeatureType

    cfg = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"])
    assert cfg.udt_native_state_layout["native_names"] == NATIVE_NAMES
    assert cfg.input_features[OBS_STATE].shape == (58,)  # what the model reads stays the converted state
    pre, _ = make_act_udt_pre_post_processors(cfg)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("NativeToUDHMStateStep") == names.index("UniDexTokStateTokenizerStep") - 1
    native = torch.from_numpy(g1_like["native_state"][:5]).float()
    converted = torch.from_numpy(to_converted(g1_like["native_state"][:5])).float()
    for i in range(5):
        a, b = pre({OBS_STATE: native[i]}), pre({OBS_STATE: converted[i]})
        torch.testing.assert_close(a[OBS_STATE], b[OBS_STATE], atol=1e-6, rtol=0)
        assert torch.equal(a[OBS_HAND_TOKEN_FEATURES], b[OBS_HAND_TOKEN_FEATURES])
    # the features a robot of this layout reports are turned into those the policy reads
    robot = {PipelineFeatureType.OBSERVATION: {OBS_STATE: PolicyFeature(FeatureType.STATE, (26,))}}
    seen = pre.transform_features(robot)[PipelineFeatureType.OBSERVATION]
    assert {k: seen[k] for k in cfg.input_features} == cfg.input_features
    searched = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"], udt_encoding=EncodingConfig(rounds=1))
    step = next(s for s in make_act_udt_pre_post_processors(searched)[0].steps if hasattr(s, "encoding"))
    assert step.encoding is searched.udt_encoding and a[OBS_HAND_TOKENS].shape == step.tokenize(converted[:1])[0].shape
    off = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"], udt_native_state=False)
    assert off.udt_native_state_layout == {}
    with pytest.raises(ValueError, match="width 26, but this step was set up for 58 columns"):
        make_act_udt_pre_post_processors(off)[0]({OBS_STATE: native[0]})


def test_relative_actions_round_trip_through_the_saved_and_reloaded_processors(tok_dir, g1_like, tmp_path):
    """udt_relative_actions: the pre-processor turns absolute actions into action - converted state (also from
    the robot's native state), the post-processor adds the cached state back; after save_pretrained and the
    stock factory's reload (which re-pairs LeRobot's two steps), absolute in == absolute out."""

    for hand_norm in ("off", "auto"):
        _relative_round_trip(tok_dir, g1_like, tmp_path / hand_norm, hand_norm)


def _relative_round_trip(tok_dir, g1_like, tmp_path, hand_norm: str) -> None:
    from lerobot.configs.types import NormalizationMode
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.processor import TransitionKey

    from lerobot_unidextok.blocks import find_udhm_blocks

    cfg = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"], udt_relative_actions=True, udt_hand_norm=hand_norm)
    assert cfg.udt_action_names == STATE_NAMES and cfg.normalization_mapping["ACTION"] == NormalizationMode.IDENTITY
    pre, post = make_act_udt_pre_post_processors(cfg, dataset_stats=_Meta(g1_like["root"])._meta.stats)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("UniDexTokStateTokenizerStep") < names.index("RelativeActionsProcessorStep")
    scaled = hand_norm != "off"  # the offsets of each block scaled by its hand's (unidextok.hand_normalizer)
    if scaled:
        assert names.index("RelativeActionsProcessorStep") == names.index("HandNormalizerStep") - 1
    else:
        assert "HandNormalizerStep" not in names
    assert names.index("RelativeActionsProcessorStep") < names.index("NormalizerProcessorStep")
    post_names = [type(s).__name__ for s in post.steps]
    assert post_names.index("AbsoluteActionsProcessorStep") == post_names.index("UnnormalizerProcessorStep") + 1 + scaled
    assert post_names.index("AbsoluteActionsProcessorStep") < post_names.index("UDHMToNativeCommandStep")
    tmp_path.mkdir()
    pre.save_pretrained(tmp_path)
    post.save_pretrained(tmp_path)
    cfg.save_pretrained(tmp_path)
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(tmp_path))  # what eval / record / rollout do

    native_state = torch.from_numpy(g1_like["native_state"][:8]).float()
    state = torch.from_numpy(to_converted(g1_like["native_state"][:8])).float()  # (8, 58)
    action = torch.stack([torch.from_numpy(to_converted(g1_like["native_action"][i : i + 4])).float()
                          for i in range(8)])  # (8, 4, 58): a chunk of 4 absolute actions per frame  # fmt: skip
    scale = torch.ones(58)
    for block in find_udhm_blocks(STATE_NAMES) if scaled else []:
        s = cfg.udt_hand_stats[ACTION][block.side][INSPIRE]
        rms = (torch.tensor(s["mean"]) ** 2 + torch.tensor(s["std"]) ** 2).sqrt()
        scale[block.slice] = torch.where(rms > 1e-6, rms, 1.0)
    for obs in (state, native_state):
        relative = pre({OBS_STATE: obs, ACTION: action})[ACTION]
        torch.testing.assert_close(relative * scale, action - state[:, None], atol=1e-5, rtol=1e-5)
        steps = list(post.step_through(relative))
        torch.testing.assert_close(steps[-2][TransitionKey.ACTION], action, atol=1e-5, rtol=0)
        native = torch.from_numpy(np.stack([g1_like["native_action"][i : i + 4] for i in range(8)])).float()
        torch.testing.assert_close(steps[-1][TransitionKey.ACTION], native, atol=1e-5, rtol=0)
    assert (relative - action).abs().max() > 0.1  # the state was really taken off


def test_a_checkpoint_saved_with_the_legacy_udt_search_rounds_encodes_as_it_did(tok_dir, g1_like, tmp_path):
    """A policy checkpoint written before udt_encoding: config.json has `udt_search_rounds`, the saved step
    `search_rounds` and its tokenizer_config the flat legacy keys. It loads through the stock factory with both
    upgraded into one EncodingConfig (the tokenizer's own encoding at that many rounds) and tokenises as the same
    policy saved in the new form."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import make_pre_post_processors

    cfg = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"])
    cfg.udt_search_rounds = 1  # as a config.json written then sets it
    cfg._upgrade_legacy_encoding()
    own = UniDexTokConfig.from_pretrained(str(tok_dir)).encoding
    assert cfg.udt_search_rounds is None and cfg.udt_encoding == dataclasses.replace(own, rounds=1)
    pre, post = make_act_udt_pre_post_processors(cfg)
    for folder in (tmp_path / "new", tmp_path / "old"):
        pre.save_pretrained(folder)
        post.save_pretrained(folder)
        cfg.save_pretrained(folder)
    old = tmp_path / "old"
    config = json.loads((old / "config.json").read_text())
    config.pop("udt_encoding")
    (old / "config.json").write_text(json.dumps({**config, "udt_search_rounds": 1}))
    for path in old.glob("policy_preprocessor*.json"):
        pipeline = json.loads(path.read_text())
        for entry in pipeline["steps"]:
            if entry.get("registry_name") == STEP_NAME:
                step_cfg = entry["config"]
                step_cfg.pop("encoding")
                tok_cfg = step_cfg["tokenizer_config"]
                tok_cfg.update({"search_" + k: v for k, v in tok_cfg.pop("encoding").items()})  # the flat legacy keys
                step_cfg["search_rounds"] = 1
        path.write_text(json.dumps(pipeline))
    assert '"search_rounds": 1' in next(old.glob("policy_preprocessor*.json")).read_text()
    state = torch.from_numpy(to_converted(g1_like["native_state"][:6])).float()
    tokens = {}
    for folder in (tmp_path / "new", old):
        loaded = PreTrainedConfig.from_pretrained(folder)
        assert loaded.udt_encoding == cfg.udt_encoding and loaded.udt_search_rounds is None
        pre_loaded, _ = make_pre_post_processors(loaded, pretrained_path=str(folder))
        step = next(s for s in pre_loaded.steps if type(s).__name__ == "UniDexTokStateTokenizerStep")
        assert step.encoding == cfg.udt_encoding and step.tokenizer.config.encoding == own
        tokens[folder.name] = pre_loaded({OBS_STATE: state})[OBS_HAND_TOKENS]
    assert torch.equal(tokens["new"], tokens["old"])


def test_copy_start_makes_the_untrained_policy_copy_the_state(tok_dir, g1_like):
    """udt_copy_start (act_udt_cpu.yaml): with relative actions the action head starts at zero, so before any
    training every action of the chunk is the current state (a LinkerHand robot trained 1000 steps without it
    stayed worse than copying the state: experiments/mix_lerobot_train.py)."""
    from lerobot.processor import TransitionKey

    from lerobot_unidextok.policies.act_udt import ACTUdtPolicy

    stats = _Meta(g1_like["root"])._meta.stats
    state = torch.from_numpy(to_converted(g1_like["native_state"][:3])).float()  # (3, 58)
    for copy_start in (True, False):
        torch.manual_seed(0)
        cfg = _from_dataset(
            ACTUdtConfig, tok_dir, g1_like["root"], udt_relative_actions=True, udt_copy_start=copy_start
        )
        policy = ACTUdtPolicy(cfg).eval()
        pre, post = make_act_udt_pre_post_processors(cfg, dataset_stats=stats)
        with torch.no_grad():
            chunk = policy.predict_action_chunk(pre({OBS_STATE: state}))  # (3, chunk, 58) offsets
        absolute = list(post.step_through(chunk))[-2][TransitionKey.ACTION]  # before the native decoding
        copied = torch.allclose(absolute, state[:, None].expand_as(absolute), atol=1e-6)
        assert copied == copy_start, copy_start
    assert not ACTUdtConfig(udt_copy_start=True).udt_relative_actions  # opt-in; the recipe sets both


def test_relative_actions_refuse_an_action_layout_that_is_not_the_states_first_columns(tok_dir, g1_like):
    meta = _Meta(g1_like["root"])
    shuffled = {**meta.features[ACTION], "names": STATE_NAMES[1:] + STATE_NAMES[:1]}
    meta.features = {**meta.features, ACTION: shuffled}
    cfg = _config(ACTUdtConfig, tok_dir, width=len(STATE_NAMES), udt_relative_actions=True)
    cfg._runtime_dataset_meta = meta
    with pytest.raises(ValueError, match="must be the first columns of observation.state, but action column 0 .* the action holds the same columns in another order: reorder"):
        cfg.validate_features()
    wide = _config(ACTUdtConfig, tok_dir, udt_hand_layout=[INSPIRE], udt_relative_actions=True)
    wide.output_features[ACTION] = PolicyFeature(FeatureType.ACTION, (46,))
    with pytest.raises(ValueError, match="the action is 46 wide and the state 44"):
        wide.validate_features()
    absolute = _config(ACTUdtConfig, tok_dir, width=len(STATE_NAMES))  # absolute actions: any action layout
    absolute._runtime_dataset_meta = meta
    absolute.validate_features()


# ---------------------------------------------------------------------------------------------
# the real lerobot-train CLI
# ---------------------------------------------------------------------------------------------
def _train(args: list[str], out: Path, hf: Path) -> Path:
    base = [str(BIN / "lerobot-train"), "--num_workers=0", f"--output_dir={out}", "--log_freq=1", "--save_freq=3"]
    r = subprocess.run(base + args, env=subprocess_env(HF_HOME=str(hf)), check=False, capture_output=True,
                       text=True, timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    assert "Traceback" not in r.stdout + r.stderr and "is installed but cannot be loaded" not in r.stderr
    return out / "checkpoints" / "last" / "pretrained_model"


def _help_text(text: str, flag: str) -> str:
    """The description argparse prints under `flag` in a --help listing, without its "(default: ...)"."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith(flag + " "))
    block = [lines[start].strip().removeprefix(flag).split(maxsplit=1)[1:]]
    for line in lines[start + 1 :]:
        if line.strip().startswith("--") or not line.strip():
            break
        block.append([line.strip()])
    words = " ".join(w for part in block for w in part)
    return words.split("(default:")[0].strip()


@pytest.mark.slow
def test_lerobot_train_help_finds_the_plugin_without_the_flag_and_describes_every_udt_field(tmp_path):
    """Without --policy.discover_packages_path lerobot-train printed 217 lines (two torchcodec tracebacks)
    ending in "Couldn't find a choice class for 'act_udt'"; with it, the udt_* flags had no descriptions."""
    from dataclasses import fields

    from lerobot_unidextok.policies import UdtConfigMixin

    r = subprocess.run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--help"], check=False,
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    assert "Traceback" not in r.stdout + r.stderr and "is installed but cannot be loaded" not in r.stderr
    for f in fields(UdtConfigMixin):
        if f.name == "udt_encoding":  # a nested config: its comment heads its group, its fields are flags
            group = r.stdout.split("Optional ['policy.udt_encoding']:\n", 1)[1].split("\n\n", 1)[0]
            assert len(group.split()) >= 4, group
            for sub in fields(EncodingConfig):
                description = _help_text(r.stdout, f"--policy.udt_encoding.{sub.name}")
                assert len(description.split()) >= 4, (sub.name, description)
            continue
        description = _help_text(r.stdout, f"--policy.{f.name}")
        assert len(description.split()) >= 4, (f.name, description)  # a sentence, not just the type


@pytest.mark.slow
def test_lerobot_train_on_a_dataset_never_converted_is_one_error_line(tok_dir, tmp_path):
    """`lerobot-train --policy.type=act_udt` on a plain LeRobot v3.0 dataset ended in a traceback with rc 1; the
    plugin turns this package's user errors inside LeRobot's CLIs into the one `error:` line and exit 2 of its
    own tools, with the command that converts the dataset."""
    from l10_robot import write_l10_robot

    raw = write_l10_robot(tmp_path / "raw", episodes=2)
    r = subprocess.run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--dataset.repo_id=test/raw",
                        f"--dataset.root={raw}", f"--policy.udt_pretrained={tok_dir}", "--policy.device=cpu",
                        "--policy.push_to_hub=false", "--steps=2", f"--output_dir={tmp_path / 'out'}", *TINY_ACT],
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error: ")]
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-3000:]
    assert len(errors) == 1 and "is not a converted UDHM dataset" in errors[0] and "unidextok-convert" in errors[0]


RELOAD = """
import sys, torch
from lerobot.configs.parser import load_plugin
load_plugin("lerobot_unidextok")  # what --policy.discover_packages_path does in LeRobot's CLIs
from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.factory import get_policy_class, make_pre_post_processors
from lerobot.datasets import LeRobotDataset
from lerobot.processor import TransitionKey
import numpy as np
from lerobot_unidextok.data import UdhmDatasetMeta
ds = LeRobotDataset("test/g1_like_udhm", root=sys.argv[1])
layout = UdhmDatasetMeta(sys.argv[1]).native_layout()
native_states = np.load(sys.argv[2])  # (N, 26) the robot's own states of the dataset frames
for path in sys.argv[3:]:
    cfg = PreTrainedConfig.from_pretrained(path)
    policy = get_policy_class(cfg.type).from_pretrained(path).eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=path)
    acts = []
    for i in (0, 5, 70):
        raw = policy.select_action(pre({"observation.state": ds[i]["observation.state"]}))
        stages = list(post.step_through(raw))  # ..., unnormalised converted action, native action
        converted, native = stages[-2][TransitionKey.ACTION], stages[-1][TransitionKey.ACTION]
        assert converted.shape[-1] == 58 and torch.equal(post(raw), native)
        # the native action is the dataset's recorded layout applied to the converted action: arms copied,
        # each Inspire block decoded with its own side's table
        want = layout.to_native(converted.detach().cpu().numpy())
        assert np.abs(native.numpy() - want).max() < 1e-5, (native, want)
        acts.append(native)
    a = torch.stack(acts)  # (3, 1, 26)
    assert torch.isfinite(a).all(), a
    # the robot's native 26-wide state gives the action its converted 58-wide state gives
    for i in (0, 5, 70):
        outs = []
        for state in (ds[i]["observation.state"], torch.from_numpy(native_states[i])):
            policy.reset()
            torch.manual_seed(0)  # diffusion samples noise
            outs.append(post(policy.select_action(pre({"observation.state": state}))))
        assert outs[1].shape == (1, 26) and torch.allclose(outs[0], outs[1], atol=1e-4), (outs[0] - outs[1]).abs().max()
    print(cfg.type, type(policy).__name__, tuple(a.shape))
"""


@pytest.mark.slow
def test_lerobot_train_act_and_diffusion_resume_and_reload(tok_dir, g1_like, tmp_path):
    """`--policy.type=act` failed (no image / env state) and diffusion failed on stacked states; resuming
    with `--policy.path` rejected `--policy.discover_packages_path`. Both from flags / config file only.
    The reloaded post-processor's native action equals the dataset's native layout applied to the policy's
    converted action (the old check, hands in [0, 1], held by clipping alone), and the reloaded pre-processor
    takes the robot's native state as well as the converted one (it refused the native width), also inside
    `lerobot-rollout` driving a robot of the native layout. The diffusion policy trains without
    --policy.discover_packages_path: LeRobot's own plugin convention imports the `lerobot_policy_unidextok`
    distribution in register_third_party_plugins()."""
    root, hf = g1_like["root"], tmp_path / "hf"
    data = ["--dataset.repo_id=test/g1_like_udhm", f"--dataset.root={root}", f"--policy.udt_pretrained={tok_dir}"]
    plugin = "--policy.discover_packages_path=lerobot_unidextok"
    # ACT from the shipped config file, overridden by flags
    act = _train([f"--config_path={shipped_config('lerobot/act_udt')}", plugin, *data, "--steps=3",
                  "--batch_size=4", "--num_workers=0", *TINY_ACT], tmp_path / "act", hf)  # fmt: skip
    # Diffusion from flags only, no plugin flag (n_obs_steps=2: the step sees (B, 2, 58) states)
    diff = _train(["--policy.type=diffusion_udt", *data, "--policy.device=cpu", "--policy.push_to_hub=false",
                   "--steps=3", "--batch_size=4", "--wandb.enable=false", *TINY_DIFFUSION], tmp_path / "diff", hf)  # fmt: skip
    for ckpt, udt_type in ((act, "act_udt"), (diff, "diffusion_udt")):
        cfg = json.loads((ckpt / "config.json").read_text())
        assert cfg["type"] == udt_type and cfg["udt_state_names"] == STATE_NAMES
        pre = [s["registry_name"] for s in json.loads((ckpt / "policy_preprocessor.json").read_text())["steps"]]
        assert pre.index("to_batch_processor") < pre.index(STEP_NAME) < pre.index("normalizer_processor")
        assert pre.index(NATIVE_TO_UDHM_STEP_NAME) == pre.index(STEP_NAME) - 1
        post = [s["registry_name"] for s in json.loads((ckpt / "policy_postprocessor.json").read_text())["steps"]]
        assert post[-1] == UDHM_TO_NATIVE_STEP_NAME
    # resume the diffusion policy from its checkpoint with the same plugin flag
    resumed = _train([f"--policy.path={diff}", plugin, *data[:2], "--policy.device=cpu", "--policy.push_to_hub=false",
                      "--steps=3", "--batch_size=4", "--wandb.enable=false"], tmp_path / "resumed", hf)  # fmt: skip
    assert json.loads((resumed / "config.json").read_text())["type"] == "diffusion_udt"
    # a fresh process reloads each checkpoint with the stock factory and returns the robot's 26-wide action,
    # from the converted state and from the robot's native state alike
    np.save(tmp_path / "native.npy", g1_like["native_state"])
    r = subprocess.run([sys.executable, "-c", RELOAD, str(root), str(tmp_path / "native.npy"), str(act), str(diff),
                        str(resumed)], check=False,
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf2")), capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert [line for line in r.stdout.splitlines() if "Policy (" in line] == [
        "act_udt ACTUdtPolicy (3, 1, 26)",
        "diffusion_udt DiffusionUdtPolicy (3, 1, 26)",
        "diffusion_udt DiffusionUdtPolicy (3, 1, 26)",
    ]
    _rollout_drives_a_native_robot(act, root, g1_like["native_state"], tmp_path)


def _rollout_drives_a_native_robot(ckpt: Path, root: Path, native: np.ndarray, tmp_path: Path) -> None:
    """`lerobot-rollout --policy.path` with a robot reporting the native layout (26 `.pos` values, recorded
    order; tests/fixtures/replay_robot): the checkpoint's processors take its state and send it 26-wide
    actions, the first one that of the stock factory for that state."""
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    np.save(tmp_path / "native_states.npy", native)
    frame, sent = 5, tmp_path / "sent.npy"
    fixtures = str(REPO / "tests" / "fixtures")
    env = subprocess_env(HF_HOME=str(tmp_path / "hf3"))
    env["PYTHONPATH"] = f"{fixtures}:{env['PYTHONPATH']}" if env.get("PYTHONPATH") else fixtures
    r = subprocess.run([str(BIN / "lerobot-rollout"), "--robot.discover_packages_path=replay_robot",
                        "--robot.type=unidextok_replay", f"--robot.dataset_root={root}",
                        f"--robot.states={tmp_path / 'native_states.npy'}", f"--robot.frame={frame}",
                        f"--robot.actions_out={sent}", f"--policy.path={ckpt}", "--strategy.type=base",
                        "--task=pick up the bottle", "--duration=1", "--fps=30", "--device=cpu", "--play_sounds=false",
                        "--return_to_initial_position=false"], env=env, check=False, capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    actions = np.load(sent)
    assert actions.ndim == 2 and actions.shape[1] == 26 and len(actions) >= 1, actions.shape
    cfg = PreTrainedConfig.from_pretrained(ckpt)
    policy = get_policy_class(cfg.type).from_pretrained(ckpt).eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=ckpt)
    with torch.inference_mode():
        want = post(policy.select_action(pre({OBS_STATE: torch.from_numpy(native[frame]).float()})))
    np.testing.assert_allclose(actions[0], want[0].numpy(), atol=1e-5)


@pytest.mark.slow
def test_real_g1_inspire_select_action_returns_the_native_action(tok_dir, g1_dataset, real_data_dir, tmp_path):
    """Real G1 + Inspire episodes converted by unidextok-convert (extra check, skips without ../shared):
    act_udt returned 12 hand values for a robot that needs 26, and refused the robot's own 26-wide state
    ("observation.state has width 26, but this step was set up for 58 columns"). In a fresh process, the
    reloaded checkpoint now gives the robot's recorded native frames exactly the actions of their converted
    frames, and a wrong width gets one line naming both layouts."""
    from g1_real import native_states

    assert UdhmDatasetMeta(g1_dataset).native_layout().native_dim == 26  # 14 arm joints + 2 x 6 Inspire values
    native = np.concatenate([native_states(real_data_dir, e) for e in range(3)])  # the 3 converted episodes
    np.save(tmp_path / "native.npy", native)
    ckpt = _train(["--policy.type=act_udt", "--policy.discover_packages_path=lerobot_unidextok",
                   "--dataset.repo_id=test/g1_udhm", f"--dataset.root={g1_dataset}", "--policy.device=cpu",
                   "--policy.push_to_hub=false", f"--policy.udt_pretrained={tok_dir}", "--steps=3", "--batch_size=4",
                   "--wandb.enable=false", *TINY_ACT], tmp_path / "train", tmp_path / "hf")  # fmt: skip
    check = f"""
import lerobot_policy_unidextok, torch
import numpy as np
from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.factory import get_policy_class, make_pre_post_processors
from lerobot.datasets import LeRobotDataset
path = "{ckpt}"
cfg = PreTrainedConfig.from_pretrained(path)
policy = get_policy_class(cfg.type).from_pretrained(path).eval()
pre, post = make_pre_post_processors(cfg, pretrained_path=path)
ds = LeRobotDataset("test/g1_udhm", root="{g1_dataset}")
native = torch.from_numpy(np.load("{tmp_path / "native.npy"}"))
assert native.shape == (len(ds), 26)
def act(state):
    policy.reset()
    return post(policy.select_action(pre({{"observation.state": state}})))
a = torch.stack([act(ds[i]["observation.state"]) for i in (0, 100, 700)])
assert torch.isfinite(a).all()
b = torch.stack([act(native[i]) for i in (0, 100, 700)])  # the robot's own state, as a robot sends it
assert torch.equal(a, b), (a - b).abs().max()
try:
    act(native[0, :25])
except ValueError as err:
    print(str(err))
print(tuple(a.shape))
"""
    r = subprocess.run([sys.executable, "-c", check], check=False, env=subprocess_env(HF_HOME=str(tmp_path / "hf2")),
                       capture_output=True, text=True, timeout=180)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    *_, error, shape = r.stdout.strip().splitlines()
    assert shape == "(3, 1, 26)"
    assert error.startswith("observation.state has width 25, neither the native nor the converted layout")
    assert "native 26 columns: kLeftShoulderPitch, kLeftShoulderRoll, ..., kRightWristYaw (14 passthrough)" in error
    assert "converted 58 columns: 14 passthrough + 2 UDHM blocks (left, right)" in error


def test_a_single_robot_dataset_trains_exactly_as_before_the_mixing(tok_dir, g1_like):
    """Mixing added per-row hands and a hand identity to the tokenizer step; a dataset of one robot takes none
    of it: no hand vocabulary, no hand ids, the fixed-layout step (not the mixed one), and the tokens and
    environment state it gives are those of a bare `UniDexTokStateTokenizerStep` on the same tokenizer (the
    single-robot tensors, no identity columns appended)."""
    from lerobot_unidextok.constants import OBS_HAND_IDS
    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep

    cfg = _from_dataset(ACTUdtConfig, tok_dir, g1_like["root"])
    assert cfg.udt_hand_vocabulary == [] and OBS_HAND_IDS not in cfg.input_features
    pre, _ = make_act_udt_pre_post_processors(cfg)
    names = [type(s).__name__ for s in pre.steps]
    assert "UniDexTokStateTokenizerStep" in names and "UniDexTokMixedTokenizerStep" not in names
    step = next(s for s in pre.steps if type(s).__name__ == "UniDexTokStateTokenizerStep")
    bare = UniDexTokStateTokenizerStep(hand_layout=list(step.hand_layout), state_names=list(step.state_names),
                                       pretrained=str(tok_dir), encoding=step.encoding)  # fmt: skip
    converted = torch.from_numpy(to_converted(g1_like["native_state"][:4])).float()
    tokens, features = bare.tokenize(converted)  # (4, H*N*K), (4, F)
    for i in range(4):
        ours = pre({OBS_STATE: converted[i]})
        assert torch.equal(ours[OBS_HAND_TOKENS].reshape(-1), tokens[i])
        torch.testing.assert_close(
            ours[OBS_HAND_TOKEN_FEATURES].reshape(-1), features[i], atol=1e-5, rtol=0
        )  # batch of 4 vs 1
    assert cfg.input_features[OBS_HAND_TOKEN_FEATURES].shape == (features.shape[-1],)
