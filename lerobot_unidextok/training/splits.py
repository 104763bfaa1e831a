"""Episode-level splits: checkpoint selection and evaluation on episodes a model never trained on.

Rows of one episode are never split between training and held-out sets: neighbouring frames of one
recording are near copies, so a frame-level split measures memorisation, not generalization.
An episode is identified by (dataset, episode index) (`HandStates.episode_keys`).
"""

from __future__ import annotations

import numpy as np

from lerobot_unidextok.data.rowstore import HandRowStore
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.training.arrays import HandStates


def _keys(data: HandStates) -> np.ndarray:
    if data.episode_index is None:
        raise ValueError(
            "these rows carry no episode index, so they cannot be split by episode; load them with "
            "load_hand_states (converted datasets) or pass episode_index to HandStates"
        )
    return data.episode_keys()


def split_by_episode(data: HandStates, held_out_fraction: float, seed: int = 0) -> tuple[HandStates, HandStates]:
    """(kept, held_out): `round(held_out_fraction * episodes)` whole episodes held out per hand (at least one
    when that hand has two or more episodes, none when it has one). Deterministic in `seed`."""
    if not 0.0 <= held_out_fraction < 1.0:
        raise ValueError(f"held_out_fraction must be in [0, 1), got {held_out_fraction}")
    keys = _keys(data)
    rng = np.random.default_rng(seed)
    held = np.zeros(len(data), dtype=bool)
    for hand in data.hand_names():
        rows = data.hands == hand
        held |= rows & np.isin(keys, _held_out_episodes(np.unique(keys[rows]), held_out_fraction, rng))
    # an episode that holds two hands is held out for both: no frame of a held-out episode trains
    held = np.isin(keys, np.unique(keys[held]))
    return data.select(np.flatnonzero(~held)), data.select(np.flatnonzero(held))


def _held_out_episodes(episodes: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """`round(fraction * episodes)` of one hand's episodes (at least one when it has two or more, none when
    it has one)."""
    if fraction <= 0 or len(episodes) < 2:
        return episodes[:0]
    n = min(len(episodes) - 1, max(1, round(fraction * len(episodes))))
    return rng.choice(episodes, size=n, replace=False)


def split_store_by_episode(
    store: HandRowStore, held_out_fraction: float, max_rows: int, seed: int = 0
) -> tuple[HandRowStore, HandStates]:
    """`split_by_episode` for a memory-mapped store: (view of the kept rows, up to `max_rows` rows of the
    held-out episodes in memory). Memory: 8 bytes per stored row (episode ids, kept-row indices)."""
    if not 0.0 <= held_out_fraction < 1.0:
        raise ValueError(f"held_out_fraction must be in [0, 1), got {held_out_fraction}")
    rng = np.random.default_rng(seed)
    keys = {hand: store.episode_keys(hand) for hand in store.hand_names()}
    held = np.unique(np.concatenate([_held_out_episodes(np.unique(k), held_out_fraction, rng) for k in keys.values()]))
    kept = {hand: np.flatnonzero(~np.isin(k, held)) for hand, k in keys.items()}
    held_view = store.view({hand: np.flatnonzero(np.isin(k, held)) for hand, k in keys.items()})
    rows = held_view.sample_rows(max_rows, seed=seed)
    selection = HandStates(
        rows["states_rad"], rows["hands"], rows["masks"], rows["episode_index"], rows["dataset_index"]
    )
    return store.view(kept), selection


def kfold_by_episode(data: HandStates, folds: int, seed: int = 0) -> list[tuple[HandStates, HandStates]]:
    """`folds` (train, test) pairs: every episode is in exactly one test fold; episodes are shuffled with
    `seed` and dealt round-robin, so fold sizes differ by at most one episode."""
    keys = _keys(data)
    episodes = np.unique(keys)
    if folds < 2 or folds > len(episodes):
        raise InvalidInputError(f"folds must be in [2, {len(episodes)}] (the number of episodes), got {folds}")
    order = np.random.default_rng(seed).permutation(episodes)
    out = []
    for k in range(folds):
        test = np.isin(keys, order[k::folds])
        out.append((data.select(np.flatnonzero(~test)), data.select(np.flatnonzero(test))))
    return out
