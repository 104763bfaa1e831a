"""Which hands two converted datasets share, by content: the mix's guard against data given twice.

Each hand of each episode (one UDHM block of `observation.state`) gets a print: its frame count and the mean of
each of its 22 joints over each of `SEGMENTS` equal stretches of the episode (radians). Two hands are the same
when their frame counts are equal and every one of those means agrees within `TOLERANCE_RAD`. Per hand, not per
episode, so it finds:

- a `cp -r` copy, and the same folder given twice;
- two conversions of one source, also with other settings that keep the hands' values: `--keep=all` or
  `hands` (the passthrough columns are left out), another `--test_fraction`, `--repo_id` or `--sides` order,
  other file chunking or episode order;
- a conversion of one hand of a two-hand recording (`--source_options` naming the right hand only) next to a
  conversion of both: their right hands are the same;
- a near copy: values that moved by less than the tolerance (1e-6 rad of noise, float64 stored as float32).

Why means with a tolerance and not a hash of rounded values: an episode holds about 900 values (40 frames x 22),
and with any rounding step some of them sit within 1e-6 of a rounding boundary, so a hash of rounded values
changes with noise far below the step almost always. Means over stretches keep the order of the motion (a
reversed or shifted episode differs) and compare in one vectorised step.

Why not the conversion record's source: the record keeps the source's name, options and each episode's key
relative to `--input`, but not which input (two recordings of one robot have the same keys). Why not a hash of
the parquet files: their bytes change with the columns kept and the chunking. Two real recordings never hold
a hand whose means agree within 1e-4 rad on all 22 joints in each stretch; a hand-made dataset could only by
copying one. A hand that never moves (one pose held, a side the episode lacks) says nothing about where it
came from: it gets no print, so two datasets that both hold a hand at rest are not called copies.

The cost is one read of three columns (`observation.state`, `episode_index`, `frame_index`) per input, file by
file (memory bounded by one data file and 176 numbers per hand).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import OBS_STATE, UDHM_DIM
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.reader import data_files

SEGMENTS = 8  # stretches of an episode whose joint means make a hand's print
TOLERANCE_RAD = 1e-4  # two prints are the same hand when every mean agrees within this


@dataclass
class HandPrints:
    """One row per moving hand of each episode of a converted dataset."""

    episodes: np.ndarray  # (n,) int64: the episode index
    sides: list[str]  # (n,) the block's side
    lengths: np.ndarray  # (n,) int64: the episode's frames
    means_rad: np.ndarray  # (n, SEGMENTS * 22) float64: each joint's mean over each stretch

    @property
    def moving_sides(self) -> dict[int, set[str]]:
        """{episode: the sides of its hands that move}."""
        out: dict[int, set[str]] = {}
        for e, side in zip(self.episodes.tolist(), self.sides, strict=True):
            out.setdefault(e, set()).add(side)
        return out


def hand_prints(root: str | Path) -> HandPrints:
    """The print of each moving hand of each episode of the converted dataset at `root` (module docstring)."""
    import pyarrow.parquet as pq  # only when mixing

    root = Path(root)
    meta = UdhmDatasetMeta(root)
    names = meta.names(OBS_STATE)
    blocks = find_udhm_blocks(names)
    columns = np.concatenate([np.arange(b.start, b.stop) for b in blocks]) if blocks else np.arange(0)
    lengths = meta.episode_lengths or {}
    sums: dict[int, np.ndarray] = {}  # (SEGMENTS, blocks, 22) float64
    counts: dict[int, np.ndarray] = {}  # (SEGMENTS,)
    first: dict[int, np.ndarray] = {}  # (blocks, 22): the episode's first frame seen
    moving: dict[int, np.ndarray] = {}  # (blocks,) bool
    for path in data_files(root):
        table = pq.read_table(path, columns=[OBS_STATE, "episode_index", "frame_index"])
        state = table.column(OBS_STATE).combine_chunks()
        values = state.values.to_numpy(zero_copy_only=False).reshape(len(state), len(names))
        hands = values[:, columns].astype(np.float64).reshape(len(state), len(blocks), UDHM_DIM)  # (N, B, 22)
        episodes = table.column("episode_index").to_numpy()
        frame = table.column("frame_index").to_numpy()
        cuts = [0, *(np.flatnonzero(np.diff(episodes)) + 1).tolist(), len(episodes)]
        for start, stop in zip(cuts[:-1], cuts[1:], strict=True):  # runs of one episode
            if stop <= start:
                continue
            e, run = int(episodes[start]), hands[start:stop]
            length = max(int(lengths.get(e, 0)), int(frame[start:stop].max()) + 1)
            segment = np.minimum(frame[start:stop] * SEGMENTS // length, SEGMENTS - 1)
            np.add.at(sums.setdefault(e, np.zeros((SEGMENTS, len(blocks), UDHM_DIM))), segment, run)
            np.add.at(counts.setdefault(e, np.zeros(SEGMENTS)), segment, 1)
            base = first.setdefault(e, run[0].copy())
            moved = (np.abs(run - base) > TOLERANCE_RAD).any(axis=(0, 2))  # (B,)
            moving[e] = moving.get(e, np.zeros(len(blocks), bool)) | moved
    rows_e, rows_side, rows_len, rows_means = [], [], [], []
    for e in sorted(sums):
        means = sums[e] / np.maximum(counts[e], 1)[:, None, None]  # (S, B, 22)
        for k, block in enumerate(blocks):
            if moving[e][k]:
                rows_e.append(e)
                rows_side.append(block.side)
                rows_len.append(int(counts[e].sum()))
                rows_means.append(means[:, k, :].ravel())
    return HandPrints(np.array(rows_e, np.int64), rows_side, np.array(rows_len, np.int64),
                      np.array(rows_means, np.float64).reshape(len(rows_e), SEGMENTS * UDHM_DIM))  # fmt: skip


def same_hands(a: HandPrints, b: HandPrints) -> list[tuple[int, int, str, str]]:
    """Every pair of the same hand in `a` and `b`: (episode in a, episode in b, side in a, side in b), sorted.
    Candidates are found by frame count and a sorted scalar (the mean of the print, which two prints within the
    tolerance share within it too), then compared on every mean."""
    out = []
    key_a = a.means_rad.mean(axis=1)
    for length in np.intersect1d(a.lengths, b.lengths):
        ia = np.flatnonzero(a.lengths == length)
        ia = ia[np.argsort(key_a[ia], kind="stable")]
        sorted_keys = key_a[ia]
        for j in np.flatnonzero(b.lengths == length):
            key = b.means_rad[j].mean()
            lo = np.searchsorted(sorted_keys, key - TOLERANCE_RAD, side="left")
            hi = np.searchsorted(sorted_keys, key + TOLERANCE_RAD, side="right")
            near = ia[lo:hi]
            same = near[np.abs(a.means_rad[near] - b.means_rad[j]).max(axis=1) <= TOLERANCE_RAD]
            out += [(int(a.episodes[i]), int(b.episodes[j]), a.sides[i], b.sides[j]) for i in same]
    return sorted(out)


@dataclass
class Repeat:
    """Two inputs that hold the same episodes, or the same hands of episodes."""

    first: str  # the inputs, as given
    second: str
    same_folder: bool  # one folder given twice (under one spelling or two)
    shared: list[tuple[int, int]]  # (episode in first, the same episode in second), by content
    first_episodes: int  # episodes of the first input (with a moving hand)
    partial_sides: list[str]  # the sides shared when some episodes share only some of their hands; [] = whole

    def describe(self) -> str:
        if self.same_folder:
            return f"inputs {self.first} and {self.second} are the same dataset (one folder)"
        pairs = ", ".join(f"{self.first}#{a} = {self.second}#{b}" for a, b in self.shared[:2])
        counted = f"{len(self.shared)} of {self.first_episodes} by content, e.g. {pairs}"
        if self.partial_sides:
            return (
                f"inputs {self.first} and {self.second} hold the same {'/'.join(self.partial_sides)} hand of "
                f"episodes ({counted}; the other hands differ: one recording converted once with all its hands "
                "and once with only some, so those hands would be in the mix twice)"
            )
        return (
            f"inputs {self.first} and {self.second} hold the same episodes ({counted}: a copy, or two conversions of "
            "one source)"
        )


def find_repeat(inputs: list[tuple[str, Path]]) -> Repeat | None:
    """The first pair of `inputs` ((name as given, dataset folder), in order) that hold the same hands: the same
    folder, or hands with the same print (module docstring); None when every hand is given once."""
    seen_roots: dict[Path, int] = {}
    for k, (name, root) in enumerate(inputs):
        same = seen_roots.setdefault(Path(root).resolve(), k)
        if same != k:
            return Repeat(inputs[same][0], name, True, [], 0, [])
    prints: list[tuple[str, HandPrints]] = []
    for name, root in inputs:
        mine = hand_prints(root)
        for other, theirs in prints:
            matches = same_hands(theirs, mine)
            if not matches:
                continue
            matched: dict[tuple[int, int], set[str]] = {}
            for a, b, side_a, side_b in matches:
                matched.setdefault((a, b), set()).update({side_a, side_b})
            theirs_sides, mine_sides = theirs.moving_sides, mine.moving_sides
            partial = sorted({s for (a, b), sides in matched.items()
                              if sides != theirs_sides[a] | mine_sides[b] for s in sides})  # fmt: skip
            return Repeat(other, name, False, sorted(matched), len(theirs_sides), partial)
        prints.append((name, mine))
    return None


__all__ = ["SEGMENTS", "TOLERANCE_RAD", "HandPrints", "Repeat", "find_repeat", "hand_prints", "same_hands"]
