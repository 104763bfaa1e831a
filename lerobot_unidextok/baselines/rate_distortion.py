"""Rate-distortion rows: tokens and bits per state next to reconstruction errors, per method and hand.

Error functions are passed in (`evaluation.metrics` provides MPJAE / MPJPE); `mpjae_deg` here is the
masked mean absolute joint-angle error used when none is given.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field

import torch

from lerobot_unidextok.baselines.base import ArrayLike, StateTokenizer, as_mask, as_states

ErrorFn = Callable[[torch.Tensor, torch.Tensor, torch.Tensor, str], float]  # (gt_rad, recon_rad, mask, hand)


def mpjae_deg(gt_rad: torch.Tensor, recon_rad: torch.Tensor, mask: torch.Tensor, hand: str = "") -> float:
    """Mean absolute joint-angle error in degrees over the active slots."""
    err = (recon_rad - gt_rad).abs()[:, mask.bool()]  # (B, n_active)
    return float(torch.rad2deg(err).mean())


@dataclass
class RateDistortionRow:
    method: str
    hand: str
    tokens_per_state: int
    codes_per_state: int
    bits_per_state: float
    num_states: int
    errors: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict:
        row = asdict(self)
        row.update(row.pop("errors"))
        return row


@torch.no_grad()
def reconstruct(tokenizer: StateTokenizer, states_rad: ArrayLike, hand: str) -> torch.Tensor:
    """decode(encode(x)) for one hand, `(B, 22)` radians."""
    return tokenizer.decode(tokenizer.encode(states_rad, hand), hand)


def rate_distortion(
    tokenizers: Mapping[str, StateTokenizer],
    test_states: Mapping[str, ArrayLike],
    masks: Mapping[str, ArrayLike],
    error_fns: Mapping[str, ErrorFn] | None = None,
) -> list[RateDistortionRow]:
    """One row per (method, hand): rate of the method and each error function on the held-out states."""
    error_fns = error_fns or {"mpjae_deg": mpjae_deg}
    missing = sorted(set(test_states) - set(masks))
    if missing:
        raise ValueError(f"masks lack hands {missing}; pass one (22,) active mask per test hand")
    rows = []
    for method, tokenizer in tokenizers.items():
        for hand, states in test_states.items():
            gt = as_states(states, f"test_states[{hand!r}]")
            mask = as_mask(masks[hand], hand)
            recon = reconstruct(tokenizer, gt, hand)
            rate = tokenizer.rate(hand)
            rows.append(
                RateDistortionRow(
                    method=method,
                    hand=hand,
                    tokens_per_state=rate.tokens_per_state,
                    codes_per_state=rate.codes_per_state,
                    bits_per_state=rate.bits_per_state,
                    num_states=gt.shape[0],
                    errors={name: fn(gt, recon, mask, hand) for name, fn in error_fns.items()},
                )  # fmt: skip
            )
    return rows


def markdown_table(rows: list[RateDistortionRow]) -> str:
    """Rows as a Markdown table (errors as columns, 2 decimals)."""
    if not rows:
        return ""
    error_names = list(rows[0].errors)
    header = ["method", "hand", "tokens/state", "bits/state", *error_names]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        cells = [
            r.method,
            r.hand,
            str(r.tokens_per_state),
            f"{r.bits_per_state:g}",
            *(f"{r.errors[n]:.2f}" for n in error_names),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
