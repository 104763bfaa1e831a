"""Hand-state rows for training tests: smooth gesture trajectories (samples.motion),
human (all 22 DoFs) and an Inspire RH56 hand (its active-DoF mask from the hand registry)."""

import numpy as np
import pytest

from lerobot_unidextok.samples.motion import gesture_track
from lerobot_unidextok.training import HandStates


def gesture_rows(hand: str, episodes: int, frames: int, seed: int) -> HandStates:
    from lerobot_unidextok import hands

    mask = np.ones(22, bool) if hand == "human" else hands.get(hand).mask().astype(bool)
    rng = np.random.default_rng(seed)
    parts = []
    for ep in range(episodes):
        q = gesture_track(rng, frames, 30.0).angles_rad.astype(np.float32) * mask  # padded slots are 0
        parts.append(HandStates(q, np.full(frames, hand), np.tile(mask, (frames, 1)), np.full(frames, ep)))
    return HandStates.concat(parts)


@pytest.fixture(scope="session")
def mixture() -> tuple[HandStates, HandStates]:
    """(train, held-out) rows of human + inspire_rh56, held-out from different episodes/seeds."""
    train = HandStates.concat([gesture_rows("human", 8, 150, 0), gesture_rows("inspire_rh56", 8, 150, 1)])
    test = HandStates.concat([gesture_rows("human", 2, 150, 10), gesture_rows("inspire_rh56", 2, 150, 11)])
    return train, test
