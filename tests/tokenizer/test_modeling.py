"""UniDexTok model: shapes per preset, hand conditioning, errors, Hub-format save/load."""

import json
import math

import pytest
import torch

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.tokenizer import FORMAT_VERSION, PRESETS, UniDexTok, UniDexTokConfig


def _states(b: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return (torch.rand(b, UDHM_DIM, generator=g) - 0.3) * 1.5


def _randomize_conditioning(model: UniDexTok) -> None:
    """Leave adaLN-Zero: give the conditioning layers non-zero weights, as training would."""
    g = torch.Generator().manual_seed(1)
    with torch.no_grad():
        for module in [*model.encoder, *model.decoder, model.enc_norm, model.dec_norm]:
            lin = module.adaLN_modulation[-1]
            lin.weight.copy_(torch.randn(lin.weight.shape, generator=g) * 0.5)
        model.hand_embed.weight.copy_(torch.randn(model.hand_embed.weight.shape, generator=g))


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_shapes_for_every_preset(preset):
    torch.manual_seed(0)
    cfg = UniDexTokConfig.from_preset(preset)
    model = UniDexTok(cfg).eval()
    x = _states(3)
    out = model(x, "human")
    assert out.states_rad.shape == (3, UDHM_DIM)
    assert out.indices.shape == (3, cfg.num_tokens, cfg.num_groups * cfg.num_stages)
    codes = model.encode(x, ["human", "allegro", "leap"])
    assert codes.dtype == torch.int64 and codes.shape == (3, cfg.num_tokens, cfg.num_groups * cfg.num_stages)
    assert int(codes.max()) < cfg.codebook_size and int(codes.min()) >= 0
    assert model.decode(codes, "human").shape == (3, UDHM_DIM)


def test_decode_of_encode_equals_forward_in_eval():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    _randomize_conditioning(model)
    model.eval()
    x = _states(16)
    hands = ["human", "inspire_rh56"] * 8
    with torch.no_grad():
        out = model(x, hands)
    codes = model.encode(x, hands)
    assert torch.equal(codes, out.indices)
    torch.testing.assert_close(model.decode(codes, hands), out.states_rad, rtol=0, atol=0)


def test_hand_argument_forms_agree():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    _randomize_conditioning(model)
    x = _states(4)
    ids = torch.tensor([model.config.hand_names.index("leap")] * 4)
    a = model.encode(x, "leap")
    assert torch.equal(a, model.encode(x, ["leap"] * 4))
    assert torch.equal(a, model.encode(x, ids))


def test_hand_conditioning_changes_outputs():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    _randomize_conditioning(model)
    model.eval()
    x = _states(32)
    codes_h = model.encode(x, "human")
    codes_r = model.encode(x, "inspire_rh56")
    assert not torch.equal(codes_h, codes_r)
    dec_h = model.decode(codes_h, "human")
    dec_r = model.decode(codes_h, "inspire_rh56")
    assert (dec_h - dec_r).abs().max() > 1e-3


def test_unknown_hand_error_and_opt_in():
    model = UniDexTok(UniDexTokConfig.from_preset("tiny")).eval()
    x = _states(2)
    with pytest.raises(ValueError, match=r"unknown hand 'mystery_hand'.*human.*allow_unknown=True"):
        model.encode(x, "mystery_hand")
    codes = model.encode(x, "mystery_hand", allow_unknown=True)
    assert codes.shape == (2, 4, 8)
    with pytest.raises(ValueError, match="hand ids"):
        model.encode(x, torch.tensor([99, 0]))
    with pytest.raises(ValueError, match="3 hands for a batch of 2"):
        model.encode(x, ["human"] * 3)


def test_bad_states_raise():
    model = UniDexTok(UniDexTokConfig.from_preset("tiny")).eval()
    with pytest.raises(ValueError, match=r"\(B, 22\)"):
        model.encode(torch.zeros(2, 21), "human")
    with pytest.raises(ValueError, match=r"\(B, 22\)"):
        model(torch.zeros(44), "human")
    bad = _states(2)
    bad[1, 3] = math.nan
    with pytest.raises(ValueError, match="NaN"):
        model.encode(bad, "human")
    with pytest.raises(ValueError, match=r"codes must have shape"):
        model.decode(torch.zeros(2, 8, 8, dtype=torch.long), "human")
    with pytest.raises(ValueError, match=r"\[0, 31\]"):
        model.decode(torch.full((2, 4, 8), 40), "human")


def test_bad_config_raises():
    with pytest.raises(ValueError, match="divisible by num_heads"):
        UniDexTokConfig(hidden_dim=10, num_heads=4)
    with pytest.raises(ValueError, match="unknown UniDexTok preset 'huge'"):
        UniDexTokConfig.from_preset("huge")


def test_masked_loss_ignores_padded_slots():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    x = _states(4)
    mask = torch.zeros(4, UDHM_DIM, dtype=torch.bool)
    mask[:, [0, 1, 6, 10, 14, 19]] = True
    out = model(x, "inspire_rh56", mask=mask)
    expected = ((out.states_rad / math.pi - x / math.pi) ** 2)[mask].mean()
    torch.testing.assert_close(out.recon_loss, expected)
    # padded slots get no gradient through the reconstruction loss
    x_bad = x.clone()
    x_bad[~mask] = 3.0
    out_bad = model(x_bad, "inspire_rh56", mask=mask)
    assert out_bad.recon_loss.item() != out.recon_loss.item()  # encoder still sees them
    with pytest.raises(ValueError, match="mask must have"):
        model(x, "human", mask=torch.ones(4, 21, dtype=torch.bool))


def test_save_load_round_trip_is_bit_identical(tmp_path):
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("small", hand_names=["human", "my_hand"]))
    _randomize_conditioning(model)
    model.eval()
    model.save_pretrained(tmp_path)
    assert {"config.json", "model.safetensors"} <= {p.name for p in tmp_path.iterdir()}
    assert not list(tmp_path.glob("*.bin")) and not list(tmp_path.glob("*.pt"))
    loaded = UniDexTok.from_pretrained(tmp_path)
    assert not loaded.training
    assert loaded.config == model.config
    x = _states(8)
    assert torch.equal(loaded.encode(x, "my_hand"), model.encode(x, "my_hand"))
    codes = model.encode(x, "human")
    torch.testing.assert_close(loaded.decode(codes, "human"), model.decode(codes, "human"), rtol=0, atol=0)


