"""Which episodes two converted datasets share, by content: the mix's guard against data given twice.

An episode's fingerprint is a 128-bit BLAKE2b digest of its hands: the float32 values of its UDHM blocks of
`observation.state`, frame after frame, the blocks in side order (left before right). It is the same for
the same episodes however they were stored, so it finds:

- a `cp -r` copy, and the same folder given twice;
- two conversions of one source, also with other settings that keep the hands' values: `--keep=all` or
  `hands` (the passthrough columns are left out), another `--test_fraction`, `--repo_id` or `--sides` order,
  other file chunking or episode order.

Why not the conversion record's source: the record keeps the source's name, options and each episode's key
relative to `--input`, but not which input (two recordings of one robot have the same keys), so it cannot
tell a second conversion of one recording from a conversion of another. Why not a hash of the parquet
files: their bytes change with the columns kept and the chunking. Two real recordings never hold an episode
with the same float32 values in every frame; a hand-made dataset could only by copying one. An episode whose
hands never move (one pose held, or no hand at all) says nothing about where it came from: it gets no
fingerprint, so two datasets that both hold a hand at rest are not called copies.

The cost is one read of two columns (`observation.state`, `episode_index`) per input, file by file (memory
bounded by one data file), and hashing the hands' bytes: about what the mix then spends reading the input.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.reader import data_files

DIGEST_BYTES = 16


def episode_fingerprints(root: str | Path) -> dict[bytes, int]:
    """The fingerprint of each episode of the converted dataset at `root` -> its episode index (module
    docstring). Episodes with the same hands in every frame (a dataset that repeats one) keep the first; an
    episode whose hands never move has none."""
    import pyarrow.parquet as pq  # only when mixing

    root = Path(root)
    names = UdhmDatasetMeta(root).names(OBS_STATE)
    blocks = sorted(find_udhm_blocks(names), key=lambda b: b.side)
    columns = np.concatenate([np.arange(b.start, b.stop) for b in blocks]) if blocks else np.arange(0)
    hashers: dict[int, hashlib.blake2b] = {}
    first_frame: dict[int, np.ndarray] = {}
    moving: set[int] = set()
    for path in data_files(root):
        table = pq.read_table(path, columns=[OBS_STATE, "episode_index"])
        state = table.column(OBS_STATE).combine_chunks()
        values = state.values.to_numpy(zero_copy_only=False).reshape(len(state), len(names))
        hands = np.ascontiguousarray(values[:, columns], dtype=np.float32)  # (N, 22 * blocks)
        episodes = table.column("episode_index").to_numpy()
        cuts = [0, *(np.flatnonzero(np.diff(episodes)) + 1).tolist(), len(episodes)]
        for start, stop in zip(cuts[:-1], cuts[1:], strict=True):  # runs of one episode, in frame order
            if stop > start:
                episode, frames = int(episodes[start]), hands[start:stop]
                hashers.setdefault(episode, hashlib.blake2b(digest_size=DIGEST_BYTES)).update(frames)
                if (frames != first_frame.setdefault(episode, frames[0].copy())).any():
                    moving.add(episode)
    out: dict[bytes, int] = {}
    for episode, hasher in sorted(hashers.items()):
        if episode in moving:
            out.setdefault(hasher.digest(), episode)
    return out


@dataclass
class Repeat:
    """Two inputs that hold the same episodes."""

    first: str  # the inputs, as given
    second: str
    same_folder: bool  # one folder given twice (under one spelling or two)
    shared: list[tuple[int, int]]  # (episode in first, the same episode in second), by content
    first_episodes: int  # episodes of the first input

    def describe(self) -> str:
        if self.same_folder:
            return f"inputs {self.first} and {self.second} are the same dataset (one folder)"
        pairs = ", ".join(f"{self.first}#{a} = {self.second}#{b}" for a, b in self.shared[:2])
        return (
            f"inputs {self.first} and {self.second} hold the same episodes ({len(self.shared)} of "
            f"{self.first_episodes} by content, e.g. {pairs}: a copy, or two conversions of one source)"
        )


def find_repeat(inputs: list[tuple[str, Path]]) -> Repeat | None:
    """The first pair of `inputs` ((name as given, dataset folder), in order) that hold the same episodes:
    the same folder, or episodes with the same fingerprint; None when every episode is given once."""
    seen_roots: dict[Path, int] = {}
    for k, (name, root) in enumerate(inputs):
        same = seen_roots.setdefault(Path(root).resolve(), k)
        if same != k:
            return Repeat(inputs[same][0], name, True, [], 0)
    prints: list[tuple[str, dict[bytes, int]]] = []
    for name, root in inputs:
        mine = episode_fingerprints(root)
        for other, theirs in prints:
            shared = sorted((e, mine[d]) for d, e in theirs.items() if d in mine)
            if shared:
                return Repeat(other, name, False, shared, len(theirs))
        prints.append((name, mine))
    return None


__all__ = ["Repeat", "episode_fingerprints", "find_repeat"]
