"""The tokenizer protocol every baseline (and UniDexTok, through an adapter) satisfies.

A state tokenizer maps UDHM states `(B, 22)` in radians of one hand type to integer codes and back.
Hands are known by their spec name only (`"human"`, `"inspire_rh56"`); masks and limits arrive as data.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import torch

from lerobot_unidextok.constants import UDHM_DIM

ArrayLike = torch.Tensor | np.ndarray


# ---------------------------------------------------------------------------------------------
# rate: what one state costs in tokens and bits
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rate:
    """Token budget of one hand state: `tokens_per_state` tokens of `codes_per_token` codes each."""

    tokens_per_state: int
    codes_per_token: int
    vocab_per_code: int  # entries each code chooses from (256 for 8-bit bins, 32 for a 5-bit group)

    @property
    def bits_per_code(self) -> float:
        return math.log2(self.vocab_per_code)

    @property
    def codes_per_state(self) -> int:
        return self.tokens_per_state * self.codes_per_token

    @property
    def bits_per_state(self) -> float:
        return self.codes_per_state * self.bits_per_code


@runtime_checkable
class StateTokenizer(Protocol):
    """encode `(B, 22)` rad -> int64 codes, decode codes -> `(B, 22)` rad, with a per-hand rate."""

    name: str

    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor: ...

    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor: ...

    def rate(self, hand: str) -> Rate: ...


@runtime_checkable
class TrainableStateTokenizer(StateTokenizer, Protocol):
    """A tokenizer that must see training states first; `fit` returns its loss history."""

    def fit(self, train_states: Mapping[str, ArrayLike], masks: Mapping[str, ArrayLike] | None = None) -> dict: ...


def tokens_per_state(tokenizer: StateTokenizer, hand: str) -> int:
    return tokenizer.rate(hand).tokens_per_state


def bits_per_state(tokenizer: StateTokenizer, hand: str) -> float:
    return tokenizer.rate(hand).bits_per_state


# ---------------------------------------------------------------------------------------------
# input checks shared by all tokenizers
# ---------------------------------------------------------------------------------------------
def as_states(states_rad: ArrayLike, what: str = "states_rad") -> torch.Tensor:
    """Return a float32 `(B, 22)` tensor, or raise a ValueError naming the shape fix."""
    states = torch.as_tensor(np.asarray(states_rad) if not isinstance(states_rad, torch.Tensor) else states_rad)
    if states.ndim == 1:
        states = states[None]
    if states.ndim != 2 or states.shape[-1] != UDHM_DIM:
        raise ValueError(
            f"{what} must have shape (B, {UDHM_DIM}) (one UDHM block per row, radians); got {tuple(states.shape)}. "
            "Split two-hand states (B, 44) into one 22-block per hand first."
        )
    if not torch.isfinite(states).all():
        raise ValueError(f"{what} contains NaN or inf; drop or interpolate those frames before tokenizing")
    return states.to(torch.float32)


def as_mask(mask: ArrayLike, hand: str) -> torch.Tensor:
    """Return a bool `(22,)` active-DoF mask, or raise naming the hand."""
    mask_t = torch.as_tensor(np.asarray(mask) if not isinstance(mask, torch.Tensor) else mask).to(torch.bool)
    if mask_t.shape != (UDHM_DIM,):
        raise ValueError(f"mask of hand {hand!r} must have shape ({UDHM_DIM},); got {tuple(mask_t.shape)}")
    if not mask_t.any():
        raise ValueError(f"mask of hand {hand!r} has no active UDHM slot; check the hand spec's active_mask")
    return mask_t


def infer_masks(train_states: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Active slots per hand = slots that are non-zero in at least one training state."""
    return {hand: as_mask(states.ne(0).any(dim=0), hand) for hand, states in train_states.items()}


def check_hand(hand: str, known: Mapping[str, object], tokenizer: str) -> None:
    if hand not in known:
        raise ValueError(
            f"{tokenizer} does not know hand {hand!r}; it knows {sorted(known)}. "
            "Fit it on data of that hand (or pass the hand's range/mask when building it)."
        )


@torch.no_grad()
def reconstruct(tokenizer: StateTokenizer, states_rad: ArrayLike, hand: str) -> torch.Tensor:
    """decode(encode(x)) for one hand, `(B, 22)` radians. Score it with `evaluation.metrics`."""
    return tokenizer.decode(tokenizer.encode(states_rad, hand), hand)