def test_load_from_local_hf_cache(tmp_path, monkeypatch):
    """A repo id resolves offline through the HF cache (snapshot layout written by hand here)."""
    from huggingface_hub import constants as hf_constants

    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny")).eval()
    cache = tmp_path / "hub"
    snap = cache / "models--someone--unidextok-tiny" / "snapshots" / ("a" * 40)
    model.save_pretrained(snap)
    (cache / "models--someone--unidextok-tiny" / "refs").mkdir(parents=True)
    (cache / "models--someone--unidextok-tiny" / "refs" / "main").write_text("a" * 40)
    monkeypatch.setattr(hf_constants, "HF_HUB_OFFLINE", True)
    loaded = UniDexTok.from_pretrained("someone/unidextok-tiny", cache_dir=cache, local_files_only=True)
    x = _states(4)
    assert torch.equal(loaded.encode(x, "human"), model.encode(x, "human"))


def test_format_version_mismatch_is_a_clear_error(tmp_path):
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    model.save_pretrained(tmp_path)
    cfg_path = tmp_path / "config.json"
    raw = json.loads(cfg_path.read_text())
    raw["format_version"] = FORMAT_VERSION + 1
    cfg_path.write_text(json.dumps(raw))
    with pytest.raises(ValueError, match="format_version"):
        UniDexTok.from_pretrained(tmp_path)
    del raw["format_version"]
    cfg_path.write_text(json.dumps(raw))
    with pytest.raises(ValueError, match="format_version=None"):
        UniDexTok.from_pretrained(tmp_path)


def test_missing_weights_is_a_clear_error(tmp_path):
    UniDexTok(UniDexTokConfig.from_preset("tiny")).save_pretrained(tmp_path)
    (tmp_path / "model.safetensors").unlink()
    with pytest.raises(FileNotFoundError, match="model.safetensors"):
        UniDexTok.from_pretrained(tmp_path)


def test_range_normalisation_maps_each_joint_range_onto_unit_interval(tmp_path):
    """input_norm="range": the encoder sees (x - center) / half-range per joint; joints without a range keep
    pi; the decoder output comes back in radians; the ranges travel in config.json."""
    ranges = [[0.0, 0.0]] * UDHM_DIM
    ranges[6] = [0.0, 1.7]  # index MCP flexion of an Inspire hand
    ranges[0] = [-0.1, 0.5]
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", input_norm="range", joint_range_rad=ranges)).eval()
    assert model.norm_center[6].item() == pytest.approx(0.85) and model.norm_scale[6].item() == pytest.approx(0.85)
    assert model.norm_center[0].item() == pytest.approx(0.2) and model.norm_scale[0].item() == pytest.approx(0.3)
    assert model.norm_scale[3].item() == pytest.approx(math.pi) and model.norm_center[3].item() == 0.0
    seen = {}

    def keep_input(module, inputs, output) -> None:
        seen["x"] = inputs[0]

    model.input_proj.register_forward_hook(keep_input)
    x = torch.zeros(1, UDHM_DIM)
    x[0, 6], x[0, 0], x[0, 3] = 1.7, -0.1, math.pi / 2
    model.encode(x, "human")
    assert seen["x"][0, 6].item() == pytest.approx(1.0) and seen["x"][0, 0].item() == pytest.approx(-1.0)
    assert seen["x"][0, 3].item() == pytest.approx(0.5)
    model.save_pretrained(tmp_path)
    loaded = UniDexTok.from_pretrained(tmp_path)
    assert loaded.config.joint_range_rad == model.config.joint_range_rad
    codes = model.encode(x, "human")
    torch.testing.assert_close(loaded.decode(codes, "human"), model.decode(codes, "human"), rtol=0, atol=0)
    with pytest.raises(ValueError, match="joint_range_rad must be 22"):
        UniDexTokConfig(input_norm="range", joint_range_rad=[[0.0, 1.0]])


def test_loss_terms_follow_their_weights():
    torch.manual_seed(0)
    x = _states(6)
    base = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    out = base(x, "human")
    d = out.states_rad / math.pi - x / math.pi
    torch.testing.assert_close(out.recon_loss, (d**2).mean())
    l1 = UniDexTok(UniDexTokConfig.from_preset("tiny", mse_weight=0.0, l1_weight=2.0))
    l1.load_state_dict(base.state_dict())
    torch.testing.assert_close(l1(x, "human").recon_loss, 2.0 * d.abs().mean())
    with pytest.raises(ValueError, match=">= 0"):
        UniDexTokConfig(l1_weight=-1.0)


def test_fourier_features_widen_the_input_projection():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", fourier_octaves=3))
    assert model.input_proj.in_features == UDHM_DIM * 7
    assert model(_states(2), "human").states_rad.shape == (2, UDHM_DIM)
