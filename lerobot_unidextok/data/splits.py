"""Which episodes of a dataset are test episodes: recorded by the conversion, or a deterministic fallback.

A converted dataset keeps its episodes in source order and records its test episodes in
`meta/unidextok_conversion.json` (`test_episodes`); `meta/info.json` keeps LeRobot's `{"train": "0:N"}`.
Datasets edited by LeRobot's `lerobot-edit-dataset` (split, delete_episodes) lose or invalidate that
record (episodes are renumbered, the file is not carried over), and datasets from elsewhere never had
one. `holdout` chooses what happens then:

- `"recorded"`: the recorded test episodes (conversion record still valid for the dataset, or a
  `"test"` range in `meta/info.json` `splits`); a dataset without them is an error saying so.
- `"hash"`: ignore records; the test episodes are the `round(0.2 * N)` episodes with the smallest
  sha1 of `episode_<index:06d>` (deterministic, needs no metadata): `split_order`, the rule the conversion
  applies to its source episode keys.
- `"auto"` (default): recorded when there is a valid record, else `"hash"` with a warning.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.errors import InvalidInputError

logger = logging.getLogger(__name__)

HOLDOUTS = ("auto", "recorded", "hash")
SPLITS = ("train", "test", "all")
HASH_TEST_FRACTION = 0.2


class SplitError(InvalidInputError):
    """The requested split cannot be given for this dataset; the message says why and what to choose."""


@dataclass(frozen=True)
class EpisodeSplit:
    """Test episode indices of a dataset and where they come from."""

    num_episodes: int
    test: tuple[int, ...]
    origin: str  # "conversion record", "meta/info.json splits", "episode hash"

    def episodes(self, split: str | None) -> np.ndarray:
        """Sorted episode indices of `split` ("train", "test", "all" / None)."""
        if split in (None, "all"):
            return np.arange(self.num_episodes)
        test = np.asarray(sorted(self.test), dtype=np.int64)
        if split == "test":
            return test
        if split == "train":
            return np.setdiff1d(np.arange(self.num_episodes), test)
        raise SplitError(f"split must be one of {SPLITS} or None, got {split!r}")


def split_order(keys: list[str], test_fraction: float = HASH_TEST_FRACTION) -> tuple[list[int], list[int]]:
    """(train, test) positions: test = the round(f * N) keys with the smallest sha1 (none when N = 1); each
    list in input order."""
    num_test = round(test_fraction * len(keys)) if len(keys) > 1 else 0
    ranked = sorted(range(len(keys)), key=lambda i: hashlib.sha1(keys[i].encode()).hexdigest())
    test = set(ranked[:num_test])
    return [i for i in range(len(keys)) if i not in test], sorted(test)


def hash_test_episodes(num_episodes: int, fraction: float = HASH_TEST_FRACTION) -> tuple[int, ...]:
    """`split_order` over the keys `episode_<index:06d>`: the test episode indices of a dataset without a record."""
    return tuple(split_order([f"episode_{i:06d}" for i in range(num_episodes)], fraction)[1])


def choose_split(
    where: str | Path, num_episodes: int, recorded: EpisodeSplit | None, why: str, holdout: str = "auto"
) -> EpisodeSplit:
    """The test episodes of a dataset under the `holdout` policy (module docstring), given its own record of
    them (`recorded`, None with `why` there is none usable; `data.meta.UdhmDatasetMeta.split` reads it)."""
    if holdout not in HOLDOUTS:
        raise SplitError(f"holdout must be one of {HOLDOUTS}, got {holdout!r}")
    if holdout == "hash":
        return EpisodeSplit(num_episodes, hash_test_episodes(num_episodes), "episode hash")
    if recorded is not None:
        return recorded
    if holdout == "recorded":
        raise SplitError(
            f"{where} records no test episodes ({why}). Choose: --holdout=hash to hold out a deterministic "
            f"{HASH_TEST_FRACTION:.0%} of its episodes, --split=all to use every episode, or pass a dataset "
            "converted by unidextok-convert"
        )
    logger.warning(
        "%s records no test episodes (%s); holding out %d of %d episodes by episode hash (--holdout=hash). "
        "Pass --holdout=recorded to require a recorded split or --split=all to use every episode.",
        where,
        why,
        len(hash_test_episodes(num_episodes)),
        num_episodes,
    )
    return EpisodeSplit(num_episodes, hash_test_episodes(num_episodes), "episode hash")
