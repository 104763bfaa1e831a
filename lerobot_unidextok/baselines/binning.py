"""Per-dimension uniform binning (the RT-2 / OpenVLA state tokenization): no training.

Each active UDHM slot of a hand gets `num_bins` equal bins over [lower, upper]; a state becomes one
token per active slot. Inputs outside the limits are clipped (as OpenVLA clips to [-1, 1]), so the
decode error is at most half a bin width inside the limits.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from lerobot_unidextok.baselines.base import ArrayLike, Rate, as_mask, as_states, check_hand
from lerobot_unidextok.constants import UDHM_DIM


@dataclass(frozen=True)
class HandRange:
    """Joint limits (radians) and active-DoF mask of one hand type, all `(22,)` in UDHM order."""

    lower_rad: np.ndarray
    upper_rad: np.ndarray
    active_mask: np.ndarray

    def __post_init__(self) -> None:
        for field_name in ("lower_rad", "upper_rad", "active_mask"):
            value = np.asarray(getattr(self, field_name))
            if value.shape != (UDHM_DIM,):
                raise ValueError(f"HandRange.{field_name} must have shape ({UDHM_DIM},); got {value.shape}")
            object.__setattr__(self, field_name, value)
        mask = self.active_mask.astype(bool)
        object.__setattr__(self, "active_mask", mask)
        bad = np.flatnonzero(mask & ~(self.upper_rad > self.lower_rad))
        if bad.size:
            raise ValueError(
                f"HandRange needs upper_rad > lower_rad on every active slot; slots {bad.tolist()} violate it "
                f"(lower {self.lower_rad[bad].tolist()}, upper {self.upper_rad[bad].tolist()})"
            )

    @classmethod
    def from_limits(cls, limits_rad: ArrayLike, active_mask: ArrayLike) -> HandRange:
        """From a `(22, 2)` [lower, upper] table (e.g. `udhm.JOINT_LIMITS_RAD`) and a `(22,)` mask."""
        limits = np.asarray(limits_rad, dtype=np.float64)
        if limits.shape != (UDHM_DIM, 2):
            raise ValueError(f"limits_rad must have shape ({UDHM_DIM}, 2) as [lower, upper]; got {limits.shape}")
        return cls(limits[:, 0], limits[:, 1], as_mask(active_mask, "range").numpy())


@dataclass(frozen=True)
class BinningConfig:
    num_bins: int = 256  # RT-2 / OpenVLA: 256 bins, 8 bits per dimension

    def __post_init__(self) -> None:
        if self.num_bins < 2:
            raise ValueError(f"num_bins must be >= 2; got {self.num_bins}")


class UniformBinning:
    """Uniform per-joint binning over each hand's limits; codes `(B, n_active)` in [0, num_bins)."""

    name = "binning"

    def __init__(self, ranges: Mapping[str, HandRange], config: BinningConfig | None = None) -> None:
        if not ranges:
            raise ValueError("UniformBinning needs at least one hand range, e.g. {'human': HandRange(...)}")
        self.config = config or BinningConfig()
        self.ranges = dict(ranges)

    # -----------------------------------------------------------------------------------------
    def bin_width_rad(self, hand: str) -> np.ndarray:
        """Bin width per active slot, `(n_active,)` radians."""
        check_hand(hand, self.ranges, self.name)
        rng = self.ranges[hand]
        idx = rng.active_mask
        return (rng.upper_rad[idx] - rng.lower_rad[idx]) / self.config.num_bins

    def rate(self, hand: str) -> Rate:
        check_hand(hand, self.ranges, self.name)
        return Rate(int(self.ranges[hand].active_mask.sum()), 1, self.config.num_bins)

    def _active_bounds(self, hand: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        check_hand(hand, self.ranges, self.name)
        rng = self.ranges[hand]
        mask = torch.as_tensor(rng.active_mask)
        lower = torch.as_tensor(rng.lower_rad[rng.active_mask], dtype=torch.float64)
        upper = torch.as_tensor(rng.upper_rad[rng.active_mask], dtype=torch.float64)
        return mask, lower, upper

    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        mask, lower, upper = self._active_bounds(hand)
        states = as_states(states_rad).to(torch.float64)[:, mask]  # (B, n_active)
        unit = (states - lower) / (upper - lower)  # (B, n_active) in [0, 1] inside the limits
        codes = torch.floor(unit * self.config.num_bins)
        return codes.clamp(0, self.config.num_bins - 1).to(torch.int64)

    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor:
        mask, lower, upper = self._active_bounds(hand)
        codes = torch.as_tensor(codes)
        if codes.ndim != 2 or codes.shape[-1] != int(mask.sum()):
            raise ValueError(
                f"binning codes of hand {hand!r} must have shape (B, {int(mask.sum())}); got {tuple(codes.shape)}"
            )
        if codes.numel() and (codes.min() < 0 or codes.max() >= self.config.num_bins):
            raise ValueError(
                f"binning codes must lie in [0, {self.config.num_bins}); got [{codes.min()}, {codes.max()}]"
            )
        centres = lower + (codes.to(torch.float64) + 0.5) * (upper - lower) / self.config.num_bins  # (B, n_active)
        states = torch.zeros(codes.shape[0], UDHM_DIM, dtype=torch.float32)
        states[:, mask] = centres.to(torch.float32)
        return states  # (B, 22), inactive slots zero
