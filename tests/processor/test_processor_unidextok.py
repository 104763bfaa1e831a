"""The UniDexTok processor step inside LeRobot pipelines, on synthetic whole-robot and hands-only states.

Fixtures live in the repository (tests/fixtures/robot_udhm.py, written independently of the package's
constants); the real LinkerHand presets in ../shared are an extra check that skips without them.
"""

import json
import logging
import math

import numpy as np
import pytest
import torch
from lerobot.configs.types import FeatureType, NormalizationMode, PipelineFeatureType, PolicyFeature
from lerobot.processor import NormalizerProcessorStep, PolicyProcessorPipeline, ProcessorStepRegistry
from robot_udhm import ARM_NAMES, INSPIRE, NATIVE_NAMES, STATE_NAMES, UDHM_JOINTS, inspire_states

from lerobot_unidextok import hands
from lerobot_unidextok.constants import OBS_HAND_TOKEN_FEATURES, OBS_HAND_TOKENS, OBS_STATE
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.processor import (
    STEP_NAME,
    UDHM_TO_NATIVE_STEP_NAME,
    HandLayout,
    UDHMToNativeCommandStep,
    UniDexTokStateTokenizerStep,
    tokens_to_native,
    udhm_to_native,
)
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig, UniDexTok, UniDexTokConfig

PAIR = [INSPIRE, INSPIRE]


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=["human", INSPIRE, "linkerhand_l10"])
    UniDexTok(cfg).save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def step(tok_dir):
    return UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir))


@pytest.fixture(scope="module")
def states():
    """(40, 44) float32 UDHM radians: left then right Inspire block."""
    return torch.from_numpy(inspire_states(40, seed=3))


@pytest.fixture(scope="module")
def robot_step(tok_dir):
    return UniDexTokStateTokenizerStep(hand_layout=PAIR, state_names=STATE_NAMES, pretrained=str(tok_dir))


def test_registered_names_have_no_slash():
    names = ProcessorStepRegistry.list()
    assert STEP_NAME in names and UDHM_TO_NATIVE_STEP_NAME in names
    assert "/" not in STEP_NAME + UDHM_TO_NATIVE_STEP_NAME


def test_tokens_and_dequantized_view_match_the_tokenizer(step, states):
    out = step.observation({OBS_STATE: states})
    tokens, view = out[OBS_HAND_TOKENS], out[OBS_HAND_TOKEN_FEATURES]
    cfg = step.tokenizer.config
    assert tokens.dtype == torch.int64 and tokens.shape == (len(states), 2 * cfg.num_tokens * cfg.num_groups)
    assert view.dtype == torch.float32 and view.shape == (len(states), 44)
    assert int(tokens.min()) >= 0 and int(tokens.max()) < cfg.codebook_size
    # per hand: encode each block with the hand name, decode it back
    left = step.tokenizer.encode(states[:, :22], INSPIRE)  # (B, N, K)
    right = step.tokenizer.encode(states[:, 22:], INSPIRE)
    assert torch.equal(tokens, torch.cat([left.flatten(1), right.flatten(1)], dim=1))
    # the dequantized view is the decoded state on the hand's active DoFs and zero elsewhere, like the data
    active = torch.zeros(22, dtype=torch.bool)
    active[[UDHM_JOINTS.index(j) for j in ("pinky_mcp_flex", "thumb_cmc_spread", "index_mcp_flex")]] = True
    decoded = step.tokenizer.decode(left, INSPIRE)
    assert torch.equal(view[:, :22][:, active], decoded[:, active])
    assert torch.all(view[:, UDHM_JOINTS.index("index_pip_flex")] == 0)
    assert torch.any(decoded[:, UDHM_JOINTS.index("index_pip_flex")] != 0)


def test_unbatched_equals_batched_row_inside_pipeline(step, states):
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    batched = pipe({OBS_STATE: states})
    single = pipe({OBS_STATE: states[2]})
    assert single[OBS_HAND_TOKENS].shape == batched[OBS_HAND_TOKENS].shape[1:]
    assert torch.equal(single[OBS_HAND_TOKENS], batched[OBS_HAND_TOKENS][2])
    torch.testing.assert_close(single[OBS_HAND_TOKEN_FEATURES], batched[OBS_HAND_TOKEN_FEATURES][2])


def test_temporal_stack_keeps_its_shape(step, states):
    """Diffusion-style stacked observations (B, T, D) failed with 'must be (D,) or (B, D)'."""
    stacked = states[:24].reshape(8, 3, 44)  # (B, T, D)
    out = step.observation({OBS_STATE: stacked})
    flat = step.observation({OBS_STATE: states[:24]})
    assert out[OBS_HAND_TOKENS].shape == (8, 3, flat[OBS_HAND_TOKENS].shape[-1])
    assert torch.equal(out[OBS_HAND_TOKENS].reshape(24, -1), flat[OBS_HAND_TOKENS])
    assert torch.equal(out[OBS_HAND_TOKEN_FEATURES].reshape(24, -1), flat[OBS_HAND_TOKEN_FEATURES])


