"""The UniDexTok processor step inside LeRobot pipelines, on real LinkerHand L10 preset poses."""

import json

import numpy as np
import pytest
import torch
from lerobot.configs.types import FeatureType, PipelineFeatureType, PolicyFeature
from lerobot.processor import PolicyProcessorPipeline, ProcessorStepRegistry

from lerobot_unidextok import hands
from lerobot_unidextok.constants import (
    OBS_HAND_TOKEN_FEATURES,
    OBS_HAND_TOKENS,
    OBS_STATE,
)
from lerobot_unidextok.processor import (
    NATIVE_STEP_NAME,
    STEP_NAME,
    HandLayout,
    UDHMToNativeCommandStep,
    UniDexTokStateTokenizerStep,
    hand_layout_from_dataset,
    tokens_to_native,
    udhm_to_native,
)
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

L10 = ["linkerhand_l10", "linkerhand_l10"]


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", "linkerhand_l10"])).save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def step(tok_dir):
    return UniDexTokStateTokenizerStep(hand_layout=L10, pretrained=str(tok_dir))


def test_registered_names_have_no_slash():
    names = ProcessorStepRegistry.list()
    assert STEP_NAME in names and NATIVE_STEP_NAME in names
    assert "/" not in STEP_NAME + NATIVE_STEP_NAME


def test_tokens_and_dequantized_view_match_the_tokenizer(step, l10_states):
    x = torch.from_numpy(l10_states)  # (P, 44)
    out = step.observation({OBS_STATE: x})
    tokens, view = out[OBS_HAND_TOKENS], out[OBS_HAND_TOKEN_FEATURES]
    cfg = step.tokenizer.config
    assert tokens.dtype == torch.int64 and tokens.shape == (
        len(x),
        2 * cfg.num_tokens * cfg.num_groups,
    )
    assert view.dtype == torch.float32 and view.shape == (len(x), 44)
    assert int(tokens.min()) >= 0 and int(tokens.max()) < cfg.codebook_size
    # per hand: encode the right block with the right hand name, decode it back
    right_codes = step.tokenizer.encode(x[:, :22], "linkerhand_l10")  # (P, N, K)
    left_codes = step.tokenizer.encode(x[:, 22:], "linkerhand_l10")
    assert torch.equal(tokens, torch.cat([right_codes.flatten(1), left_codes.flatten(1)], dim=1))
    # the dequantized view is the decoded state on the hand's active DoFs and zero elsewhere, like the data
    active = torch.as_tensor(hands.get("linkerhand_l10").active_mask)
    decoded = step.tokenizer.decode(right_codes, "linkerhand_l10")
    assert torch.equal(view[:, :22], decoded * active)
    assert torch.all(view[:, :22][:, ~active] == 0) and torch.any(decoded[:, ~active] != 0)


def test_unbatched_equals_batched_row_inside_pipeline(step, l10_states):
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    x = torch.from_numpy(l10_states)
    batched = pipe({OBS_STATE: x})
    single = pipe({OBS_STATE: x[2]})
    assert single[OBS_HAND_TOKENS].shape == batched[OBS_HAND_TOKENS].shape[1:]
    assert torch.equal(single[OBS_HAND_TOKENS], batched[OBS_HAND_TOKENS][2])
    torch.testing.assert_close(single[OBS_HAND_TOKEN_FEATURES], batched[OBS_HAND_TOKEN_FEATURES][2])


