"""Invariants of the factorised cosine VQ."""

import math

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


# ---------------------------------------------------------------------------------------------
# worked examples on a toy quantiser: 1 group of 2 codes in 2-D, whose numbers follow by hand
# ---------------------------------------------------------------------------------------------
def _toy_vq(**kw) -> FactorizedCosineVQ:
    """Codes e0 = (1, 0) and e1 = (0, 1) with norms 2 and 4; project_in keeps the first two input dims."""
    cfg = UniDexTokConfig.from_preset("tiny", codebook_dim=2, num_groups=1, codebook_size=2, **kw)
    vq = FactorizedCosineVQ(cfg)
    with torch.no_grad():
        vq.project_in.weight.zero_()
        vq.project_in.weight[0, 0] = vq.project_in.weight[1, 1] = 1.0
        vq.project_in.bias.zero_()
        vq.codebooks.copy_(torch.tensor([[[2.0, 0.0], [0.0, 4.0]]]))
    return vq


def _rows(*codes: int) -> torch.Tensor:
    """(1, len(codes), 64) tokens pointing exactly at the given codes (0 -> e0, 1 -> e1)."""
    z = torch.zeros(1, len(codes), 64)
    for i, c in enumerate(codes):
        z[0, i, c] = 1.0
    return z


def _h(*p: float) -> float:
    return -sum(x * math.log(x) for x in p if x > 0)


def test_entropy_term_worked_example():
    """entropy = mean per-token entropy of softmax(cos / T) - entropy of the batch-average distribution.

    Tokens (e0, e1 | e0, e0) in a batch of 2 x 2, T = 0.5: each token's distribution is (a, 1 - a) or
    (1 - a, a) with a = e^2 / (e^2 + 1); the batch average is (3a + (1 - a), 3(1 - a) + a) / 4. Catches a
    temperature that multiplies, a flipped sign, the average taken per token instead of over the batch."""
    vq = _toy_vq(entropy_weight=1.0, entropy_temperature=0.5)
    z = torch.cat([_rows(0, 1), _rows(0, 0)])  # (2, 2, 64)
    _, indices, loss, parts = vq(z, return_loss_breakdown=True)
    assert indices.flatten().tolist() == [0, 1, 0, 0]
    a = math.exp(2) / (math.exp(2) + 1)
    avg = ((3 * a + (1 - a)) / 4, (3 * (1 - a) + a) / 4)
    assert parts.entropy.item() == pytest.approx(_h(a, 1 - a) - _h(*avg), rel=1e-5)
    assert parts.commitment.item() == pytest.approx(0.0, abs=1e-12)  # inputs sit on their codes
    assert loss.item() == pytest.approx(parts.entropy.item(), rel=1e-5)


def test_usage_and_perplexity_worked_example():
    """3 tokens on code 0 and 1 on code 1: usage 1, perplexity exp(H(3/4, 1/4)); one token alone: usage 1/2,
    perplexity 1. Catches a count normaliser floor of 2, a wrong log clamp, codes counted along the wrong axis."""
    vq = _toy_vq().eval()
    with torch.no_grad():
        vq(torch.cat([_rows(0, 1), _rows(0, 0)]))
    assert vq.codebook_usage() == pytest.approx({"usage": 1.0, "perplexity": math.exp(_h(0.75, 0.25))})
    with torch.no_grad():
        vq(_rows(1))
    assert vq.codebook_usage() == pytest.approx({"usage": 0.5, "perplexity": 1.0})


def test_usage_ema_updates_in_training_only():
    """Fresh EMA = 1/S per code; a training batch moves it by (1 - decay) towards the batch's code shares;
    eval batches leave it (and the stored features) alone."""
    vq = _toy_vq(usage_decay=0.9)
    torch.testing.assert_close(vq.usage_ema, torch.full((1, 2), 0.5))
    vq.eval()
    vq(torch.cat([_rows(0, 1), _rows(0, 0)]))
    torch.testing.assert_close(vq.usage_ema, torch.full((1, 2), 0.5))
    assert vq.last_features.numel() == 0
    vq.train()
    vq(torch.cat([_rows(0, 1), _rows(0, 0)]))
    torch.testing.assert_close(vq.usage_ema, torch.tensor([[0.9 * 0.5 + 0.1 * 0.75, 0.9 * 0.5 + 0.1 * 0.25]]))
    assert vq.last_features.shape == (4, 1, 2)