def test_whole_robot_state_tokenises_only_the_hand_blocks(robot_step, step, states):
    """A 58-wide G1 state (14 arm joints + 2 blocks) used to fail on width; arms must not affect tokens."""
    arms = torch.randn(len(states), 14) * 0.3
    whole = torch.cat([arms, states], dim=1)  # names = STATE_NAMES
    out = robot_step.observation({OBS_STATE: whole})
    hands_only = step.observation({OBS_STATE: states})
    assert torch.equal(out[OBS_HAND_TOKENS], hands_only[OBS_HAND_TOKENS])
    assert torch.equal(out[OBS_HAND_TOKEN_FEATURES], hands_only[OBS_HAND_TOKEN_FEATURES])
    assert torch.equal(out[OBS_STATE], whole)  # the state itself passes unchanged
    other_arms = robot_step.observation({OBS_STATE: torch.cat([arms + 0.2, states], dim=1)})
    assert torch.equal(other_arms[OBS_HAND_TOKENS], out[OBS_HAND_TOKENS])
    # blocks found by name, not position: hands first, arms after gives the same tokens
    moved = UniDexTokStateTokenizerStep(hand_layout=PAIR, state_names=STATE_NAMES[14:] + ARM_NAMES,
                                        tokenizer_config=robot_step.tokenizer_config)  # fmt: skip
    moved.load_state_dict(robot_step.state_dict())
    assert torch.equal(moved.observation({OBS_STATE: torch.cat([states, arms], 1)})[OBS_HAND_TOKENS],
                       out[OBS_HAND_TOKENS])  # fmt: skip
    with pytest.raises(ValueError, match=r"width 44, but this step was set up for 58 columns \(14 passthrough"):
        robot_step.observation({OBS_STATE: states})


def test_embedding_representation_width_and_features(tok_dir, states):
    step = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), representation="embedding")
    cfg = step.tokenizer.config
    view = step.observation({OBS_STATE: states})[OBS_HAND_TOKEN_FEATURES]
    assert view.shape == (len(states), 2 * cfg.num_tokens * cfg.codebook_dim)
    norms = view.reshape(len(states), -1, cfg.group_dim).norm(dim=-1)  # unit-norm code vectors
    torch.testing.assert_close(norms, torch.ones_like(norms))
    feats = step.transform_features(
        {PipelineFeatureType.OBSERVATION: {OBS_STATE: PolicyFeature(FeatureType.STATE, (44,))}}
    )
    obs = feats[PipelineFeatureType.OBSERVATION]
    assert obs[OBS_HAND_TOKEN_FEATURES] == PolicyFeature(FeatureType.ENV, (view.shape[1],))
    assert obs[OBS_HAND_TOKENS].shape == (2 * cfg.num_tokens * cfg.num_groups,)
    assert OBS_STATE in obs


def test_pipeline_save_and_reload_is_bit_exact(robot_step, states, tmp_path):
    pipe = PolicyProcessorPipeline(steps=[robot_step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    saved = json.loads((tmp_path / "policy_preprocessor.json").read_text())
    assert saved["steps"][0]["registry_name"] == STEP_NAME
    assert saved["steps"][0]["config"]["hand_layout"] == PAIR
    assert saved["steps"][0]["config"]["state_names"] == STATE_NAMES
    assert (tmp_path / f"policy_preprocessor_step_0_{STEP_NAME}.safetensors").is_file()
    # reload without the original checkpoint folder: weights come from the pipeline's safetensors
    saved["steps"][0]["config"]["pretrained"] = "/nonexistent/checkpoint"
    (tmp_path / "policy_preprocessor.json").write_text(json.dumps(saved))
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    x = torch.cat([torch.zeros(len(states), 14), states], dim=1)
    a, b = pipe({OBS_STATE: x}), again({OBS_STATE: x})
    assert torch.equal(a[OBS_HAND_TOKENS], b[OBS_HAND_TOKENS])
    assert torch.equal(a[OBS_HAND_TOKEN_FEATURES], b[OBS_HAND_TOKEN_FEATURES])


def test_reference_only_pipeline_reloads_from_checkpoint_folder(tok_dir, states, tmp_path):
    step = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), embed_weights=False)
    assert step.state_dict() == {} and step.get_config()["tokenizer_config"] is None
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    assert torch.equal(pipe({OBS_STATE: states})[OBS_HAND_TOKENS], again({OBS_STATE: states})[OBS_HAND_TOKENS])


def test_bad_width_names_the_fix(step):
    """The message names the widths that would work (a wrong list there, e.g. 66 for two hands, misleads)."""
    known = r"known widths: 22 \(1 hand\), 44 \(2 hands\)\)\."
    with pytest.raises(ValueError, match=rf"width 30, which matches no UDHM layout.*{known}.*unidextok-convert"):
        step.observation({OBS_STATE: torch.zeros(4, 30)})
    with pytest.raises(ValueError, match="width 22"):
        step.observation({OBS_STATE: torch.zeros(22)})  # one hand where the layout has two


