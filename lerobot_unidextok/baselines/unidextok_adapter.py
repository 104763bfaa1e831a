"""Thin adapter giving a UniDexTok model the `StateTokenizer` interface (rate from its config).

Duck-typed: `tokenizer/` sits on the same layer, so it is not imported here.
"""

from __future__ import annotations

import torch

from lerobot_unidextok.baselines.base import ArrayLike, Rate, as_states


class UniDexTokAdapter:
    """Wraps any model with `encode(states_rad, hand) -> (B, N, K)`, `decode(codes, hand)` and a
    `config` carrying `num_tokens`, `num_groups`, `codebook_size`."""

    name = "unidextok"

    def __init__(self, model) -> None:
        missing = [attr for attr in ("encode", "decode", "config") if not hasattr(model, attr)]
        if missing:
            raise ValueError(
                f"UniDexTokAdapter needs a model with encode/decode/config; {type(model).__name__} lacks {missing}"
            )
        self.model = model

    def rate(self, hand: str) -> Rate:
        cfg = self.model.config
        return Rate(cfg.num_tokens, cfg.num_groups, cfg.codebook_size)

    @torch.no_grad()
    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        return torch.as_tensor(self.model.encode(as_states(states_rad), hand)).to(torch.int64)  # (B, N, K)

    @torch.no_grad()
    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor:
        return torch.as_tensor(self.model.decode(codes, hand)).to(torch.float32)  # (B, 22) rad
