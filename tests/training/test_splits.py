"""Episode splits: no frame of a held-out episode is ever in the training rows."""

import numpy as np
import pytest

from lerobot_unidextok.training import HandStates
from lerobot_unidextok.training.splits import kfold_by_episode, split_by_episode


def _rows() -> HandStates:
    """Two datasets that both number their episodes 0..; dataset 1 has two hands per frame."""
    rng = np.random.default_rng(0)
    parts = []
    for ds, (episodes, hands) in enumerate([(6, ["human"]), (5, ["inspire_rh56", "inspire_rh56"])]):
        for ep in range(episodes):
            n = 10 + ep
            for h in hands:
                parts.append(HandStates(rng.normal(size=(n, 22)), np.full(n, h), np.ones((n, 22), bool),
                                        np.full(n, ep), np.full(n, ds)))  # fmt: skip
    return HandStates.concat(parts)


def _episodes(data: HandStates) -> set[tuple[int, int]]:
    return set(zip(data.dataset_index.tolist(), data.episode_index.tolist(), strict=True))


def test_split_by_episode_keeps_episodes_whole():
    data = _rows()
    kept, held = split_by_episode(data, 0.3, seed=0)
    assert len(kept) + len(held) == len(data)
    assert not _episodes(kept) & _episodes(held)
    # (dataset 0, episode 3) and (dataset 1, episode 3) are different episodes
    assert len(_episodes(held)) == 2 + 2  # round(0.3 * 6) + round(0.3 * 5) episodes
    # every frame of a held-out episode is held out (both hands of the two-hand dataset)
    for ds, ep in _episodes(held):
        rows = (data.dataset_index == ds) & (data.episode_index == ep)
        assert ((held.dataset_index == ds) & (held.episode_index == ep)).sum() == rows.sum()
    # deterministic in the seed, and 0 holds nothing out
    assert _episodes(split_by_episode(data, 0.3, seed=0)[1]) == _episodes(held)
    assert len(split_by_episode(data, 0.0)[1]) == 0


def test_kfold_tests_every_episode_once_and_never_trains_on_it():
    data = _rows()
    folds = kfold_by_episode(data, 4, seed=1)
    tested = [_episodes(test) for _, test in folds]
    assert set().union(*tested) == _episodes(data)
    assert sum(len(t) for t in tested) == len(_episodes(data))  # each episode in exactly one fold
    for train, test in folds:
        assert not _episodes(train) & _episodes(test)
        assert len(train) + len(test) == len(data)
    with pytest.raises(ValueError, match="folds must be in"):
        kfold_by_episode(data, 12)


def test_rows_without_episodes_cannot_be_split_by_episode():
    data = HandStates(np.zeros((4, 22)), np.full(4, "human"), np.ones((4, 22), bool))
    with pytest.raises(ValueError, match="no episode index"):
        split_by_episode(data, 0.5)
