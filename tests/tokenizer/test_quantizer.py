"""Invariants of the factorised cosine VQ."""

import pytest
import torch

from lerobot_unidextok.tokenizer import FactorizedCosineVQ, UniDexTokConfig


@pytest.fixture
def vq() -> FactorizedCosineVQ:
    torch.manual_seed(0)
    return FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny"))


def test_indices_in_range_and_shape(vq):
    z = torch.randn(16, 4, 64)
    quantized, indices, loss = vq(z)
    assert quantized.shape == (16, 4, 64)
    assert indices.shape == (16, 4, 8) and indices.dtype == torch.int64
    assert int(indices.min()) >= 0 and int(indices.max()) < 32
    assert loss.ndim == 0 and loss.item() > 0


def test_eval_decode_of_indices_equals_quantized_forward(vq):
    vq.eval()
    z = torch.randn(32, 4, 64)
    with torch.no_grad():
        quantized, indices, _ = vq(z)
        again = vq.get_output_from_indices(indices)
    torch.testing.assert_close(again, quantized, rtol=0, atol=0)


def test_codes_are_nearest_by_cosine(vq):
    z = torch.randn(8, 4, 64)
    _, indices, _ = vq(z)
    u = torch.nn.functional.normalize(vq.project_in(z).view(8, 4, 8, 32), dim=-1)
    cb = torch.nn.functional.normalize(vq.codebooks, dim=-1)
    brute = torch.stack([(u[:, :, k, None, :] * cb[k]).sum(-1).argmax(-1) for k in range(8)], dim=-1)
    assert torch.equal(brute, indices)


def test_straight_through_gradients_reach_the_input_and_codebook(vq):
    z = torch.randn(8, 4, 64, requires_grad=True)
    quantized, _, loss = vq(z)
    (quantized.square().sum() + loss).backward()
    assert z.grad is not None and z.grad.abs().sum() > 0
    assert vq.codebooks.grad is not None and vq.codebooks.grad.abs().sum() > 0


def test_commitment_loss_weights_follow_config():
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny"))
    z = torch.randn(8, 4, 64)
    _, _, loss, parts = vq(z, return_loss_breakdown=True)
    torch.testing.assert_close(loss, 0.25 * parts.commitment + 1.0 * parts.codebook)
    # commitment and codebook terms have the same value, different gradients (see the gradient test)
    torch.testing.assert_close(parts.commitment, parts.codebook)


def _loss_grads(beta: float, codebook_weight: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Gradients of the VQ loss alone w.r.t. (input z, projection weight, codebooks) for one fixed model/input."""
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(
        UniDexTokConfig.from_preset("tiny", commitment_weight=beta, codebook_weight=codebook_weight)
    )
    z = torch.randn(8, 4, 64, generator=torch.Generator().manual_seed(1), requires_grad=True)
    _, _, loss = vq(z)
    grad_z, grad_proj, grad_cb = torch.autograd.grad(loss, [z, vq.project_in.weight, vq.codebooks])
    return grad_z, grad_proj, grad_cb


def test_vq_loss_gradients_encoder_gets_beta_codebook_gets_one():
    """The commitment term (weight beta) moves only the encoder side, the codebook term (weight 1) only the codes.

    Catches: beta applied to the codebook term instead of the commitment term, the stop-gradient on the
    wrong side (commitment = mse(sg[u], q) or codebook = mse(sg[q], u)), or either term dropped."""
    ref_z, ref_proj, ref_cb = _loss_grads(1.0, 1.0)
    assert ref_z.abs().sum() > 0 and ref_proj.abs().sum() > 0 and ref_cb.abs().sum() > 0
    z, proj, cb = _loss_grads(0.25, 1.0)  # the paper's weights
    torch.testing.assert_close(z, 0.25 * ref_z, rtol=1e-5, atol=1e-9)  # encoder side scales with beta
    torch.testing.assert_close(proj, 0.25 * ref_proj, rtol=1e-5, atol=1e-9)
    torch.testing.assert_close(cb, ref_cb, rtol=0, atol=0)  # the codebook does not see beta
    z, proj, cb = _loss_grads(1.0, 3.0)
    torch.testing.assert_close(z, ref_z, rtol=0, atol=0)  # the encoder does not see the codebook weight
    torch.testing.assert_close(cb, 3.0 * ref_cb, rtol=1e-5, atol=1e-9)
    z, _, cb = _loss_grads(0.0, 1.0)
    assert torch.count_nonzero(z) == 0 and torch.equal(cb, ref_cb)  # beta = 0: no gradient to the encoder
    z, _, cb = _loss_grads(1.0, 0.0)
    assert torch.count_nonzero(cb) == 0 and torch.equal(z, ref_z)  # no codebook term: codes get no gradient


def test_entropy_regulariser_changes_loss_when_enabled():
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny", entropy_weight=0.1))
    _, _, loss, parts = vq(torch.randn(8, 4, 64), return_loss_breakdown=True)
    assert parts.entropy.item() != 0
    torch.testing.assert_close(loss, 0.25 * parts.commitment + parts.codebook + 0.1 * parts.entropy)


def test_dead_codes_are_reseeded_from_batch_features(vq):
    vq.train()
    z = torch.randn(64, 4, 64)
    vq(z)
    vq.usage_ema.zero_()
    vq.usage_ema[:, 0] = 1.0  # every code but the first looks dead
    before = vq.codebooks.detach().clone()
    n = vq.reseed_dead_codes()
    assert n == 8 * 31
    assert torch.equal(vq.codebooks[:, 0], before[:, 0])
    # re-seeded codes point along batch features
    feats = vq.last_features  # (M, K, d)
    cos = torch.einsum("md,sd->ms", feats[:, 3], torch.nn.functional.normalize(vq.codebooks[3, 1:], dim=-1))
    assert torch.allclose(cos.max(0).values, torch.ones(31), atol=1e-5)


def test_usage_statistics(vq):
    vq(torch.randn(256, 4, 64))
    usage = vq.codebook_usage()
    assert 0 < usage["usage"] <= 1
    assert 1 <= usage["perplexity"] <= 32


def test_bad_indices_raise(vq):
    with pytest.raises(ValueError, match="num_groups"):
        vq.check_indices(torch.zeros(2, 4, 7, dtype=torch.long))
    with pytest.raises(ValueError, match=r"\[0, 31\]"):
        vq.check_indices(torch.full((2, 4, 8), 32))
