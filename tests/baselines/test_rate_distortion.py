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


def test_unidextok_adapter_on_the_real_model() -> None:
    tokenizer = pytest.importorskip("lerobot_unidextok.tokenizer")
    cfg = tokenizer.UniDexTokConfig.from_preset("tiny", hand_names=["human", "inspire_rh56"])
    adapter = UniDexTokAdapter(tokenizer.UniDexTok(cfg).eval())
    rate = adapter.rate("human")
    assert (rate.tokens_per_state, rate.codes_per_token, rate.vocab_per_code) == (4, 8, 32)
    assert rate.bits_per_state == 4 * 8 * 5
    x = torch.rand(5, 22)
    codes = adapter.encode(x, "human")
    assert codes.dtype == torch.int64 and codes.shape == (5, 4, 8) and 0 <= codes.min() and codes.max() < 32
    assert adapter.decode(codes, "human").shape == (5, 22)
    paper = tokenizer.UniDexTokConfig.from_preset("paper")
    assert Rate(paper.num_tokens, paper.num_groups, paper.codebook_size).bits_per_state == 320
    with pytest.raises(ValueError, match="encode/decode/config"):
        UniDexTokAdapter(object())
