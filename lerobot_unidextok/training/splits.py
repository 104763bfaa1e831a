"""Episode-level splits: checkpoint selection and evaluation on episodes a model never trained on.

Rows of one episode are never split between training and held-out sets: neighbouring frames of one
recording are near copies, so a frame-level split measures memorisation, not generalization.
An episode is identified by (dataset, episode index) (`HandStates.episode_keys`).
"""

from __future__ import annotations

import numpy as np

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
    if held_out_fraction > 0:
        for hand in data.hand_names():
            rows = data.hands == hand
            episodes = np.unique(keys[rows])
            if len(episodes) < 2:
                continue
            n = min(len(episodes) - 1, max(1, round(held_out_fraction * len(episodes))))
            held |= rows & np.isin(keys, rng.choice(episodes, size=n, replace=False))
    # an episode that holds two hands is held out for both: no frame of a held-out episode trains
    held = np.isin(keys, np.unique(keys[held]))
    return data.select(np.flatnonzero(~held)), data.select(np.flatnonzero(held))


def kfold_by_episode(data: HandStates, folds: int, seed: int = 0) -> list[tuple[HandStates, HandStates]]:
    """`folds` (train, test) pairs: every episode is in exactly one test fold; episodes are shuffled with
    `seed` and dealt round-robin, so fold sizes differ by at most one episode."""
    keys = _keys(data)
    episodes = np.unique(keys)
    if folds < 2 or folds > len(episodes):
        raise ValueError(f"folds must be in [2, {len(episodes)}] (the number of episodes), got {folds}")
    order = np.random.default_rng(seed).permutation(episodes)
    out = []
    for k in range(folds):
        test = np.isin(keys, order[k::folds])
        out.append((data.select(np.flatnonzero(~test)), data.select(np.flatnonzero(test))))
    return out