def test_nan_names_the_frame(step, states):
    x = states.clone()
    x[1, 5] = float("nan")
    with pytest.raises(ValueError, match=r"NaN/inf \(batch rows \[1\]; first at column 5\), in a hand block"):
        step.observation({OBS_STATE: x})


def test_a_nan_arm_an_all_zero_hand_and_an_empty_batch_are_named_for_what_they_are(robot_step, states):
    """Before: a NaN in an arm column got "mask untracked hands in the converter", an all-zero state "looks
    normalised", and an empty batch a RuntimeError from inside torch."""
    x = torch.cat([torch.zeros(len(states), 14), states], dim=1)
    arm = x.clone()
    arm[2, 3] = float("nan")
    name = robot_step.state_names[3]
    with pytest.raises(ValueError, match=rf"rows \[2\]; first at column 3 \({name}\)\): a column outside the hand blocks"):
        robot_step.observation({OBS_STATE: arm})
    zero = x.clone()
    zero[:, 14:36] = 0.0
    with pytest.raises(ValueError, match=r"block 0 is all zeros, a pose the .* hand cannot take. An absent hand"):
        robot_step.observation({OBS_STATE: zero})
    with pytest.raises(ValueError, match=r"empty batch \(shape \(0, 58\)\): feed at least one frame"):
        robot_step.observation({OBS_STATE: x[:0]})


def test_degrees_are_refused(step, states):
    """A state in degrees (90 for a right angle) used to be tokenised without a word."""
    with pytest.raises(ValueError, match=r"look like degrees.*deg2rad"):
        step.observation({OBS_STATE: torch.rad2deg(states)})


@pytest.mark.parametrize("mode", [NormalizationMode.MEAN_STD, NormalizationMode.MIN_MAX])
def test_step_after_the_normalizer_is_refused(step, states, mode):
    """Placed after LeRobot's normalizer the step tokenised z-scores (decoded states reached -7 rad)."""
    x = states.numpy()
    stats = {OBS_STATE: {"mean": x.mean(0), "std": x.std(0), "min": x.min(0), "max": x.max(0)}}
    norm = NormalizerProcessorStep(features={OBS_STATE: PolicyFeature(FeatureType.STATE, (44,))},
                                   norm_map={FeatureType.STATE: mode}, stats=stats)  # fmt: skip
    wrong = PolicyProcessorPipeline(steps=[norm, step], name="policy_preprocessor")
    with pytest.raises(ValueError, match=r"looks normalised.*before `normalizer_processor`"):
        wrong({OBS_STATE: states})
    right = PolicyProcessorPipeline(steps=[step, norm], name="policy_preprocessor")
    assert right({OBS_STATE: states})[OBS_HAND_TOKENS].shape[0] == len(states)


def test_range_check_warn_and_off(tok_dir, states, caplog):
    deg = torch.rad2deg(states)
    warn = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), range_check="warn")
    with caplog.at_level(logging.WARNING):
        warn.observation({OBS_STATE: deg})
    assert "look like degrees" in caplog.text
    off = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), range_check="off")
    assert off.observation({OBS_STATE: deg})[OBS_HAND_TOKENS].shape[0] == len(states)
    with pytest.raises(ValueError, match="range_check must be one of"):
        UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), range_check="maybe")


def test_checkpoint_missing_offline_names_unidextok_pull():
    with pytest.raises(FileNotFoundError, match=r"unidextok-pull --repo_id=nobody/missing-tokenizer"):
        UniDexTokStateTokenizerStep(hand_layout=["human"], pretrained="nobody/missing-tokenizer")


def test_hand_outside_vocabulary_is_refused_or_zero_shot(tok_dir, caplog):
    with pytest.raises(ValueError, match=r"not trained on hands \['xhand1'\].*allow_unknown=True"):
        UniDexTokStateTokenizerStep(hand_layout=["xhand1"], pretrained=str(tok_dir))
    with caplog.at_level(logging.WARNING):
        step = UniDexTokStateTokenizerStep(hand_layout=["xhand1"], pretrained=str(tok_dir), allow_unknown=True)
    assert "['xhand1'] were never trained" in caplog.text and "unknown-hand embedding" in caplog.text
    out = step.observation({OBS_STATE: torch.zeros(22)})
    unknown = step.tokenizer.encode(torch.zeros(1, 22), torch.tensor([step.tokenizer.unknown_hand_id]))
    assert torch.equal(out[OBS_HAND_TOKENS], unknown.flatten())


