"""Rates (tokens and bits per state) of the paper budgets and of UniDexTok through its adapter."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok.baselines.base import Rate
from lerobot_unidextok.baselines.unidextok_adapter import UniDexTokAdapter

LIMITS = np.stack([np.full(22, -0.5), np.full(22, 1.6)], axis=1)


def test_rates_of_the_paper_budgets() -> None:
    assert Rate(22, 1, 256).bits_per_state == 176
    assert Rate(8, 8, 32).bits_per_state == 320
    assert Rate(1, 1, 8192).bits_per_state == 13


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
