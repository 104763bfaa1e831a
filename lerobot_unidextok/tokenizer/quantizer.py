"""Factorised cosine vector quantiser: C -> codebook_dim, K groups, one small codebook per group.

Codes learn from the codebook loss (paper) or, with `codebook_update="ema"`, as the running mean of the
unit-norm encoder vectors assigned to them (VQ-VAE-2 style; the codebook is then not a gradient target).

Dead codes: the quantiser keeps an EMA of how often each code is picked. `reseed_dead_codes()`
(called by the training loop after an optimiser step) replaces codes whose usage EMA is below
`dead_code_threshold / codebook_size` with random encoder features of the last training batch, so
every code keeps receiving gradient. Nothing changes in eval mode.
"""

from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import nn

from lerobot_unidextok.tokenizer.configuration_unidextok import UniDexTokConfig


# ---------------------------------------------------------------------------------------------
# helper functions
# ---------------------------------------------------------------------------------------------
def l2norm(x: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    return F.normalize(x, dim=-1, eps=eps)


class LossBreakdown(NamedTuple):
    commitment: torch.Tensor
    codebook: torch.Tensor
    entropy: torch.Tensor


# ---------------------------------------------------------------------------------------------
# main class
# ---------------------------------------------------------------------------------------------
class FactorizedCosineVQ(nn.Module):
    """Quantise (B, N, C) tokens into (B, N, K) int64 codes; returns (quantized, indices, loss)."""

    def __init__(self, config: UniDexTokConfig) -> None:
        super().__init__()
        self.num_groups = config.num_groups
        self.group_dim = config.group_dim
        self.codebook_size = config.codebook_size
        self.commitment_weight = config.commitment_weight
        self.codebook_weight = config.codebook_weight
        self.entropy_weight = config.entropy_weight
        self.entropy_temperature = config.entropy_temperature
        self.dead_code_threshold = config.dead_code_threshold
        self.usage_decay = config.usage_decay
        self.ema = config.codebook_update == "ema"
        self.rotation_trick = config.gradient_estimator == "rotation"
        self.ema_decay = config.ema_decay

        self.project_in = nn.Linear(config.hidden_dim, config.codebook_dim)
        self.project_out = nn.Linear(config.codebook_dim, config.hidden_dim)
        # (K, S, d): one codebook of S entries per group, compared by cosine similarity
        self.codebooks = nn.Parameter(torch.randn(config.num_groups, config.codebook_size, self.group_dim))
        # training statistics, not part of the checkpoint
        self.register_buffer(
            "usage_ema",
            torch.full((config.num_groups, config.codebook_size), 1.0 / config.codebook_size),
            persistent=False,
        )
        self.register_buffer("last_features", torch.empty(0), persistent=False)
        if self.ema:  # running sums of assigned vectors and counts (training statistics, not saved)
            self.codebooks.requires_grad_(False)
            self.register_buffer("ema_sum", torch.empty(0), persistent=False)
            self.register_buffer("ema_count", torch.empty(0), persistent=False)
        self.last_perplexity = float("nan")
        self.last_usage = float("nan")

    # -----------------------------------------------------------------------------------------
    # tensor helpers
    # -----------------------------------------------------------------------------------------
    def normalized_codebooks(self) -> torch.Tensor:
        return l2norm(self.codebooks)  # (K, S, d)

    def indices_to_codes(self, indices: torch.Tensor) -> torch.Tensor:
        """(..., K) int64 codes -> (..., K, d) unit-norm code vectors."""
        cb = self.normalized_codebooks()  # (K, S, d)
        groups = torch.arange(self.num_groups, device=indices.device)  # (K,)
        return cb[groups, indices]  # (..., K, d)

    def get_output_from_indices(self, indices: torch.Tensor) -> torch.Tensor:
        """(B, N, K) codes -> (B, N, C) quantised tokens as seen by the decoder."""
        codes = self.indices_to_codes(indices)  # (B, N, K, d)
        return self.project_out(codes.flatten(-2))  # (B, N, C)

    def unit_groups(self, z: torch.Tensor) -> torch.Tensor:
        """(B, N, C) tokens -> (B, N, K, d) unit-norm group vectors, the inputs of the code search."""
        b, n, _ = z.shape
        return l2norm(self.project_in(z).view(b, n, self.num_groups, self.group_dim))  # (B, N, K, d)

    def similarities(self, u: torch.Tensor) -> torch.Tensor:
        """(B, N, K, d) unit-norm group vectors -> (B, N, K, S) cosine similarity to every code of its group."""
        return torch.einsum("bnkd,ksd->bnks", u, self.normalized_codebooks())  # (B, N, K, S)

    def nearest_indices(self, z: torch.Tensor) -> torch.Tensor:
        """(B, N, C) tokens -> (B, N, K) int64 index of the nearest code per group (no losses, no statistics)."""
        return self.similarities(self.unit_groups(z)).argmax(dim=-1)  # (B, N, K)

    def check_indices(self, indices: torch.Tensor) -> None:
        if indices.dtype not in (torch.int64, torch.int32, torch.int16, torch.uint8):
            raise ValueError(f"codes must be an integer tensor, got dtype {indices.dtype}")
        if indices.shape[-1] != self.num_groups:
            raise ValueError(f"codes last dim must be num_groups={self.num_groups}, got {tuple(indices.shape)}")
        if indices.numel() and (int(indices.min()) < 0 or int(indices.max()) >= self.codebook_size):
            raise ValueError(f"codes must lie in [0, {self.codebook_size - 1}]")

    # -----------------------------------------------------------------------------------------
    # forward
    # -----------------------------------------------------------------------------------------
    def forward(
        self, z: torch.Tensor, return_loss_breakdown: bool = False
    ) -> (
        tuple[torch.Tensor, torch.Tensor, torch.Tensor] | tuple[torch.Tensor, torch.Tensor, torch.Tensor, LossBreakdown]
    ):
        # project and split into unit-norm group vectors
        u = self.unit_groups(z)  # (B, N, K, d)

        # nearest code by cosine similarity, per group
        sim = self.similarities(u)  # (B, N, K, S)
        indices = sim.argmax(dim=-1)  # (B, N, K)
        q = self.indices_to_codes(indices)  # (B, N, K, d)

        # losses: beta * commitment + codebook term (+ optional entropy)
        commitment = F.mse_loss(u, q.detach())
        codebook = F.mse_loss(q, u.detach()) if not self.ema else z.new_zeros(())
        entropy = z.new_zeros(())
        if self.entropy_weight > 0:
            probs = (sim / self.entropy_temperature).softmax(dim=-1)  # (B, N, K, S)
            per_sample = -(probs * probs.clamp_min(1e-9).log()).sum(-1).mean()
            avg = probs.flatten(0, 1).mean(0)  # (K, S)
            codebook_entropy = -(avg * avg.clamp_min(1e-9).log()).sum(-1).mean()
            entropy = per_sample - codebook_entropy
        loss = self.commitment_weight * commitment + self.codebook_weight * codebook + self.entropy_weight * entropy

        # gradient estimator (exact codes when no gradient is needed); both give q in the forward pass
        if not torch.is_grad_enabled():
            q_st = q  # (B, N, K, d)
        elif self.rotation_trick:  # R u with R (no gradient) the rotation taking unit u onto unit q
            ud, qd = u.detach(), q.detach()
            r = l2norm(ud + qd)  # (B, N, K, d)
            q_st = u - 2 * r * (u * r).sum(-1, keepdim=True) + 2 * qd * (u * ud).sum(-1, keepdim=True)
        else:  # straight-through
            q_st = u + (q - u).detach()  # (B, N, K, d)
        quantized = self.project_out(q_st.flatten(-2))  # (B, N, C)

        self._track_usage(indices, u)
        if self.ema and self.training and torch.is_grad_enabled():
            self._ema_update(indices, u)
        if return_loss_breakdown:
            return quantized, indices, loss, LossBreakdown(commitment, codebook, entropy)
        return quantized, indices, loss

    # -----------------------------------------------------------------------------------------
    # usage statistics and dead codes
    # -----------------------------------------------------------------------------------------
    @torch.no_grad()
    def _track_usage(self, indices: torch.Tensor, u: torch.Tensor) -> None:
        flat = indices.reshape(-1, self.num_groups)  # (M, K)
        counts = torch.zeros(self.num_groups, self.codebook_size, device=indices.device)  # (K, S)
        counts.scatter_add_(1, flat.T, torch.ones_like(flat.T, dtype=counts.dtype))
        probs = counts / counts.sum(-1, keepdim=True).clamp_min(1)  # (K, S)
        ent = -(probs * probs.clamp_min(1e-12).log()).sum(-1)  # (K,)
        self.last_perplexity = float(ent.exp().mean())
        self.last_usage = float((counts > 0).float().mean())
        if self.training:
            self.usage_ema.mul_(self.usage_decay).add_(probs, alpha=1 - self.usage_decay)
            self.last_features = u.detach().reshape(-1, self.num_groups, self.group_dim)  # (M, K, d)

    @torch.no_grad()
    def _ema_update(self, indices: torch.Tensor, u: torch.Tensor) -> None:
        """codebook <- EMA of the mean unit-norm vector assigned to each code (groups independent)."""
        flat_u = u.detach().reshape(-1, self.num_groups, self.group_dim).transpose(0, 1)  # (K, M, d)
        onehot = F.one_hot(indices.reshape(-1, self.num_groups).T, self.codebook_size).to(u.dtype)  # (K, M, S)
        counts = onehot.sum(1)  # (K, S)
        sums = torch.einsum("kms,kmd->ksd", onehot, flat_u)  # (K, S, d)
        if self.ema_sum.numel() == 0:
            self.ema_count = torch.ones_like(counts)
            self.ema_sum = l2norm(self.codebooks.data).clone()
        self.ema_count.mul_(self.ema_decay).add_(counts, alpha=1 - self.ema_decay)
        self.ema_sum.mul_(self.ema_decay).add_(sums, alpha=1 - self.ema_decay)
        self.codebooks.data.copy_(self.ema_sum / self.ema_count.clamp_min(1e-5).unsqueeze(-1))

    @torch.no_grad()
    def reseed_dead_codes(self) -> int:
        """Re-seed rarely used codes from the last training batch; returns how many were replaced."""
        if self.dead_code_threshold <= 0 or self.last_features.numel() == 0:
            return 0
        dead = self.usage_ema < self.dead_code_threshold / self.codebook_size  # (K, S)
        n_dead = int(dead.sum())
        if n_dead == 0:
            return 0
        feats = self.last_features  # (M, K, d)
        for k in range(self.num_groups):
            slots = dead[k].nonzero().flatten()
            if slots.numel() == 0:
                continue
            pick = torch.randint(0, feats.shape[0], (slots.numel(),), device=feats.device)
            self.codebooks.data[k, slots] = feats[pick, k] * self.codebooks.data[k].norm(dim=-1).mean()
            self.usage_ema[k, slots] = 1.0 / self.codebook_size
            if self.ema and self.ema_sum.numel():
                self.ema_sum[k, slots] = feats[pick, k]
                self.ema_count[k, slots] = 1.0
        return n_dead

    def codebook_usage(self) -> dict[str, float]:
        """Fraction of codes used and mean per-group perplexity of the last batch."""
        return {"usage": self.last_usage, "perplexity": self.last_perplexity}
