"""DiT-style adaLN-Zero transformer blocks conditioned on a hand-type embedding, and that embedding.

Block layout and the embedder with its extra "null" row and condition dropout follow facebookresearch/DiT
`models.py` (`DiTBlock`, `FinalLayer`, `LabelEmbedder`; written fresh here, not copied).
"""

import torch
import torch.nn.functional as F
from torch import nn


def modulate(x: torch.Tensor, shift: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """gamma(c) * x + beta(c) with gamma = 1 + scale: x (B, N, C), shift/scale (B, C)."""
    return x * (1 + scale.unsqueeze(1)) + shift.unsqueeze(1)


# ---------------------------------------------------------------------------------------------
# hand conditioning
# ---------------------------------------------------------------------------------------------
class HandEmbedder(nn.Module):
    """Hand-type embedding c_h: one row per vocabulary hand plus a last "unknown hand" row (DiT's
    `LabelEmbedder` null row), with hand dropout: in training, a `drop_prob` share of rows is routed to the
    unknown row, so the path that tokenises unseen hands zero-shot gets trained."""

    def __init__(self, num_hands: int, hidden_dim: int, device=None, dtype=None) -> None:
        super().__init__()
        # (H + 1, C), as an nn.Embedding's weight (state-dict key `hand_embed.weight`), same default init
        self.weight = nn.Parameter(torch.empty(num_hands + 1, hidden_dim, device=device, dtype=dtype))
        nn.init.normal_(self.weight)

    @property
    def unknown_id(self) -> int:
        """Id of the unknown-hand row (= the number of vocabulary hands)."""
        return self.weight.shape[0] - 1

    def token_drop(self, ids: torch.Tensor, drop_prob: float, generator: torch.Generator | None = None) -> torch.Tensor:
        """(B,) ids with a `drop_prob` share replaced by the unknown id; draws on the CPU from `generator`."""
        drop = torch.rand(ids.shape, generator=generator).to(ids.device) < drop_prob  # (B,)
        return torch.where(drop, torch.full_like(ids, self.unknown_id), ids)  # (B,)

    def forward(
        self, ids: torch.Tensor, drop_prob: float = 0.0, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """(B,) hand ids -> (B, C) embeddings; `drop_prob` applies in training mode only."""
        if self.training and drop_prob > 0:
            ids = self.token_drop(ids, drop_prob, generator)  # (B,)
        return F.embedding(ids, self.weight)  # (B, C)

    @torch.no_grad()
    def with_new_hands(self, count: int) -> "HandEmbedder":
        """A copy with `count` more vocabulary rows before the unknown row; they start equal to it."""
        grown = HandEmbedder(self.unknown_id + count, self.weight.shape[1], self.weight.device, self.weight.dtype)
        known, unknown = self.weight[:-1], self.weight[-1:]  # (H, C), (1, C)
        grown.weight.copy_(torch.cat([known, unknown.expand(count, -1), unknown], dim=0))  # (H + count + 1, C)
        return grown


# ---------------------------------------------------------------------------------------------
# attention and MLP
# ---------------------------------------------------------------------------------------------
class SelfAttention(nn.Module):
    """Multi-head self-attention through F.scaled_dot_product_attention."""

    def __init__(self, hidden_dim: int, num_heads: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.num_heads = num_heads
        self.qkv = nn.Linear(hidden_dim, 3 * hidden_dim)
        self.proj = nn.Linear(hidden_dim, hidden_dim)
        self.dropout = dropout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, n, c = x.shape
        qkv = self.qkv(x).view(b, n, 3, self.num_heads, c // self.num_heads)  # (B, N, 3, H, D)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # 3 x (B, H, N, D)
        p = self.dropout if self.training else 0.0
        y = F.scaled_dot_product_attention(q, k, v, dropout_p=p)  # (B, H, N, D)
        y = y.transpose(1, 2).reshape(b, n, c)  # (B, N, C)
        return self.proj(y)  # (B, N, C)


class MLP(nn.Module):
    """Linear -> GELU(tanh) -> Linear."""

    def __init__(self, hidden_dim: int, mlp_ratio: float, dropout: float = 0.0) -> None:
        super().__init__()
        inner = int(hidden_dim * mlp_ratio)
        self.fc1 = nn.Linear(hidden_dim, inner)
        self.fc2 = nn.Linear(inner, hidden_dim)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.drop(self.fc2(F.gelu(self.fc1(x), approximate="tanh")))  # (B, N, C)


# ---------------------------------------------------------------------------------------------
# conditioned blocks
# ---------------------------------------------------------------------------------------------
class AdaLNBlock(nn.Module):
    """Transformer block with adaLN-Zero: shift/scale/gate of both sub-layers come from c."""

    def __init__(self, hidden_dim: int, num_heads: int, mlp_ratio: float, dropout: float = 0.0) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(hidden_dim, elementwise_affine=False, eps=1e-6)
        self.attn = SelfAttention(hidden_dim, num_heads, dropout)
        self.norm2 = nn.LayerNorm(hidden_dim, elementwise_affine=False, eps=1e-6)
        self.mlp = MLP(hidden_dim, mlp_ratio, dropout)
        self.adaLN_modulation = nn.Sequential(nn.SiLU(), nn.Linear(hidden_dim, 6 * hidden_dim))

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        # x (B, N, C), c (B, C)
        mods = self.adaLN_modulation(c).chunk(6, dim=-1)  # 6 x (B, C)
        shift_msa, scale_msa, gate_msa, shift_mlp, scale_mlp, gate_mlp = mods
        x = x + gate_msa.unsqueeze(1) * self.attn(modulate(self.norm1(x), shift_msa, scale_msa))  # (B, N, C)
        x = x + gate_mlp.unsqueeze(1) * self.mlp(modulate(self.norm2(x), shift_mlp, scale_mlp))  # (B, N, C)
        return x  # (B, N, C)


class AdaLNFinalNorm(nn.Module):
    """Affine-free LayerNorm modulated by c (DiT's FinalLayer without its projection)."""

    def __init__(self, hidden_dim: int) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(hidden_dim, elementwise_affine=False, eps=1e-6)
        self.adaLN_modulation = nn.Sequential(nn.SiLU(), nn.Linear(hidden_dim, 2 * hidden_dim))

    def forward(self, x: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        shift, scale = self.adaLN_modulation(c).chunk(2, dim=-1)  # 2 x (B, C)
        return modulate(self.norm(x), shift, scale)  # (B, N, C)