def test_vocabulary_hand_never_trained_is_refused(tmp_path, caplog):
    """A tokenizer trained on one hand listed all 11 vocabulary hands and ran 'shadow' silently."""
    torch.manual_seed(0)
    cfg = UniDexTokConfig.from_preset("tiny", trained_hands=[INSPIRE])  # default vocabulary: 11 hands
    assert "shadow" in cfg.hand_names
    UniDexTok(cfg).save_pretrained(tmp_path / "tok")
    with pytest.raises(ValueError, match=r"not trained on hands \['shadow'\] \(it knows \['inspire_rh56_unitree'\]\)"):
        UniDexTokStateTokenizerStep(hand_layout=["shadow"] * 2, pretrained=str(tmp_path / "tok"))
    step = UniDexTokStateTokenizerStep(hand_layout=["shadow"], pretrained=str(tmp_path / "tok"), allow_unknown=True)
    assert step.hand_ids.tolist() == [step.tokenizer.unknown_hand_id]  # not the untrained 'shadow' row
    assert UniDexTokStateTokenizerStep(hand_layout=[INSPIRE], pretrained=str(tmp_path / "tok")).hand_ids.tolist() == [
        cfg.hand_names.index(INSPIRE)
    ]


def test_hand_without_spec_fails_before_logging(tok_dir, caplog):
    """An unknown hand logged 'using its unknown-hand embedding' and then raised anyway."""
    with caplog.at_level(logging.INFO), pytest.raises(ValueError, match=r"\['mystery'\] have no hand spec"):
        UniDexTokStateTokenizerStep(hand_layout=["mystery"], pretrained=str(tok_dir), allow_unknown=True)
    assert "unknown-hand embedding" not in caplog.text


def test_layout_from_converted_whole_robot_dataset(g1_like):
    layout = UdhmDatasetMeta(g1_like["root"]).hand_layout()
    assert layout.hands == PAIR and layout.sides == ["left", "right"]
    assert layout.state_names == STATE_NAMES and layout.passthrough_names == ARM_NAMES
    np.testing.assert_array_equal(layout.block_columns, np.arange(14, 58))
    step = UniDexTokStateTokenizerStep.from_dataset(g1_like["root"], preset="tiny")
    assert step.layout.state_dim == 58
    with pytest.raises(ValueError, match="none of the 22 state names"):
        HandLayout.from_state_names([f"j{i}" for i in range(22)], "human")
    with pytest.raises(ValueError, match="incomplete or out of order"):
        HandLayout.from_state_names(["right_thumb_cmc_flex"] * 10, "human")


def test_native_layout_decodes_the_dataset_action_back_to_the_robot(g1_like):
    """Decoding returns the 26-wide G1 vector: arms bit-identical, hands back in Unitree's [0, 1] units."""
    from lerobot.datasets import LeRobotDataset

    layout = UdhmDatasetMeta(g1_like["root"]).native_layout()
    assert layout.native_names == NATIVE_NAMES and layout.native_dim == 26
    ds = LeRobotDataset("test/g1_like_udhm", root=g1_like["root"])
    actions = torch.stack([ds[i]["action"] for i in range(len(ds))])  # (N, 58)
    native = layout.to_native(actions.numpy())
    expected = g1_like["native_action"]
    assert native.shape == expected.shape == (len(ds), 26)
    np.testing.assert_array_equal(native[:, :14].astype(np.float32), expected[:, :14])  # arms untouched
    np.testing.assert_allclose(native[:, 14:], expected[:, 14:], atol=1e-5)  # float32 UDHM round trip
    post = UDHMToNativeCommandStep.from_layout(layout)
    chunk = post.action(actions[:12].reshape(2, 6, 58))  # (B, T, D) action chunks keep their shape
    assert chunk.shape == (2, 6, 26) and chunk.dtype == torch.float32
    again = UDHMToNativeCommandStep(**json.loads(json.dumps(post.get_config())))
    torch.testing.assert_close(again.action(actions[:3]), torch.as_tensor(native[:3], dtype=torch.float32))
    feats = post.transform_features({PipelineFeatureType.ACTION: {"action": PolicyFeature(FeatureType.ACTION, (58,))}})
    assert feats[PipelineFeatureType.ACTION]["action"].shape == (26,)


def test_without_a_conversion_record_a_whole_robot_is_not_decoded_but_hands_only_are(
    g1_like, g1_like_hands, tmp_path, caplog
):
    """lerobot-edit-dataset drops meta/unidextok_conversion.json. Where the robot's hand columns sat among its arms
    is then unknown: rebuilding the native vector from the hand specs (arms first) was silently wrong for a source
    whose hands come first, so a whole robot gets no native layout and a warning naming the fix; a hands-only
    vector is the blocks' hand joints in block order."""
    import shutil

    for name, fixture in (("robot", g1_like), ("hands", g1_like_hands)):
        shutil.copytree(fixture["root"], tmp_path / name)
        (tmp_path / name / "meta" / "unidextok_conversion.json").unlink()
    with caplog.at_level("WARNING"):
        assert UdhmDatasetMeta(tmp_path / "robot").native_layout() is None
    assert "where the robot's hand columns sit" in caplog.text and "Copy meta/unidextok_conversion.json" in caplog.text
    layout = UdhmDatasetMeta(tmp_path / "hands").native_layout()
    assert layout.native_names == [f"{s}_{j}" for s in ("left", "right") for j in hands.get(INSPIRE).joint_names]
    x = inspire_states(1)
    np.testing.assert_allclose(layout.to_native(x)[0], udhm_to_native(x, HandLayout(PAIR, ["left", "right"]))[0])


