"""Shared training states for the trainable baselines: smooth low-dimensional hand poses inside limits."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok.constants import UDHM_DIM

INSPIRE_MASK = np.zeros(UDHM_DIM, bool)
INSPIRE_MASK[[0, 1, 6, 10, 14, 19]] = True


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    """Small models on 2 shared cores: one thread avoids oversubscription; restored afterwards."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def synergy_states(n: int, seed: int) -> torch.Tensor:
    """Poses from 3 random postural synergies (grasp-like correlations), radians in about [-0.4, 1.6]."""
    rng = np.random.default_rng(seed)
    basis = rng.normal(0.0, 0.4, size=(3, UDHM_DIM))
    weights = rng.uniform(-1.0, 1.0, size=(n, 3))
    return torch.as_tensor(np.clip(0.6 + weights @ basis, -0.4, 1.6), dtype=torch.float32)


@pytest.fixture(scope="module")
def train_states() -> dict[str, torch.Tensor]:
    human = synergy_states(600, seed=1)
    inspire = synergy_states(300, seed=2) * torch.as_tensor(INSPIRE_MASK)
    return {"human": human, "inspire_rh56": inspire}


@pytest.fixture(scope="module")
def masks() -> dict[str, torch.Tensor]:
    return {"human": torch.ones(UDHM_DIM, dtype=torch.bool), "inspire_rh56": torch.as_tensor(INSPIRE_MASK)}
