"""Rate-distortion rows: rates per method, MPJAE consistent with a direct computation, table output."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok.baselines import HandRange, UniformBinning, markdown_table, mpjae_deg, rate_distortion
from lerobot_unidextok.baselines.base import Rate
from lerobot_unidextok.baselines.unidextok_adapter import UniDexTokAdapter

LIMITS = np.stack([np.full(22, -0.5), np.full(22, 1.6)], axis=1)


def test_rates_of_the_paper_budgets() -> None:
    assert Rate(22, 1, 256).bits_per_state == 176
    assert Rate(8, 8, 32).bits_per_state == 320
    assert Rate(1, 1, 8192).bits_per_state == 13


def test_rows_for_two_bin_counts(train_states, masks) -> None:
    coarse = UniformBinning({h: HandRange.from_limits(LIMITS, m) for h, m in masks.items()}, config=None)
    from lerobot_unidextok.baselines import BinningConfig

    fine = UniformBinning({h: HandRange.from_limits(LIMITS, m) for h, m in masks.items()}, BinningConfig(num_bins=16))
    rows = rate_distortion({"b256": coarse, "b16": fine}, train_states, masks)
    by = {(r.method, r.hand): r for r in rows}
    assert len(rows) == 4
    assert by["b256", "human"].bits_per_state == 176 and by["b16", "human"].bits_per_state == 88
    assert by["b256", "inspire_rh56"].tokens_per_state == 6
    # fewer bits, more error; 256 bins over 2.1 rad: mean error ~ width/4 = 0.12 deg
    assert by["b16", "human"].errors["mpjae_deg"] > 10 * by["b256", "human"].errors["mpjae_deg"]
    assert 0.05 < by["b256", "human"].errors["mpjae_deg"] < 0.2
    table = markdown_table(rows)
    assert table.count("\n") == 5 and "| b16 | human | 22 | 88 |" in table


def test_mpjae_ignores_inactive_slots() -> None:
    gt = torch.zeros(4, 22)
    recon = torch.zeros(4, 22)
    recon[:, 3] = torch.deg2rad(torch.tensor(10.0))
    mask = torch.zeros(22, dtype=torch.bool)
    mask[[3, 4]] = True
    assert mpjae_deg(gt, recon, mask) == pytest.approx(5.0, rel=1e-5)
    mask[3] = False
    assert mpjae_deg(gt, recon, mask) == 0.0


def test_unidextok_adapter_rate_and_errors() -> None:
    class Cfg:
        num_tokens, num_groups, codebook_size = 8, 8, 32

    class Model:
        config = Cfg()

        def encode(self, states_rad, hand):
            return torch.zeros(states_rad.shape[0], 8, 8, dtype=torch.long)

        def decode(self, codes, hand):
            return torch.zeros(codes.shape[0], 22)

    adapter = UniDexTokAdapter(Model())
    assert adapter.rate("human").bits_per_state == 320
    assert adapter.encode(torch.zeros(3, 22), "human").shape == (3, 8, 8)
    with pytest.raises(ValueError, match="encode/decode/config"):
        UniDexTokAdapter(object())