def test_tokens_to_native_decodes_each_block_with_its_side(step, states):
    """tokens -> decode per block -> that block's side of the hand spec (the old check, values in [0, 1],
    held by clipping alone). Catches blocks decoded with the wrong side or in the wrong order."""
    tokens = step.observation({OBS_STATE: states})[OBS_HAND_TOKENS]
    layout = HandLayout(PAIR, ["left", "right"])
    native = tokens_to_native(tokens, step.tokenizer, layout)
    cfg = step.tokenizer.config
    codes = tokens.reshape(len(states), 2, cfg.num_tokens, cfg.num_groups)
    spec = hands.get(INSPIRE)
    want = np.concatenate([spec.from_udhm(step.tokenizer.decode(codes[:, k], INSPIRE).numpy(), side=side)
                           for k, side in enumerate(["left", "right"])], axis=1)  # fmt: skip
    assert native.shape == (len(states), 12)
    np.testing.assert_allclose(native, want, atol=1e-6)
    np.testing.assert_allclose(tokens_to_native(tokens[0], step.tokenizer, layout), want[0], atol=1e-6)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_device_follows_input(step, states):
    out = step.observation({OBS_STATE: states.cuda()})
    assert out[OBS_HAND_TOKENS].device.type == "cuda"


def test_token_preview_shows_codes_and_decoded_state(step, states):
    from lerobot_unidextok.processor import token_preview

    text = token_preview(step, states[:2])
    cfg = step.tokenizer.config
    assert text.count("frame ") == 4  # 2 frames x 2 hands
    assert text.count("  tokens ") == 4 * cfg.num_tokens
    first_codes = step.observation({OBS_STATE: states[0]})[OBS_HAND_TOKENS][: cfg.num_groups]
    assert "  tokens " + " ".join(f"{c:2d}" for c in first_codes.tolist()) in text
    assert "input deg" in text and "decoded deg" in text
    # the numbers are degrees of the first hand's active joints, and the error is over all of them
    lines = text.splitlines()
    row = next(i for i, ln in enumerate(lines) if ln.endswith("input deg"))
    shown = [float(v) for v in lines[row].split()[:-2]]
    decoded = [float(v) for v in lines[row + 1].split()[:-2]]
    rows = step.hand_blocks(states[:1])[0, 0]  # (22,) rad, frame 0, hand 0
    active = step.active_masks[0]
    want = np.degrees(rows[active].numpy())[: len(shown)]
    np.testing.assert_allclose(shown, want, atol=0.051)
    codes = step.tokenize(states[:1])[0].reshape(-1, cfg.num_tokens, cfg.num_groups)  # (H, N, K)
    back = step.tokenizer.decode(codes, step.hand_ids)[0]  # (22,) hand 0, rad
    np.testing.assert_allclose(decoded, np.degrees(back[active].numpy())[: len(decoded)], atol=0.051)
    err = float(lines[0].split("= ")[1].split(" deg")[0])
    assert err == pytest.approx(float((back - rows).abs()[active].mean()) * 180 / math.pi, abs=0.0051)
    assert lines[0].startswith(f"frame 0 hand 0 ({PAIR[0]}): {cfg.num_tokens} tokens x {cfg.num_groups} codes")


def test_token_preview_of_a_whole_robot_state(robot_step, step, states):
    """The preview reshaped the whole state into hand rows, so arm columns showed up as hand angles."""
    from lerobot_unidextok.processor import token_preview

    whole = torch.cat([torch.full((2, 14), 0.5), states[:2]], dim=1)  # (2, 58)
    assert token_preview(robot_step, whole) == token_preview(step, states[:2])


