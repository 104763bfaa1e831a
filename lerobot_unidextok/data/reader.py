"""Read a converted UDHM LeRobotDataset (v3.0) into per-hand rows with pyarrow, no per-frame Python.

Each frame of an H-hand dataset gives H rows (frame-major: frame 0 hand 0, frame 0 hand 1, ...).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from lerobot_unidextok.constants import (
    ACTION,
    HAND_TYPE_KEY,
    OBS_STATE,
    UDHM_DIM,
    UDHM_JOINT_NAMES,
    UDHM_MASK_KEY,
)

SPLITS = ("train", "test")


@dataclass
class UdhmFrames:
    """Per-hand rows of a converted dataset (N = frames x hands)."""

    states_rad: np.ndarray  # (N, 22) float32
    hands: np.ndarray  # (N,) str: hand spec name of the row
    masks: np.ndarray  # (N, 22) bool: active UDHM slots
    episode_index: np.ndarray  # (N,) int64
    side: np.ndarray  # (N,) str: "right" | "left"
    frame_index: np.ndarray  # (N,) int64: frame within the episode
    actions_rad: np.ndarray | None = None  # (N, 22) float32 where the dataset has `action`
    fps: float = 0.0
    info: dict = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return int(self.states_rad.shape[0])

    def select(self, rows: np.ndarray) -> UdhmFrames:
        """Rows by boolean mask or index array (e.g. `frames.select(frames.hands == "human")`)."""
        return UdhmFrames(
            states_rad=self.states_rad[rows],
            hands=self.hands[rows],
            masks=self.masks[rows],
            episode_index=self.episode_index[rows],
            side=self.side[rows],
            frame_index=self.frame_index[rows],
            actions_rad=None if self.actions_rad is None else self.actions_rad[rows],
            fps=self.fps,
            info=self.info,
        )


def _resolve_root(root: str | Path | None, repo_id: str | None) -> Path:
    if root is None:
        if repo_id is None:
            raise ValueError("give root= (a converted dataset folder) or repo_id= (looked up in the local caches)")
        from lerobot_unidextok.utils.hf_cache import dataset_root

        root = dataset_root(repo_id)  # $HF_LEROBOT_HOME/<repo_id>, then the HF cache (unidextok-pull)
    root = Path(root)
    if not (root / "meta" / "info.json").is_file():
        raise FileNotFoundError(
            f"{root} is not a LeRobotDataset: meta/info.json missing. Convert a source first with "
            "`unidextok-convert --source=... --input=... --root=...`"
        )
    return root


def read_info(root: str | Path) -> dict:
    """meta/info.json of a dataset folder."""
    return json.loads((Path(root) / "meta" / "info.json").read_text())


def split_episode_range(info: dict, split: str) -> tuple[int, int]:
    """(first, end) episode indices of `split` from info.json `splits` ("a:b")."""
    splits = info.get("splits") or {}
    if split not in splits:
        raise ValueError(
            f"split {split!r} not in meta/info.json splits {sorted(splits)}; use one of them or split=None"
        )
    a, b = (int(x) for x in str(splits[split]).split(":"))
    return a, b


def _block_sides(info: dict) -> list[str]:
    """Side of each 22-block of observation.state from its names ("<side>_<udhm joint>")."""
    ft = info["features"].get(OBS_STATE)
    if ft is None:
        raise ValueError(f"dataset has no {OBS_STATE!r} feature; is it a UDHM conversion?")
    dim = int(ft["shape"][0])
    if dim % UDHM_DIM:
        raise ValueError(f"{OBS_STATE} has {dim} values, not a multiple of {UDHM_DIM}: not a UDHM dataset")
    names = ft.get("names") or []
    if isinstance(names, dict):  # LeRobot also allows {"axes": [...]}
        names = next(iter(names.values()))
    sides = []
    for b in range(dim // UDHM_DIM):
        block = list(names[b * UDHM_DIM : (b + 1) * UDHM_DIM])
        side = block[0].split("_", 1)[0] if block else ""
        if [n.split("_", 1)[-1] for n in block] != list(UDHM_JOINT_NAMES):
            raise ValueError(f"{OBS_STATE} block {b} names are not '<side>_<udhm joint>' in UDHM order: {block[:3]}...")
        sides.append(side)
    return sides


def _fixed_list_to_numpy(col: pa.ChunkedArray, width: int, dtype) -> np.ndarray:
    """(N, width) array from a fixed_size_list / list column without per-row Python."""
    col = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    flat = col.flatten() if not pa.types.is_fixed_size_list(col.type) else col.values
    if pa.types.is_fixed_size_list(col.type) and col.offset:
        flat = flat.slice(col.offset * width, len(col) * width)
    arr = flat.to_numpy(zero_copy_only=False).astype(dtype, copy=False)
    return arr.reshape(len(col), width)


def load_udhm_frames(
    root: str | Path | None = None,
    repo_id: str | None = None,
    split: str | None = None,
    drop_absent: bool = True,
) -> UdhmFrames:
    """Load a converted dataset's hand states as per-hand rows.

    split: "train" | "test" (episode ranges from meta/info.json `splits`) or None for all episodes.
    drop_absent: drop rows whose mask is all False (a hand not present in that frame, zero-filled).
    """
    if split is not None and split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS} or None, got {split!r}")
    root = _resolve_root(root, repo_id)
    info = read_info(root)
    sides = _block_sides(info)
    num_hands = len(sides)
    width = UDHM_DIM * num_hands

    files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not files:
        raise FileNotFoundError(f"no data parquet files under {root / 'data'}")
    columns = [OBS_STATE, UDHM_MASK_KEY, HAND_TYPE_KEY, "episode_index", "frame_index"]
    has_action = ACTION in info["features"]
    if has_action:
        columns.append(ACTION)
    table = pa.concat_tables(pq.read_table(f, columns=columns) for f in files)
    if split is not None:
        a, b = split_episode_range(info, split)
        ep = table.column("episode_index")
        table = table.filter(pc.and_(pc.greater_equal(ep, a), pc.less(ep, b)))

    n = table.num_rows
    states = _fixed_list_to_numpy(table.column(OBS_STATE), width, np.float32).reshape(n * num_hands, UDHM_DIM)
    masks = _fixed_list_to_numpy(table.column(UDHM_MASK_KEY), width, np.bool_).reshape(n * num_hands, UDHM_DIM)
    actions = None
    if has_action:
        actions = _fixed_list_to_numpy(table.column(ACTION), width, np.float32).reshape(n * num_hands, UDHM_DIM)

    # hand_type: split each distinct string once, then gather by dictionary index.
    ht = table.column(HAND_TYPE_KEY).combine_chunks().dictionary_encode()
    per_value = []
    for s in ht.dictionary.to_pylist():
        parts = s.split(",")
        if len(parts) != num_hands:
            raise ValueError(f"hand_type {s!r} names {len(parts)} hands but {OBS_STATE} has {num_hands} blocks")
        per_value.append(parts)
    lut = np.array(per_value, dtype=object).reshape(-1, num_hands) if per_value else np.empty((0, num_hands), object)
    codes = ht.indices.to_numpy(zero_copy_only=False)
    hands = lut[codes].reshape(-1).astype(str) if n else np.empty(0, dtype=str)

    rep = lambda a: np.repeat(a, num_hands)
    frames = UdhmFrames(
        states_rad=states,
        hands=hands,
        masks=masks,
        episode_index=rep(table.column("episode_index").to_numpy()).astype(np.int64),
        side=np.tile(np.array(sides, dtype=str), n),
        frame_index=rep(table.column("frame_index").to_numpy()).astype(np.int64),
        actions_rad=actions,
        fps=float(info.get("fps", 0)),
        info=info,
    )
    if drop_absent:
        present = frames.masks.any(axis=1)
        if not present.all():
            frames = frames.select(present)
    return frames