def test_reseed_threshold_boundary_and_scale():
    """A code is dead when its usage EMA is strictly below threshold / S; exactly at it, it lives. A re-seeded
    code is a batch feature scaled to the mean code norm (here (2 + 4) / 2 = 3) and its EMA restarts at 1/S."""
    vq = _toy_vq(dead_code_threshold=0.5)
    assert vq.reseed_dead_codes() == 0  # no training batch seen yet: nothing to seed from
    vq.train()
    vq(_rows(0, 0, 0))  # features all e0
    with torch.no_grad():
        vq.usage_ema.copy_(torch.tensor([[0.25, 0.2499]]))  # threshold / S = 0.25
    before = vq.codebooks.detach().clone()
    assert vq.reseed_dead_codes() == 1
    torch.testing.assert_close(vq.codebooks[0, 0], before[0, 0], rtol=0, atol=0)  # at the threshold: kept
    torch.testing.assert_close(vq.codebooks[0, 1], torch.tensor([3.0, 0.0]))  # e0 feature x mean norm 3
    torch.testing.assert_close(vq.usage_ema, torch.tensor([[0.25, 0.5]]))
    assert vq.reseed_dead_codes() == 0  # nobody dead any more
    off = _toy_vq(dead_code_threshold=0.0).train()
    off(_rows(0, 0))
    with torch.no_grad():
        off.usage_ema.zero_()
    assert off.reseed_dead_codes() == 0


def test_training_forward_value_is_the_code():
    """With gradients on, the straight-through output still equals decoding the chosen codes."""
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny")).train()
    z = torch.randn(4, 4, 64, requires_grad=True)
    quantized, indices, _ = vq(z)
    torch.testing.assert_close(quantized, vq.get_output_from_indices(indices), rtol=1e-5, atol=1e-6)


def test_negative_indices_raise(vq):
    codes = torch.zeros(2, 4, 8, dtype=torch.long)
    codes[1, 2, 3] = -1
    with pytest.raises(ValueError, match=r"\[0, 31\]"):
        vq.check_indices(codes)
    vq.check_indices(torch.full((2, 4, 8), 31))  # the largest valid code passes
    with pytest.raises(ValueError, match="integer"):
        vq.check_indices(torch.zeros(2, 4, 8))


def test_default_straight_through_passes_the_gradient_unchanged():
    """Straight-through (the default): d quantized / d z is that of the unquantised path project_out(u), as if
    the code were u. Catches the estimator switch read the wrong way round (`== "rotation"` -> `!=`), which
    makes every default model train with the rotation trick."""
    torch.manual_seed(0)
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny"))
    z = torch.randn(8, 4, 64, requires_grad=True)
    quantized, _, _ = vq(z)
    quantized.pow(3).sum().backward()  # a non-linear head, so the upstream gradient depends on the value
    z2 = z.detach().clone().requires_grad_(True)
    u = torch.nn.functional.normalize(vq.project_in(z2).view(8, 4, vq.num_groups, vq.group_dim), dim=-1)
    upstream = 3 * quantized.detach().pow(2)  # d/dq of q^3 at the quantised value
    (vq.project_out(u.flatten(-2)) * upstream).sum().backward()
    torch.testing.assert_close(z.grad, z2.grad, rtol=1e-5, atol=1e-6)


def test_training_statistics_are_not_in_the_checkpoint():
    """usage_ema, last_features and the EMA codebook's running sums are training statistics, not weights: the
    state dict holds the codebooks and projections only. Catches one of them made persistent (a checkpoint that
    carries, and on load overwrites, another run's statistics; its size then depends on the last batch)."""
    vq = FactorizedCosineVQ(UniDexTokConfig.from_preset("tiny", codebook_update="ema")).train()
    vq(torch.randn(4, 4, 64))
    assert vq.ema_sum.numel() and vq.ema_count.numel() and vq.last_features.numel()
    assert sorted(vq.state_dict()) == [
        "codebooks", "project_in.bias", "project_in.weight", "project_out.bias", "project_out.weight",
    ]  # fmt: skip