def test_layout_refuses_a_dataset_that_mixes_hands(tmp_path):
    """A converted LinkerHand sample alternates L10 and L20 episodes: one fixed layout would silently
    tokenise L20 frames as L10, so the layout reader must refuse and name both hands."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["linkerhand"], episodes_per_source=4, frames_per_episode=30)
    report = convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=tmp_path / "ds", progress=False))
    assert {"linkerhand_l10", "linkerhand_l20"} <= set(report.hands)
    with pytest.raises(ValueError, match="mixes hand layouts.*linkerhand_l10.*linkerhand_l20"):
        UdhmDatasetMeta(report.root).hand_layout()


# ---------------------------------------------------------------------------------------------
# mixed-hand layouts: each block is tokenised and decoded with its own hand
# ---------------------------------------------------------------------------------------------
MIXED = ["human", "linkerhand_l10", INSPIRE]


@pytest.fixture(scope="module")
def hand_aware_tok_dir(tmp_path_factory):
    """A tokenizer whose output depends on the hand. A freshly built one does not (adaLN-Zero starts every
    block as the identity, so the hand embedding has no effect): its conditioning layers get random weights."""
    torch.manual_seed(7)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=MIXED))
    with torch.no_grad():
        for name, param in model.named_parameters():
            if "adaLN_modulation" in name or name == "hand_embed.weight":
                param.normal_(0.0, 0.5)
    path = tmp_path_factory.mktemp("tok_mixed") / "unidextok-tiny"
    model.save_pretrained(path)
    return path


def _block(hand: str, side: str, frames: int, seed: int) -> torch.Tensor:
    """(frames, 22) float32 UDHM radians of `hand` from uniformly drawn native values (human: in-limit angles)."""
    rng = np.random.default_rng(seed)
    spec = hands.get(hand)
    if hand == "human":
        from lerobot_unidextok import udhm

        return torch.from_numpy(udhm.sample_angles(rng, (frames,), margin=0.05).astype(np.float32))
    lo, hi = spec.raw_range(side).T
    raw = rng.uniform(lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo), size=(frames, len(lo)))
    return torch.from_numpy(np.asarray(spec.to_udhm(raw, side=side), dtype=np.float32))


@pytest.mark.parametrize("layout", [MIXED[:2], MIXED[1::-1], MIXED], ids=["human+l10", "l10+human", "three-blocks"])
def test_mixed_hand_blocks_are_tokenised_with_their_own_hand(hand_aware_tok_dir, layout):
    """Tokens of block i are encode(block_i, hand_i); the view is decode(...) masked by hand_i's active DoFs.

    Catches: blocks tokenised with one hand id for all (`_hand_ids` repeated in the wrong order, e.g.
    `repeat_interleave` instead of `repeat`, or hands swapped across blocks), a mask taken from the wrong
    block, blocks read in the wrong order. Every earlier layout had the same hand in both blocks."""
    sides = ["right", "left", "right"]
    blocks = [_block(h, sides[i], 12, seed=i) for i, h in enumerate(layout)]
    x = torch.cat(blocks, dim=1)  # (12, 22 * H)
    step = UniDexTokStateTokenizerStep(hand_layout=layout, pretrained=str(hand_aware_tok_dir))
    out = step.observation({OBS_STATE: x})
    tok = step.tokenizer
    codes = [tok.encode(b, h) for b, h in zip(blocks, layout, strict=True)]  # (12, N, K) each
    assert torch.equal(out[OBS_HAND_TOKENS], torch.cat([c.flatten(1) for c in codes], dim=1))
    # the hand matters for this tokenizer, so the comparison above can fail
    assert not torch.equal(tok.encode(blocks[0], layout[1]), codes[0])
    for i, (hand, c) in enumerate(zip(layout, codes, strict=True)):
        view = out[OBS_HAND_TOKEN_FEATURES][:, 22 * i : 22 * (i + 1)]
        active = torch.from_numpy(hands.get(hand).active_mask)
        assert torch.equal(view[:, active], tok.decode(c, hand)[:, active])
        assert torch.count_nonzero(view[:, ~active]) == 0
    # one frame at a time gives the same tokens as the batch (ids per row in block order for B = 1 too)
    assert torch.equal(step.observation({OBS_STATE: x[3]})[OBS_HAND_TOKENS], out[OBS_HAND_TOKENS][3])


def test_mixed_whole_robot_state_and_native_decoding(hand_aware_tok_dir):
    """Arms + a left human hand + a right L10: blocks found by name, decoded per hand and side.

    Catches: `udhm_to_native` decoding every block with the first hand's spec or the other side's table
    (the per-side rest offsets of the Inspire hand differ between left and right)."""
    from robot_udhm import ARM_NAMES

    names = ARM_NAMES + [f"left_{j}" for j in UDHM_JOINTS] + [f"right_{j}" for j in UDHM_JOINTS]
    human, l10 = _block("human", "left", 10, seed=1), _block("linkerhand_l10", "right", 10, seed=2)
    x = torch.cat([torch.randn(10, 14) * 0.3, human, l10], dim=1)  # (10, 58)
    step = UniDexTokStateTokenizerStep(hand_layout=["human", "linkerhand_l10"], state_names=names,
                                       pretrained=str(hand_aware_tok_dir))  # fmt: skip
    expected = torch.cat([step.tokenizer.encode(human, "human").flatten(1),
                          step.tokenizer.encode(l10, "linkerhand_l10").flatten(1)], dim=1)  # fmt: skip
    assert torch.equal(step.observation({OBS_STATE: x})[OBS_HAND_TOKENS], expected)

    inspire_left, l10_right = _block(INSPIRE, "left", 10, seed=3), _block("linkerhand_l10", "right", 10, seed=4)
    layout = HandLayout([INSPIRE, "linkerhand_l10"], ["left", "right"])
    native = udhm_to_native(torch.cat([inspire_left, l10_right], dim=1), layout)
    want = np.concatenate([hands.get(INSPIRE).from_udhm(inspire_left.numpy(), side="left"),
                           hands.get("linkerhand_l10").from_udhm(l10_right.numpy(), side="right")], axis=1)  # fmt: skip
    assert native.shape == (10, 6 + 10)
    np.testing.assert_allclose(native, want, atol=1e-5)
    wrong_side = hands.get(INSPIRE).from_udhm(inspire_left.numpy(), side="right")
    assert np.abs(wrong_side - want[:, :6]).max() > 0.01  # sides matter, so the comparison above can fail


# ---------------------------------------------------------------------------------------------
# extra checks on real data (skip without ../shared)
# ---------------------------------------------------------------------------------------------
def test_udhm_to_native_recovers_real_l10_presets(real_data_dir, tok_dir):
    import yaml
    from linkerhand_udhm import l10_preset_states

    l10_states = l10_preset_states(real_data_dir)  # (P, 44) right + left presets
    presets = yaml.safe_load((real_data_dir / "linkerhand-ros2-sdk" / "L10_positions.yaml").read_text())
    right = {p["ACTION_NAME"]: p["POSITION"] for p in presets["RIGHT_HAND"]}
    left = {p["ACTION_NAME"]: p["POSITION"] for p in presets["LEFT_HAND"]}
    raw = np.array([right[n] + left[n] for n in right if n in left], dtype=np.float64)  # (P, 20)
    layout = HandLayout(["linkerhand_l10"] * 2, ["right", "left"])
    np.testing.assert_allclose(udhm_to_native(torch.from_numpy(l10_states), layout), raw, atol=0.5)
    post = UDHMToNativeCommandStep(hand_layout=["linkerhand_l10"] * 2, sides=["right", "left"])
    np.testing.assert_allclose(post.action(torch.from_numpy(l10_states)).numpy(), raw, atol=0.5)
    step = UniDexTokStateTokenizerStep(hand_layout=["linkerhand_l10"] * 2, pretrained=str(tok_dir))
    assert step.observation({OBS_STATE: torch.from_numpy(l10_states)})[OBS_HAND_TOKENS].shape[0] == len(raw)


def test_udhm_to_native_with_a_whole_robot_layout_gives_the_native_vector():
    """A step built from a whole robot's state names decodes a converted 58-wide G1 vector back to Unitree's
    26 native columns: the arm passthrough by name, then each Inspire hand. Catches the state names dropped
    on the way to the native layout (`state_names or None` -> `and None`: hands only, arms lost)."""
    from robot_udhm import native_motion, to_converted

    native = native_motion(6, seed=1)  # (6, 26) arms + left hand + right hand, Unitree's order and units
    out = udhm_to_native(to_converted(native), HandLayout(PAIR, ["left", "right"], STATE_NAMES))
    assert out.shape == (6, 26)
    np.testing.assert_allclose(out, native, atol=1e-5)


def test_the_default_tokenizer_is_the_shipped_universal_one_and_a_preset_only_when_asked():
    from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER

    shipped = UniDexTok.from_pretrained(DEFAULT_TOKENIZER)
    step = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE])
    assert step.pretrained == DEFAULT_TOKENIZER and step.tokenizer.config == shipped.config
    for (name, a), (_, b) in zip(step.tokenizer.state_dict().items(), shipped.state_dict().items(), strict=True):
        assert torch.equal(a, b), name
    untrained = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE], preset="tiny")  # explicit request
    assert untrained.pretrained is None and untrained.tokenizer.config.num_tokens == 4
    assert untrained.get_config()["tokenizer_config"] is not None  # a reload rebuilds the tiny model, not the default
    assert UniDexTokStateTokenizerStep(hand_layout=[INSPIRE], pretrained=None).tokenizer.config.trained_hands == []


def test_the_step_encodes_as_its_tokenizer_does_unless_told_and_keeps_it_on_reload():
    """By default (`encoding=None`) the step encodes with its tokenizer's own encoding: for the shipped one,
    the decoder-aware search, which decodes closer to the state on the hands' active DoFs than the nearest codes
    (`encoding=NEAREST_CODES`). Both settings survive a reload, the override unchanged. (`unidextok/universal-small`
    by its id: the searching one, whichever shipped id is the default.)"""
    from lerobot_unidextok.pretrained import UNIVERSAL_SMALL

    states = torch.from_numpy(inspire_states(16, seed=2))  # (16, 44) two Inspire hands
    default = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE], pretrained=UNIVERSAL_SMALL)
    nearest = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE], pretrained=UNIVERSAL_SMALL,
                                          encoding=NEAREST_CODES)  # fmt: skip
    tok = default.tokenizer
    assert default.encoding is None and tok.config.encoding.rounds > 0 and nearest.encoding is NEAREST_CODES
    rows = states.reshape(-1, 22)  # (32, 22) one row per hand
    assert torch.equal(default.tokenize(states)[0].reshape(-1, 8, 8), tok.encode(rows, INSPIRE))
    assert torch.equal(nearest.tokenize(states)[0].reshape(-1, 8, 8), tok.encode(rows, INSPIRE, encoding=NEAREST_CODES))
    active = nearest.active_masks.reshape(-1).repeat(16, 1)  # (16, 44)
    errors = []
    for step in (nearest, default):
        _, view = step.tokenize(states)
        errors.append(float((view - states).abs()[active].mean()))
    assert errors[1] < 0.6 * errors[0]
    for step in (default, nearest):
        again = UniDexTokStateTokenizerStep(**json.loads(json.dumps(step.get_config())))
        again.load_state_dict(step.state_dict())  # as the pipeline reloads a step
        assert again.encoding == step.encoding
        assert torch.equal(again.tokenize(states)[0], step.tokenize(states)[0])
    with pytest.raises(ValueError, match="encoding.rounds must be >= 0"):
        UniDexTokStateTokenizerStep(hand_layout=[INSPIRE], encoding={"rounds": -1})


def test_a_step_saved_with_the_legacy_search_rounds_encodes_as_it_did():
    """A step saved before EncodingConfig: its config has `search_rounds` and its tokenizer_config the flat legacy
    keys. It loads with the tokenizer's own encoding at that many rounds (what it encoded with), and saves the new
    form. (Steps saved then held `unidextok/universal-small`: named by its id, whichever shipped id is the default.)"""
    from lerobot_unidextok.pretrained import UNIVERSAL_SMALL

    states = torch.from_numpy(inspire_states(8, seed=4))
    step = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE], pretrained=UNIVERSAL_SMALL)
    saved = json.loads(json.dumps(step.get_config()))
    tok_cfg = dict(saved["tokenizer_config"])
    legacy_keys = {"rounds": "search_rounds", "method": "search_method", "sweeps": "search_sweeps",
                   "changes": "search_changes", "tolerance_deg": "search_tolerance_deg"}  # fmt: skip
    tok_cfg.update({legacy_keys[k]: v for k, v in tok_cfg.pop("encoding").items()})
    for rounds in (0, 1):
        legacy = {**{k: v for k, v in saved.items() if k != "encoding"}, "tokenizer_config": tok_cfg,
                  "search_rounds": rounds}  # fmt: skip
        old = UniDexTokStateTokenizerStep(**legacy)
        old.load_state_dict(step.state_dict())
        own = step.tokenizer.config.encoding
        assert old.tokenizer.config.encoding == own
        assert old.encoding == EncodingConfig(rounds=rounds, method=own.method, changes=own.changes,
                                              tolerance_deg=own.tolerance_deg, sweeps=own.sweeps)  # fmt: skip
        assert torch.equal(old.tokenize(states)[0].reshape(-1, 8, 8),
                           step.tokenizer.encode(states.reshape(-1, 22), INSPIRE, encoding=old.encoding))
        assert old.get_config()["encoding"]["rounds"] == rounds and "search_rounds" not in old.get_config()
    with pytest.raises(ValueError, match="give `encoding` only"):
        UniDexTokStateTokenizerStep(hand_layout=[INSPIRE], search_rounds=1, encoding=NEAREST_CODES)


def test_a_step_that_does_not_encode_gives_no_codes_a_zero_view_and_still_checks(tok_dir, states, monkeypatch):
    """`encode=False` (a `<type>_udt` policy with `udt_hand_input=state`): the widths of the encoding step, codes
    -1, the view zero, the tokenizer never run; the state is still checked, and the setting survives a reload."""
    encoding = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir))
    want = encoding.observation({OBS_STATE: states[:4]})
    quiet = UniDexTokStateTokenizerStep(hand_layout=PAIR, pretrained=str(tok_dir), encode=False)
    for method in ("encode", "encode_decode"):
        monkeypatch.setattr(UniDexTok, method, lambda *a, **k: pytest.fail("the tokenizer ran"))
    out = quiet.observation({OBS_STATE: states[:4]})
    assert out[OBS_HAND_TOKENS].shape == want[OBS_HAND_TOKENS].shape and (out[OBS_HAND_TOKENS] == -1).all()
    assert out[OBS_HAND_TOKEN_FEATURES].shape == want[OBS_HAND_TOKEN_FEATURES].shape
    assert not out[OBS_HAND_TOKEN_FEATURES].any() and want[OBS_HAND_TOKEN_FEATURES].any()
    with pytest.raises(ValueError, match="degrees"):
        quiet.observation({OBS_STATE: torch.rad2deg(states[:4])})
    assert quiet.get_config()["encode"] is False
    assert UniDexTokStateTokenizerStep(**{**quiet.get_config(), "pretrained": str(tok_dir)}).encode is False
