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
    # commitment and codebook terms have the same value, different gradients
    torch.testing.assert_close(parts.commitment, parts.codebook)


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


def test_rotation_trick_forward_is_the_code_and_gradient_is_rotated():
    """The rotation-trick option: same forward value as straight-through, a different gradient to the input."""
    cfg = UniDexTokConfig.from_preset("tiny")
    grads = {}
    for estimator in ("straight_through", "rotation"):
        torch.manual_seed(0)
        vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny", gradient_estimator=estimator))
        z = torch.randn(8, 4, 64, requires_grad=True)
        quantized, indices, _ = vq(z)
        with torch.no_grad():
            exact = vq.get_output_from_indices(indices)
        torch.testing.assert_close(quantized, exact, rtol=0, atol=1e-5)
        quantized.pow(3).sum().backward()
        grads[estimator] = z.grad.clone()
    assert not torch.allclose(grads["rotation"], grads["straight_through"])
    assert cfg.gradient_estimator == "straight_through"  # the paper's estimator stays the default


def test_ema_codebook_moves_toward_assigned_vectors_without_gradient():
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny", codebook_update="ema", ema_decay=0.5))
    assert not vq.codebooks.requires_grad
    z = torch.randn(64, 4, 64)
    before = torch.nn.functional.normalize(vq.codebooks.detach().clone(), dim=-1)
    _, indices, loss, parts = vq(z, return_loss_breakdown=True)
    assert parts.codebook.item() == 0.0  # no codebook loss term
    u = torch.nn.functional.normalize(vq.project_in(z).view(64, 4, 8, 32), dim=-1).detach()
    # a used code: its new direction is closer to the mean of its assigned vectors than before
    k, s = 0, int(indices[..., 0].flatten().mode().values)
    target = torch.nn.functional.normalize(u[..., 0, :][indices[..., 0] == s].mean(0), dim=-1)
    after = torch.nn.functional.normalize(vq.codebooks[k, s], dim=-1)
    assert (after @ target) > (before[k, s] @ target)
    vq.eval()  # eval forward leaves the codebook alone
    frozen = vq.codebooks.clone()
    vq(torch.randn(8, 4, 64))
    assert torch.equal(frozen, vq.codebooks)
