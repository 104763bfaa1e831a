"""In-memory per-hand rows for training and evaluation (the batches come from `coverage.MixtureSampler`)."""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from dataclasses import dataclass

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.errors import InvalidInputError


@dataclass
class HandStates:
    """Rows of one hand state each: (N, 22) radians, (N,) hand names, (N, 22) active-DoF masks, and where
    known the episode of each row and the dataset it came from (position in the loaded list)."""

    states_rad: np.ndarray
    hands: np.ndarray
    masks: np.ndarray
    episode_index: np.ndarray | None = None
    dataset_index: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.states_rad = np.asarray(self.states_rad, dtype=np.float32)
        self.hands = np.asarray(self.hands).astype(str)
        self.masks = np.asarray(self.masks, dtype=bool)
        n = len(self.states_rad)
        if self.states_rad.ndim != 2 or self.states_rad.shape[1] != UDHM_DIM:
            raise ValueError(f"states_rad must be (N, {UDHM_DIM}), got {self.states_rad.shape}")
        if self.hands.shape != (n,):
            raise ValueError(f"hands must be (N,) = ({n},), got {self.hands.shape}")
        if self.masks.shape != self.states_rad.shape:
            raise ValueError(f"masks must be {self.states_rad.shape}, got {self.masks.shape}")
        if not np.isfinite(self.states_rad).all():
            raise ValueError("states_rad contains NaN/inf; drop or fill those frames first")
        for name in ("episode_index", "dataset_index"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=np.int64)
                if value.shape != (n,):
                    raise ValueError(f"{name} must be (N,) = ({n},), got {value.shape}")
                setattr(self, name, value)

    def __len__(self) -> int:
        return len(self.states_rad)

    def episode_keys(self) -> np.ndarray:
        """(N,) int64 id of each row's episode, unique across datasets (dataset index in the high bits)."""
        if self.episode_index is None:
            raise ValueError("these rows carry no episode index")
        ds = np.zeros_like(self.episode_index) if self.dataset_index is None else self.dataset_index
        return (ds << 32) + self.episode_index

    def select(self, rows: np.ndarray) -> "HandStates":
        ep = None if self.episode_index is None else self.episode_index[rows]
        ds = None if self.dataset_index is None else self.dataset_index[rows]
        return HandStates(self.states_rad[rows], self.hands[rows], self.masks[rows], ep, ds)

    def only(self, hands: list[str] | str) -> "HandStates":
        hands = [hands] if isinstance(hands, str) else hands
        return self.select(np.flatnonzero(np.isin(self.hands, hands)))

    def without(self, hands: list[str] | str) -> "HandStates":
        hands = [hands] if isinstance(hands, str) else hands
        return self.select(np.flatnonzero(~np.isin(self.hands, hands)))

    def hand_names(self) -> list[str]:
        return sorted(set(self.hands.tolist()))

    @staticmethod
    def concat(parts: list["HandStates"]) -> "HandStates":
        if not parts:
            raise ValueError("nothing to concatenate: no hand-state arrays given")
        eps = ds = None
        if all(p.episode_index is not None for p in parts):
            eps = np.concatenate([p.episode_index for p in parts])
        if all(p.dataset_index is not None for p in parts):
            ds = np.concatenate([p.dataset_index for p in parts])
        return HandStates(
            np.concatenate([p.states_rad for p in parts]),
            np.concatenate([p.hands for p in parts]),
            np.concatenate([p.masks for p in parts]),
            eps,
            ds,
        )

    @staticmethod
    def from_frames(frames, dataset_index: int = 0) -> "HandStates":
        """From `lerobot_unidextok.data.UdhmFrames`; `dataset_index` tells datasets apart in `episode_keys`."""
        n = len(frames.states_rad)
        return HandStates(frames.states_rad, frames.hands, frames.masks, frames.episode_index,
                          np.full(n, dataset_index, dtype=np.int64))  # fmt: skip


def load_hand_states(datasets: list[str], split: str | None, holdout: str = "auto") -> HandStates:
    """Per-hand rows of one split of several converted datasets (local roots or repo ids); `holdout` says
    what a dataset without a recorded test split gives (`lerobot_unidextok.data.splits`)."""
    from pathlib import Path

    from lerobot_unidextok.data import load_udhm_frames

    if not datasets:
        raise InvalidInputError("no datasets given: pass --datasets='[path/or/repo_id, ...]'")
    parts = []
    for i, ds in enumerate(datasets):
        if Path(ds).expanduser().is_dir():
            frames = load_udhm_frames(root=Path(ds).expanduser(), split=split, holdout=holdout)
        else:
            frames = load_udhm_frames(repo_id=ds, split=split, holdout=holdout)
        parts.append(HandStates.from_frames(frames, dataset_index=i))
    return HandStates.concat(parts)


def subsample_episodes(data: HandStates, fraction: float, seed: int = 0) -> HandStates:
    """Keep the first `fraction` of each hand's frames, per episode where known (few-shot)."""
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    if fraction == 1.0:
        return data
    rng = np.random.default_rng(seed)
    keep = []
    for hand in data.hand_names():
        rows = np.flatnonzero(data.hands == hand)
        if data.episode_index is not None:
            keys = data.episode_keys()
            eps = np.unique(keys[rows])
            rng.shuffle(eps)
            taken = []
            target = max(1, int(round(fraction * len(rows))))
            for ep in eps:  # whole episodes first, then a slice of the last one
                ep_rows = rows[keys[rows] == ep]
                taken.append(ep_rows[: target - sum(map(len, taken))])
                if sum(map(len, taken)) >= target:
                    break
            keep.append(np.concatenate(taken))
        else:
            keep.append(rng.choice(rows, size=max(1, int(round(fraction * len(rows)))), replace=False))
    return data.select(np.sort(np.concatenate(keep)))
