"""FSQ / residual-VQ baselines: matched 320-bit budget, code ranges, training lowers the loss."""

from __future__ import annotations

import numpy as np
import pytest
import torch

pytest.importorskip("vector_quantize_pytorch")

from lerobot_unidextok.baselines import QuantizedAEConfig, QuantizedAETokenizer, reconstruct  # noqa: E402


@pytest.fixture(scope="module", params=["fsq", "rvq"])
def fitted(request, train_states, masks):
    torch.manual_seed(0)  # the weights and batches draw from torch's global generator: whatever ran before
    tok = QuantizedAETokenizer(QuantizedAEConfig.from_preset("tiny", quantizer=request.param))
    history = tok.fit(train_states, masks)
    return tok, history


def test_matched_budget_and_codes(fitted, train_states, masks) -> None:
    tok, _ = fitted
    rate = tok.rate("human")
    assert (rate.tokens_per_state, rate.codes_per_token, rate.vocab_per_code) == (8, 8, 32)
    assert rate.bits_per_state == 320  # UniDexTok's 8 tokens x 8 groups x 5 bits
    for hand, states in train_states.items():
        codes = tok.encode(states[:40], hand)
        assert codes.dtype == torch.int64 and codes.shape == (40, 8, 8)
        assert codes.min() >= 0 and codes.max() < 32
        recon = tok.decode(codes, hand)
        assert recon.shape == (40, 22) and (recon[:, ~masks[hand]] == 0).all()


def test_training_lowers_loss_and_error(fitted, train_states) -> None:
    tok, history = fitted
    losses = np.asarray(history["loss"])
    assert losses[-5:].mean() < 0.7 * losses[:5].mean()
    x = train_states["human"]
    err = (reconstruct(tok, x, "human") - x).abs().mean()
    assert err < 0.75 * (x - x.mean(0)).abs().mean()  # clearly better than predicting the mean pose


def test_decode_of_codes_equals_quantized_forward(fitted, train_states) -> None:
    """In eval mode decode(encode(x)) reproduces the straight-through forward pass exactly."""
    tok, _ = fitted
    x = train_states["inspire_rh56"][:30]
    with torch.no_grad():
        z_q = tok.quantizer(tok._latent(x / torch.pi * tok.masks["inspire_rh56"], "inspire_rh56"))[0]
        forward = tok._reconstruct(z_q, "inspire_rh56") * torch.pi * tok.masks["inspire_rh56"]
    torch.testing.assert_close(reconstruct(tok, x, "inspire_rh56"), forward, rtol=1e-5, atol=1e-5)


def test_bad_config_and_codes(fitted) -> None:
    tok, _ = fitted
    with pytest.raises(ValueError, match="quantizer must be"):
        QuantizedAEConfig(quantizer="lfq")
    with pytest.raises(ValueError, match="bits_per_code"):
        QuantizedAEConfig(quantizer="fsq", bits_per_code=7)
    with pytest.raises(ValueError, match=r"\[0, 32\)"):
        tok.decode(torch.full((1, 8, 8), 40), "human")
