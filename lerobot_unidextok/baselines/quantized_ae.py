"""FSQ and residual-VQ baselines from `vector-quantize-pytorch`, at UniDexTok's token budget.

One small hand-conditioned MLP autoencoder shared by all hands (the hand enters as a learned embedding,
like UniDexTok's c_h), with N tokens per state; only the quantizer differs:
- FSQ: each token is `codes_per_token` FSQ codebooks, each with `bits_per_code` bits of levels.
- RVQ: each token is quantised by `codes_per_token` residual stages of `2**bits_per_code` entries.
Default 8 tokens x 8 codes x 5 bits = 320 bits, UniDexTok's budget.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import torch
from torch import nn

from lerobot_unidextok.baselines.base import ArrayLike, Rate, as_mask, as_states, check_hand, infer_masks
from lerobot_unidextok.constants import ANGLE_SCALE_RAD, UDHM_DIM
from lerobot_unidextok.utils.cli import progress_bar
from lerobot_unidextok.utils.imports import require_package

# FSQ levels per code for a bit budget (FSQ paper, Table 1, for 8 and 10 bits; the others are our choice).
FSQ_LEVELS: dict[int, tuple[int, ...]] = {3: (8,), 4: (4, 4), 5: (8, 4), 6: (8, 8), 8: (8, 6, 5), 10: (8, 5, 5, 5)}
QUANTIZERS = ("fsq", "rvq")


def require_vector_quantize() -> None:
    """ImportError naming the `baselines` extra when vector-quantize-pytorch is missing."""
    require_package(
        "vector-quantize-pytorch", "baselines", purpose="an FSQ / RVQ baseline", import_name="vector_quantize_pytorch"
    )


@dataclass
class QuantizedAEConfig:
    """Shared MLP autoencoder around an FSQ or residual-VQ bottleneck."""

    quantizer: str = "fsq"  # "fsq" | "rvq"
    num_tokens: int = 8  # N tokens per state (UniDexTok: 8)
    codes_per_token: int = 8  # FSQ codebooks / RVQ stages per token (UniDexTok: 8 groups)
    bits_per_code: int = 5  # FSQ: levels from FSQ_LEVELS; RVQ: 2**bits entries per stage (UniDexTok: 32)
    token_dim: int = 32  # width of one token before the quantizer's own projection
    hidden_dim: int = 256
    hand_embed_dim: int = 16
    batch_size: int = 256  # per hand and step
    lr: float = 1e-3
    steps: int = 2000
    commitment_weight: float = 0.25  # RVQ only (FSQ has no auxiliary loss)
    seed: int = 0
    progress: bool = True
    hands: list[str] = field(default_factory=list)  # filled by fit

    def __post_init__(self) -> None:
        if self.quantizer not in QUANTIZERS:
            raise ValueError(f"quantizer must be one of {QUANTIZERS}; got {self.quantizer!r}")
        if self.quantizer == "fsq" and self.bits_per_code not in FSQ_LEVELS:
            raise ValueError(f"FSQ bits_per_code must be one of {sorted(FSQ_LEVELS)}; got {self.bits_per_code}")
        if min(self.num_tokens, self.codes_per_token, self.bits_per_code, self.steps) < 1:
            raise ValueError("num_tokens, codes_per_token, bits_per_code and steps must all be >= 1")

    @property
    def vocab_per_code(self) -> int:
        if self.quantizer == "fsq":
            return math.prod(FSQ_LEVELS[self.bits_per_code])
        return 2**self.bits_per_code

    @classmethod
    def from_preset(cls, name: str, **overrides) -> QuantizedAEConfig:
        if name not in QAE_PRESETS:
            raise ValueError(f"unknown preset {name!r}; choose one of {sorted(QAE_PRESETS)}")
        return replace(QAE_PRESETS[name], **overrides)


QAE_PRESETS: dict[str, QuantizedAEConfig] = {
    "cpu": QuantizedAEConfig(),
    "tiny": QuantizedAEConfig(hidden_dim=32, token_dim=8, batch_size=32, lr=3e-3, steps=120, progress=False),
}


class QuantizedAETokenizer(nn.Module):
    """Hand-conditioned MLP autoencoder; codes `(B, num_tokens, codes_per_token)` in [0, vocab_per_code)."""

    def __init__(self, config: QuantizedAEConfig | None = None) -> None:
        super().__init__()
        require_vector_quantize()
        self.config = config or QuantizedAEConfig()
        self.name = self.config.quantizer
        cfg = self.config
        width = cfg.num_tokens * cfg.token_dim
        self.encoder = nn.Sequential(
            nn.Linear(UDHM_DIM + cfg.hand_embed_dim, cfg.hidden_dim), nn.GELU(),
            nn.Linear(cfg.hidden_dim, cfg.hidden_dim), nn.GELU(),
            nn.Linear(cfg.hidden_dim, width),
        )  # fmt: skip
        self.decoder = nn.Sequential(
            nn.Linear(width + cfg.hand_embed_dim, cfg.hidden_dim), nn.GELU(),
            nn.Linear(cfg.hidden_dim, cfg.hidden_dim), nn.GELU(),
            nn.Linear(cfg.hidden_dim, UDHM_DIM),
        )  # fmt: skip
        if cfg.quantizer == "fsq":
            from vector_quantize_pytorch import FSQ

            self.quantizer = FSQ(
                levels=list(FSQ_LEVELS[cfg.bits_per_code]), dim=cfg.token_dim, num_codebooks=cfg.codes_per_token
            )
        else:
            from vector_quantize_pytorch import ResidualVQ

            self.quantizer = ResidualVQ(
                dim=cfg.token_dim, num_quantizers=cfg.codes_per_token, codebook_size=cfg.vocab_per_code,
                kmeans_init=True, threshold_ema_dead_code=2, commitment_weight=cfg.commitment_weight,
            )  # fmt: skip
        self.hand_embedding: nn.Embedding | None = None
        self.masks: dict[str, torch.Tensor] = {}

    # --- public API -------------------------------------------------------------------------
    def rate(self, hand: str) -> Rate:
        return Rate(self.config.num_tokens, self.config.codes_per_token, self.config.vocab_per_code)

    def _hand_vec(self, hand: str, batch: int) -> torch.Tensor:
        check_hand(hand, self.masks, self.name)
        idx = torch.full((batch,), self.config.hands.index(hand), dtype=torch.long)
        return self.hand_embedding(idx)  # (B, E)

    def _latent(self, x_norm: torch.Tensor, hand: str) -> torch.Tensor:
        cond = self._hand_vec(hand, x_norm.shape[0])
        z = self.encoder(torch.cat([x_norm, cond], dim=-1))  # (B, N * d)
        return z.view(x_norm.shape[0], self.config.num_tokens, self.config.token_dim)  # (B, N, d)

    def _reconstruct(self, z_q: torch.Tensor, hand: str) -> torch.Tensor:
        cond = self._hand_vec(hand, z_q.shape[0])
        return self.decoder(torch.cat([z_q.flatten(1), cond], dim=-1))  # (B, 22) normalised

    @torch.no_grad()
    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        check_hand(hand, self.masks, self.name)
        x_norm = as_states(states_rad) / ANGLE_SCALE_RAD * self.masks[hand]
        _, indices, *_ = self.quantizer(self._latent(x_norm, hand))
        return indices.to(torch.int64)  # (B, N, codes_per_token)

    @torch.no_grad()
    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor:
        check_hand(hand, self.masks, self.name)
        cfg = self.config
        codes = torch.as_tensor(codes)
        if codes.ndim != 3 or codes.shape[1:] != (cfg.num_tokens, cfg.codes_per_token):
            raise ValueError(
                f"{self.name} codes must have shape (B, {cfg.num_tokens}, {cfg.codes_per_token}); got {tuple(codes.shape)}"
            )
        if codes.numel() and (codes.min() < 0 or codes.max() >= cfg.vocab_per_code):
            raise ValueError(
                f"{self.name} codes must lie in [0, {cfg.vocab_per_code}); got [{codes.min()}, {codes.max()}]"
            )
        if cfg.quantizer == "fsq":
            z_q = self.quantizer.indices_to_codes(codes)  # (B, N, d)
        else:
            z_q = self.quantizer.get_output_from_indices(codes)  # (B, N, d)
        return self._reconstruct(z_q, hand) * ANGLE_SCALE_RAD * self.masks[hand]  # (B, 22) rad

    # --- training ---------------------------------------------------------------------------
    def fit(self, train_states: Mapping[str, ArrayLike], masks: Mapping[str, ArrayLike] | None = None) -> dict:
        """Train on `{hand: (N, 22) rad}` with masked MSE on angles / pi; returns {"loss": [...]}."""
        cfg = self.config
        if not train_states:
            raise ValueError(f"{self.name}.fit needs states of at least one hand: {{'human': (N, 22) radians}}")
        states = {hand: as_states(s, f"train_states[{hand!r}]") for hand, s in train_states.items()}
        self.masks = (
            {hand: as_mask(masks[hand], hand).float() for hand in states} if masks is not None
            else {hand: m.float() for hand, m in infer_masks(states).items()}
        )  # fmt: skip
        cfg.hands = sorted(states)
        torch.manual_seed(cfg.seed)
        generator = torch.Generator().manual_seed(cfg.seed)
        self.hand_embedding = nn.Embedding(len(cfg.hands), cfg.hand_embed_dim)
        norm = {hand: s / ANGLE_SCALE_RAD * self.masks[hand] for hand, s in states.items()}
        opt = torch.optim.AdamW(self.parameters(), lr=cfg.lr)
        self.train()
        losses = []
        for _ in progress_bar(range(cfg.steps), desc=f"{self.name} autoencoder", disable=not cfg.progress):
            loss = torch.zeros(())
            for hand, data in norm.items():
                x = data[torch.randint(data.shape[0], (cfg.batch_size,), generator=generator)]  # (B, 22)
                out = self.quantizer(self._latent(x, hand))
                z_q, aux = out[0], (out[2].sum() if len(out) > 2 else 0.0)
                mask = self.masks[hand]
                recon = ((self._reconstruct(z_q, hand) - x) ** 2 * mask).sum() / (mask.sum() * x.shape[0])
                loss = loss + recon + aux
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(loss.item())
        self.eval()
        return {"loss": losses}


def fsq_tokenizer(config: QuantizedAEConfig | None = None) -> QuantizedAETokenizer:
    return QuantizedAETokenizer(replace(config or QuantizedAEConfig(), quantizer="fsq"))


def rvq_tokenizer(config: QuantizedAEConfig | None = None) -> QuantizedAETokenizer:
    return QuantizedAETokenizer(replace(config or QuantizedAEConfig(), quantizer="rvq"))