def test_embedding_representation_width_and_features(tok_dir, l10_states):
    step = UniDexTokStateTokenizerStep(hand_layout=L10, pretrained=str(tok_dir), representation="embedding")
    cfg = step.tokenizer.config
    out = step.observation({OBS_STATE: torch.from_numpy(l10_states)})
    view = out[OBS_HAND_TOKEN_FEATURES]
    assert view.shape == (len(l10_states), 2 * cfg.num_tokens * cfg.codebook_dim)
    # unit-norm code vectors per (hand, token, group)
    norms = view.reshape(len(l10_states), -1, cfg.group_dim).norm(dim=-1)
    torch.testing.assert_close(norms, torch.ones_like(norms))
    feats = step.transform_features(
        {PipelineFeatureType.OBSERVATION: {OBS_STATE: PolicyFeature(FeatureType.STATE, (44,))}}
    )
    obs = feats[PipelineFeatureType.OBSERVATION]
    assert obs[OBS_HAND_TOKEN_FEATURES] == PolicyFeature(FeatureType.ENV, (view.shape[1],))
    assert obs[OBS_HAND_TOKENS].shape == (out[OBS_HAND_TOKENS].shape[1],)
    assert OBS_STATE in obs


def test_pipeline_save_and_reload_is_bit_exact(step, l10_states, tmp_path):
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    saved = json.loads((tmp_path / "policy_preprocessor.json").read_text())
    assert saved["steps"][0]["registry_name"] == STEP_NAME
    assert saved["steps"][0]["config"]["hand_layout"] == L10
    assert (tmp_path / f"policy_preprocessor_step_0_{STEP_NAME}.safetensors").is_file()
    # reload without the original checkpoint folder: weights come from the pipeline's safetensors
    saved["steps"][0]["config"]["pretrained"] = "/nonexistent/checkpoint"
    (tmp_path / "policy_preprocessor.json").write_text(json.dumps(saved))
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    x = torch.from_numpy(l10_states)
    a, b = pipe({OBS_STATE: x}), again({OBS_STATE: x})
    assert torch.equal(a[OBS_HAND_TOKENS], b[OBS_HAND_TOKENS])
    assert torch.equal(a[OBS_HAND_TOKEN_FEATURES], b[OBS_HAND_TOKEN_FEATURES])


def test_reference_only_pipeline_reloads_from_checkpoint_folder(tok_dir, l10_states, tmp_path):
    step = UniDexTokStateTokenizerStep(hand_layout=L10, pretrained=str(tok_dir), embed_weights=False)
    assert step.state_dict() == {} and step.get_config()["tokenizer_config"] is None
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    x = torch.from_numpy(l10_states)
    assert torch.equal(pipe({OBS_STATE: x})[OBS_HAND_TOKENS], again({OBS_STATE: x})[OBS_HAND_TOKENS])


def test_bad_width_names_the_fix(step):
    with pytest.raises(ValueError, match=r"width 30, which matches no UDHM layout.*unidextok-convert"):
        step.observation({OBS_STATE: torch.zeros(4, 30)})
    with pytest.raises(ValueError, match="width 22"):
        step.observation({OBS_STATE: torch.zeros(22)})  # one hand where the layout has two


def test_nan_names_the_frame(step, l10_states):
    x = torch.from_numpy(l10_states.copy())
    x[1, 5] = float("nan")
    with pytest.raises(ValueError, match=r"NaN/inf \(first at \[batch, dim\] = \[1, 5\]\)"):
        step.observation({OBS_STATE: x})


def test_checkpoint_missing_offline_names_unidextok_pull():
    with pytest.raises(FileNotFoundError, match=r"unidextok-pull --repo_id=nobody/missing-tokenizer"):
        UniDexTokStateTokenizerStep(hand_layout=["human"], pretrained="nobody/missing-tokenizer")


def test_layout_from_converted_dataset(l10_dataset):
    layout = hand_layout_from_dataset(l10_dataset)
    assert layout == HandLayout(hands=L10, sides=["right", "left"])
    with pytest.raises(ValueError, match="not '<side>_<udhm joint>'"):
        HandLayout.from_state_names([f"j{i}" for i in range(22)], "human")
    with pytest.raises(ValueError, match="match no UDHM layout"):
        HandLayout.from_state_names(["right_thumb_cmc_flex"] * 10, "human")