def test_ema_update_worked_example_with_more_codes_than_dims():
    """EMA codebook update, by hand: 1 group, 3 codes in 2-D (e0, e1, -e0), decay 0.5, one token
    u = (0.6, 0.8) (nearest code e1). Counts start at 1 and sums at the unit codes, so
    count = 0.5 * 1 + 0.5 * (0, 1, 0) = (0.5, 1, 0.5); sum_1 = 0.5 * e1 + 0.5 * u = (0.3, 0.9); codes =
    sum / count = (1, 0), (0.3, 0.9), (-1, 0). Catches dividing by the counts on the wrong axis (only
    visible when codes != dims: the tiny preset has 32 of both)."""
    cfg = UniDexTokConfig.from_preset("tiny", codebook_dim=2, num_groups=1, codebook_size=3, codebook_update="ema",
                                      ema_decay=0.5)  # fmt: skip
    vq = FactorizedCosineVQ(cfg).train()
    with torch.no_grad():
        vq.project_in.weight.zero_()
        vq.project_in.weight[0, 0] = vq.project_in.weight[1, 1] = 1.0
        vq.project_in.bias.zero_()
        vq.codebooks.copy_(torch.tensor([[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]]))
    z = torch.zeros(1, 1, 64)
    z[0, 0, :2] = torch.tensor([0.6, 0.8])
    _, indices, _ = vq(z)
    assert indices.flatten().tolist() == [1]
    torch.testing.assert_close(vq.codebooks, torch.tensor([[[1.0, 0.0], [0.3, 0.9], [-1.0, 0.0]]]))


def test_reseed_before_any_batch_and_from_a_single_row():
    """Re-seeding needs a training batch: with every code below the threshold but no batch seen yet it does
    nothing (catches the "no features" guard testing `numel() == 1`, which then draws from an empty batch).
    From a one-row batch every dead code becomes that row (catches drawing rows from 1, not 0)."""
    vq = _toy_vq(dead_code_threshold=1.5)  # uniform usage 1/2 < 1.5 / 2: every code is dead
    assert vq.reseed_dead_codes() == 0
    vq.train()
    vq(_rows(1))  # one token, feature e1
    with torch.no_grad():
        vq.usage_ema.zero_()
    assert vq.reseed_dead_codes() == 2
    torch.testing.assert_close(vq.codebooks, torch.tensor([[[0.0, 3.0], [0.0, 3.0]]]))  # e1 x mean norm 3


def test_l2norm_gives_unit_vectors_whatever_their_length():
    """Cosine VQ compares directions: latents and codes of any length (here 1e-3 to 1e3) come out of unit
    length, and a zero vector stays finite. Catches an eps as large as the vectors (`1e-6` -> `1.000001`),
    which leaves every vector shorter than 1 unnormalised."""
    from lerobot_unidextok.tokenizer.quantizer import l2norm

    x = torch.randn(64, 8) * torch.logspace(-3, 3, 64)[:, None]
    torch.testing.assert_close(l2norm(x).norm(dim=-1), torch.ones(64))
    torch.testing.assert_close(l2norm(x), x / x.norm(dim=-1, keepdim=True))
    assert torch.isfinite(l2norm(torch.zeros(2, 8))).all()


def test_nearest_indices_are_the_forward_indices_without_side_effects(vq):
    """`UniDexTok.encode` uses `nearest_indices`: the same codes as the forward pass, no statistics moved."""
    vq.train()
    z = torch.randn(16, 4, 64)
    usage = vq.usage_ema.clone()
    nearest = vq.nearest_indices(z)
    assert torch.equal(vq.usage_ema, usage)
    _, indices, _ = vq(z)
    assert torch.equal(nearest, indices)
