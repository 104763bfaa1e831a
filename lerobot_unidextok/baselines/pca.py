"""PCA + uniform binning: the simplest rival at UniDexTok's token count.

Each hand's training states (its active UDHM slots, radians) are centred and projected on their first
`num_components` principal components; each component is binned uniformly into `2**bits` bins over its
training range (values outside are clipped). Default 8 components x 8 bits = 8 tokens, 64 bits per state.
`shared=True` fits one PCA over all hands' 22-slot states instead (inactive slots are zero) and masks the
decoded state with the hand's active slots, so it also codes hands it never saw if their mask is given.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from lerobot_unidextok.baselines.base import ArrayLike, Rate, as_mask, as_states, check_hand, infer_masks
from lerobot_unidextok.constants import UDHM_DIM

SHARED = "__shared__"


@dataclass(frozen=True)
class PCAConfig:
    num_components: int = 8  # tokens per state (UniDexTok: 8)
    bits: int = 8  # bits per token: 2**bits uniform bins per component
    shared: bool = False  # one PCA over all hands (masked) instead of one per hand

    def __post_init__(self) -> None:
        if not 1 <= self.num_components <= UDHM_DIM:
            raise ValueError(f"num_components must be in [1, {UDHM_DIM}], got {self.num_components}")
        if not 1 <= self.bits <= 16:
            raise ValueError(f"bits must be in [1, 16], got {self.bits}")


@dataclass(frozen=True)
class _Basis:
    dims: np.ndarray  # (D,) UDHM slots the basis works on
    mean: np.ndarray  # (D,)
    components: np.ndarray  # (D, M) orthonormal columns, M <= num_components
    lower: np.ndarray  # (M,) training range of each coefficient
    upper: np.ndarray  # (M,)


class PCATokenizer:
    """PCA to `num_components` coefficients, each binned to `bits` bits; codes `(B, M)` in [0, 2**bits)."""

    name = "pca"

    def __init__(self, config: PCAConfig | None = None) -> None:
        self.config = config or PCAConfig()
        self.bases: dict[str, _Basis] = {}
        self.masks: dict[str, np.ndarray] = {}

    @property
    def num_bins(self) -> int:
        return 2**self.config.bits

    def fit(self, train_states: Mapping[str, ArrayLike], masks: Mapping[str, ArrayLike] | None = None) -> dict:
        """Fit on `{hand: (N, 22) rad}`; `masks` may also name hands without rows (shared mode codes them)."""
        if not train_states:
            raise ValueError("PCATokenizer.fit needs states of at least one hand: {'human': (N, 22) radians, ...}")
        states = {h: as_states(s, f"train_states[{h!r}]").double().numpy() for h, s in train_states.items()}
        empty = [h for h, s in states.items() if len(s) == 0]
        if empty:
            raise ValueError(f"train_states has no frames for {empty}; drop those hands or add data")
        given = {h: as_mask(m, h).numpy() for h, m in (masks or {}).items()}
        inferred = {h: m.numpy() for h, m in infer_masks({h: torch.as_tensor(s) for h, s in states.items()}).items()}
        self.masks = {**inferred, **given}
        if self.config.shared:
            rows = np.concatenate([s * self.masks[h] for h, s in states.items()])
            fitted = {SHARED: self._fit_basis(rows, np.arange(UDHM_DIM))}
        else:
            fitted = {h: self._fit_basis(s, np.flatnonzero(self.masks[h])) for h, s in states.items()}
        self.bases = {h: basis for h, (basis, _) in fitted.items()}
        return {"explained_variance_ratio": {h: ratio for h, (_, ratio) in fitted.items()}}

    def _fit_basis(self, rows: np.ndarray, dims: np.ndarray) -> tuple[_Basis, float]:
        x = rows[:, dims]  # (N, D)
        mean = x.mean(0)
        _, s, vt = np.linalg.svd(x - mean, full_matrices=False)
        m = min(self.config.num_components, len(dims), len(x))
        comps = vt[:m].T  # (D, M)
        coef = (x - mean) @ comps  # (N, M)
        lower, upper = coef.min(0), coef.max(0)
        upper = np.where(upper > lower, upper, lower + 1e-6)
        var = s**2
        return _Basis(dims, mean, comps, lower, upper), float(var[:m].sum() / max(var.sum(), 1e-12))

    def _basis(self, hand: str) -> _Basis:
        check_hand(hand, self.masks, self.name)
        return self.bases[SHARED] if self.config.shared else self.bases[hand]

    def rate(self, hand: str) -> Rate:
        return Rate(self._basis(hand).components.shape[1], 1, self.num_bins)

    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        b = self._basis(hand)
        x = as_states(states_rad).double().numpy() * self.masks[hand]  # (B, 22)
        coef = (x[:, b.dims] - b.mean) @ b.components  # (B, M)
        unit = (coef - b.lower) / (b.upper - b.lower)
        return torch.as_tensor(np.clip(np.floor(unit * self.num_bins), 0, self.num_bins - 1).astype(np.int64))

    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor:
        b = self._basis(hand)
        codes = torch.as_tensor(codes)
        m = b.components.shape[1]
        if codes.ndim != 2 or codes.shape[1] != m:
            raise ValueError(f"PCA codes of hand {hand!r} must have shape (B, {m}); got {tuple(codes.shape)}")
        if codes.numel() and (codes.min() < 0 or codes.max() >= self.num_bins):
            raise ValueError(f"PCA codes must lie in [0, {self.num_bins}); got [{codes.min()}, {codes.max()}]")
        coef = b.lower + (codes.numpy().astype(np.float64) + 0.5) * (b.upper - b.lower) / self.num_bins  # (B, M)
        out = np.zeros((codes.shape[0], UDHM_DIM))
        out[:, b.dims] = b.mean + coef @ b.components.T
        return torch.as_tensor(out * self.masks[hand], dtype=torch.float32)  # (B, 22), inactive slots zero