def test_udhm_to_native_recovers_real_presets(real_data_dir, l10_states):
    import yaml

    presets = yaml.safe_load((real_data_dir / "linkerhand-ros2-sdk" / "L10_positions.yaml").read_text())
    right = {p["ACTION_NAME"]: p["POSITION"] for p in presets["RIGHT_HAND"]}
    left = {p["ACTION_NAME"]: p["POSITION"] for p in presets["LEFT_HAND"]}
    raw = np.array([right[n] + left[n] for n in right if n in left], dtype=np.float64)  # (P, 20)
    layout = HandLayout(L10, ["right", "left"])
    native = udhm_to_native(torch.from_numpy(l10_states), layout)
    assert native.shape == raw.shape
    np.testing.assert_allclose(native, raw, atol=0.5)  # float32 UDHM round trip, 0-255 units
    post = UDHMToNativeCommandStep(hand_layout=L10, sides=["right", "left"])
    np.testing.assert_allclose(post.action(torch.from_numpy(l10_states)).numpy(), raw, atol=0.5)
    assert post.native_dim() == 2 * hands.get("linkerhand_l10").num_native


def test_tokens_to_native_shape_and_limits(step, l10_states):
    tokens = step.observation({OBS_STATE: torch.from_numpy(l10_states)})[OBS_HAND_TOKENS]
    native = tokens_to_native(tokens, step.tokenizer, HandLayout(L10, ["right", "left"]))
    assert native.shape == (len(l10_states), 20)
    assert native.min() >= 0 and native.max() <= 255  # clipped to the SDK range
    assert tokens_to_native(tokens[0], step.tokenizer, HandLayout(L10, ["right", "left"])).shape == (20,)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_device_follows_input(step, l10_states):
    out = step.observation({OBS_STATE: torch.from_numpy(l10_states).cuda()})
    assert out[OBS_HAND_TOKENS].device.type == "cuda"


def test_hand_outside_vocabulary_needs_allow_unknown(tok_dir):
    with pytest.raises(ValueError, match=r"\['xhand1'\] are not in the tokenizer vocabulary"):
        UniDexTokStateTokenizerStep(hand_layout=["xhand1"], pretrained=str(tok_dir), allow_unknown=False)
    step = UniDexTokStateTokenizerStep(hand_layout=["xhand1"], pretrained=str(tok_dir))
    out = step.observation({OBS_STATE: torch.zeros(22)})
    unknown = step.tokenizer.encode(torch.zeros(1, 22), torch.tensor([step.tokenizer.unknown_hand_id]))
    assert torch.equal(out[OBS_HAND_TOKENS], unknown.flatten())


def test_token_preview_shows_codes_and_decoded_state(step, l10_states):
    from lerobot_unidextok.processor import token_preview

    text = token_preview(step, torch.from_numpy(l10_states[:2]))
    cfg = step.tokenizer.config
    assert text.count("frame ") == 4  # 2 frames x 2 hands
    assert text.count("  tokens ") == 4 * cfg.num_tokens
    first_codes = step.observation({OBS_STATE: torch.from_numpy(l10_states[0])})[OBS_HAND_TOKENS][: cfg.num_groups]
    assert "  tokens " + " ".join(f"{c:2d}" for c in first_codes.tolist()) in text
    assert "input deg" in text and "decoded deg" in text


def test_layout_refuses_a_dataset_that_mixes_hands(tmp_path):
    """A converted LinkerHand sample alternates L10 and L20 episodes: one fixed layout would silently
    tokenise L20 frames as L10, so the layout reader must refuse and name both hands."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.conversion.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["linkerhand"], episodes_per_source=4, frames_per_episode=30)
    report = convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=tmp_path / "ds", progress=False))
    assert {"linkerhand_l10", "linkerhand_l20"} <= set(report.hands)
    with pytest.raises(ValueError, match="mixes hand layouts.*linkerhand_l10.*linkerhand_l20"):
        hand_layout_from_dataset(report.root)
