"""Uniform binning: codes in range, decode(encode(x)) within half a bin, rate, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok.baselines import BinningConfig, HandRange, UniformBinning
from lerobot_unidextok.baselines.base import StateTokenizer
from lerobot_unidextok.constants import UDHM_DIM

LIMITS = np.stack([np.full(UDHM_DIM, -0.5), np.full(UDHM_DIM, 1.6)], axis=1)
LIMITS[[5, 9, 13, 18]] = [-0.35, 0.35]  # abduction slots are narrower
INSPIRE_MASK = np.zeros(UDHM_DIM, bool)
INSPIRE_MASK[[0, 1, 6, 10, 14, 19]] = True


@pytest.fixture
def binning() -> UniformBinning:
    return UniformBinning(
        {
            "human": HandRange.from_limits(LIMITS, np.ones(UDHM_DIM, bool)),
            "inspire": HandRange.from_limits(LIMITS, INSPIRE_MASK),
        }
    )


def _inside(n: int, mask: np.ndarray, seed: int = 0) -> torch.Tensor:
    rng = np.random.default_rng(seed)
    x = rng.uniform(LIMITS[:, 0], LIMITS[:, 1], size=(n, UDHM_DIM)) * mask
    return torch.as_tensor(x, dtype=torch.float32)


@pytest.mark.parametrize("hand, mask", [("human", np.ones(UDHM_DIM, bool)), ("inspire", INSPIRE_MASK)])
def test_roundtrip_within_half_bin(binning: UniformBinning, hand: str, mask: np.ndarray) -> None:
    x = _inside(2000, mask)
    codes = binning.encode(x, hand)
    assert codes.dtype == torch.int64 and codes.shape == (2000, int(mask.sum()))
    assert codes.min() >= 0 and codes.max() <= 255
    recon = binning.decode(codes, hand)
    assert recon.shape == (2000, UDHM_DIM)
    err = (recon - x).abs()[:, torch.as_tensor(mask)].numpy()
    half_bin = binning.bin_width_rad(hand) / 2
    assert (err <= half_bin + 1e-6).all()
    assert err.max() > 0.9 * half_bin.min()  # the bound is tight, not vacuous
    assert (recon[:, ~torch.as_tensor(mask)] == 0).all()


def test_edges_and_clipping(binning: UniformBinning) -> None:
    x = torch.as_tensor(np.stack([LIMITS[:, 0], LIMITS[:, 1], LIMITS[:, 0] - 1, LIMITS[:, 1] + 1]), dtype=torch.float32)
    codes = binning.encode(x, "human")
    assert (codes[0] == 0).all() and (codes[1] == 255).all()
    assert torch.equal(codes[2], codes[0]) and torch.equal(codes[3], codes[1])


def test_rate_matches_rt2(binning: UniformBinning) -> None:
    assert isinstance(binning, StateTokenizer)
    assert binning.rate("human").bits_per_state == 176  # 22 x 8 bits
    assert binning.rate("inspire").tokens_per_state == 6
    assert (
        UniformBinning({"h": HandRange.from_limits(LIMITS, np.ones(22))}, BinningConfig(num_bins=16))
        .rate("h")
        .bits_per_state
        == 88
    )


def test_bad_input_errors(binning: UniformBinning) -> None:
    with pytest.raises(ValueError, match="shape"):
        binning.encode(torch.zeros(3, 44), "human")
    with pytest.raises(ValueError, match="knows"):
        binning.encode(torch.zeros(3, 22), "allegro")
    with pytest.raises(ValueError, match=r"\[0, 256\)"):
        binning.decode(torch.full((1, 22), 256), "human")
    with pytest.raises(ValueError, match="upper_rad > lower_rad"):
        HandRange.from_limits(np.zeros((22, 2)), np.ones(22))
    with pytest.raises(ValueError, match="NaN"):
        binning.encode(torch.full((1, 22), float("nan")), "human")
