"""Training batches from in-memory rows (`HandStates`) or a memory-mapped row store (`data.HandRowStore`).

Both follow one mixing rule: each row of a batch is hand `h` with probability `share_h` (relative
`hand_weights`, `default_weight` for hands not listed), then one of that hand's rows, uniformly. So a row
of hand `h` has probability `share_h / n_h` per draw, whatever the source:

- `InMemoryBatches`: `HandMixSampler` (one categorical draw over all N rows with those probabilities);
  the batches are the ones the loop drew before streaming existed, number for number.
- `StreamingBatches`: per-hand counts from one multinomial draw, then uniform row indices inside each
  hand's memory-mapped arrays: memory O(hands), not O(rows); only the drawn rows' pages are read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_unidextok.data.rowstore import HandRowStore
from lerobot_unidextok.training.arrays import HandMixSampler, HandStates

__all__ = ["Batch", "InMemoryBatches", "StreamingBatches", "hand_shares", "make_batches"]


@dataclass
class Batch:
    states_rad: np.ndarray  # (B, 22) float32
    masks: np.ndarray  # (B, 22) bool
    hands: np.ndarray  # (B,) int64: index into the batch source's `hand_names`


def hand_shares(hand_names: list[str], weights: dict[str, float], default_weight: float) -> np.ndarray:
    """(H,) share of each hand in a batch: relative weights, normalised."""
    w = np.array([weights.get(n, default_weight) for n in hand_names], dtype=np.float64)
    if w.sum() <= 0:
        raise ValueError(f"all hand weights are zero for hands {hand_names}; give at least one a weight > 0")
    return w / w.sum()


class InMemoryBatches:
    """Batches of in-memory rows through `HandMixSampler`."""

    def __init__(self, data: HandStates, weights: dict[str, float], default_weight: float, seed: int):
        self.sampler = HandMixSampler(data.hands, weights, default_weight, seed=seed)
        self.hand_names = data.hand_names()
        self.hand_share = self.sampler.hand_share
        self._states, self._masks = data.states_rad, data.masks
        self._hand_of_row = np.searchsorted(np.array(self.hand_names), data.hands)  # (N,)

    def sample(self, batch_size: int) -> Batch:
        rows = self.sampler.sample(batch_size)
        return Batch(self._states[rows], self._masks[rows], self._hand_of_row[rows].astype(np.int64))


class StreamingBatches:
    """Batches drawn from a memory-mapped row store: hand counts by share, then rows uniformly per hand."""

    def __init__(self, store: HandRowStore, weights: dict[str, float], default_weight: float, seed: int):
        self.store = store
        self.hand_names = store.hand_names()
        share = hand_shares(self.hand_names, weights, default_weight)
        self.hand_share = dict(zip(self.hand_names, share.tolist(), strict=True))
        self._share = share
        self._rows = [store.hands[h] for h in self.hand_names]
        self.rng = np.random.default_rng(seed)

    def sample(self, batch_size: int) -> Batch:
        counts = self.rng.multinomial(batch_size, self._share)  # (H,)
        x = np.empty((batch_size, self._rows[0].states_rad.shape[1]), np.float32)
        m = np.empty(x.shape, bool)
        h = np.repeat(np.arange(len(counts)), counts)  # (B,) grouped by hand; order does not change the loss
        at = 0
        for k, c in enumerate(counts):
            if c == 0:
                continue
            rows = np.sort(self.rng.integers(len(self._rows[k]), size=c))  # sorted: sequential page reads
            x[at : at + c] = self._rows[k].states_rad[rows]
            m[at : at + c] = self._rows[k].masks[rows]
            at += c
        return Batch(x, m, h.astype(np.int64))


def make_batches(
    data: HandStates | HandRowStore, weights: dict[str, float], default_weight: float, seed: int
) -> InMemoryBatches | StreamingBatches:
    if isinstance(data, HandRowStore):
        return StreamingBatches(data, weights, default_weight, seed)
    return InMemoryBatches(data, weights, default_weight, seed)
