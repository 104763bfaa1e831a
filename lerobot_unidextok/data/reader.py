"""Read a converted UDHM LeRobotDataset (v3.0) into per-hand rows with pyarrow, no per-frame Python.

Each frame of an H-hand dataset gives H rows (frame-major: frame 0 hand 0, frame 0 hand 1, ...).
The UDHM blocks are found by name (`blocks.find_udhm_blocks`) inside a state that may also hold
the robot's other columns (arms, grippers); the train/test split comes from `data.splits`.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from lerobot_unidextok.blocks import UdhmBlock, feature_names, find_udhm_blocks
from lerobot_unidextok.constants import ACTION, DATA_GLOB, HAND_TYPE_KEY, INFO_PATH, OBS_STATE, UDHM_DIM, UDHM_MASK_KEY
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.splits import HOLDOUTS, SPLITS, EpisodeSplit, SplitError
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.utils.hf_cache import dataset_root


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


def dataset_folder(name: str | Path) -> Path:
    """A dataset given as a folder or a repo id (found in the local caches): its folder, with meta/info.json."""
    path = Path(name).expanduser()
    return resolve_root(path, None) if path.exists() else resolve_root(None, str(name))


def resolve_root(root: str | Path | None, repo_id: str | None) -> Path:
    """The dataset folder: `root`, else `repo_id` found in the local caches; it must hold meta/info.json."""
    if root is None:
        if repo_id is None:
            raise ValueError("give root= (a converted dataset folder) or repo_id= (looked up in the local caches)")

        root = dataset_root(repo_id)  # $HF_LEROBOT_HOME/<repo_id>, then the HF cache (unidextok-pull)
    root = Path(root)
    if not (root / INFO_PATH).is_file():
        raise MissingInputError(
            f"{root} is not a LeRobotDataset: meta/info.json missing. Convert a source first with "
            "`unidextok-convert --source=... --input=... --root=...`"
        )
    return root


def split_episode_range(info: dict, split: str) -> tuple[int, int]:
    """(first, end) episode indices of `split` from info.json `splits` ("a:b")."""
    splits = info.get("splits") or {}
    if split not in splits:
        raise InvalidInputError(
            f"split {split!r} not in meta/info.json splits {sorted(splits)}; use one of them or split=None"
        )
    a, b = (int(x) for x in str(splits[split]).split(":"))
    return a, b


def udhm_blocks(info: dict, key: str = OBS_STATE) -> list[UdhmBlock]:
    """The UDHM blocks of a vector feature, found by name; a clear error when there are none."""
    ft = info["features"].get(key)
    if ft is None:
        raise InvalidInputError(f"dataset has no {key!r} feature; is it a UDHM conversion?")
    names = feature_names(ft)
    dim = int(ft["shape"][0])
    if len(names) != dim:
        raise InvalidInputError(f"{key} has {dim} values but {len(names)} names; UDHM blocks are found by name")
    blocks = find_udhm_blocks(names)
    if not blocks:
        raise InvalidInputError(
            f"{key} has no UDHM block (22 names '<side>_<udhm joint>', e.g. right_thumb_cmc_flex); "
            "convert the dataset with unidextok-convert first"
        )
    return blocks


def _fixed_list_to_numpy(col: pa.ChunkedArray, width: int, dtype) -> np.ndarray:
    """(N, width) array from a fixed_size_list / list column without per-row Python."""
    col = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    flat = col.flatten() if not pa.types.is_fixed_size_list(col.type) else col.values
    if pa.types.is_fixed_size_list(col.type) and col.offset:
        flat = flat.slice(col.offset * width, len(col) * width)
    arr = flat.to_numpy(zero_copy_only=False).astype(dtype, copy=False)
    return arr.reshape(len(col), width)


def _columns_of_blocks(column: pa.ChunkedArray, width: int, blocks: list[UdhmBlock], dtype) -> np.ndarray:
    """(N, 22 * H) of the blocks' columns of a (N, width) list column."""
    values = _fixed_list_to_numpy(column, width, dtype)
    index = np.concatenate([np.arange(b.start, b.stop) for b in blocks])
    return values if len(index) == width else values[:, index]


@dataclass
class _Layout:
    """What turns a table of a dataset's rows into per-hand rows: its UDHM blocks and columns."""

    blocks: list[UdhmBlock]
    state_width: int
    action_blocks: list[UdhmBlock] | None
    action_width: int
    columns: list[str]

    @property
    def sides(self) -> list[str]:
        return [b.side for b in self.blocks]


def _layout(info: dict) -> _Layout:
    blocks = udhm_blocks(info)
    sides = [b.side for b in blocks]
    columns = [OBS_STATE, UDHM_MASK_KEY, HAND_TYPE_KEY, "episode_index", "frame_index"]
    action_blocks, action_width = None, 0
    if ACTION in info["features"]:
        try:
            action_blocks = udhm_blocks(info, ACTION)
        except ValueError:
            action_blocks = None  # an action without UDHM blocks (copied unchanged from the source)
        if action_blocks is not None:
            if [b.side for b in action_blocks] != sides:
                raise InvalidInputError(
                    f"{ACTION} UDHM blocks {[b.side for b in action_blocks]} differ from {OBS_STATE} {sides}"
                )
            columns.append(ACTION)
            action_width = int(info["features"][ACTION]["shape"][0])
    return _Layout(blocks, int(info["features"][OBS_STATE]["shape"][0]), action_blocks, action_width, columns)


def data_files(root: Path) -> list[Path]:
    """The dataset's data parquet files in order; FileNotFoundError when there are none."""
    files = sorted(root.glob(DATA_GLOB))
    if not files:
        raise MissingInputError(f"no data parquet files under {root / 'data'}")
    return files


def _split_episodes(meta: UdhmDatasetMeta, split: str | None, holdout: str) -> np.ndarray | None:
    """Episode indices of `split` (None: every episode); a clear error for an empty split."""
    if split is not None and split not in SPLITS:
        raise InvalidInputError(f"split must be one of {SPLITS} or None, got {split!r}")
    if holdout not in HOLDOUTS:
        raise InvalidInputError(f"holdout must be one of {HOLDOUTS}, got {holdout!r}")
    if split in (None, "all"):
        return None
    episode_split: EpisodeSplit = meta.split(holdout)
    wanted = episode_split.episodes(split)
    if not len(wanted):
        raise SplitError(
            f"{meta.root} has no {split} episodes ({episode_split.origin}: {len(episode_split.test)} test of "
            f"{episode_split.num_episodes}): score every episode instead (`--split=all` on the command line, "
            "split='all' in Python)"
        )
    return wanted


def _frames_of_table(table: pa.Table, layout: _Layout, info: dict, drop_absent: bool) -> UdhmFrames:
    """Per-hand rows of a table of dataset rows (frame-major), no per-frame Python."""
    num_hands = len(layout.blocks)
    n = table.num_rows
    width = UDHM_DIM * num_hands
    states = _columns_of_blocks(table.column(OBS_STATE), layout.state_width, layout.blocks, np.float32).reshape(
        n * num_hands, UDHM_DIM
    )
    masks = _fixed_list_to_numpy(table.column(UDHM_MASK_KEY), width, np.bool_).reshape(n * num_hands, UDHM_DIM)
    actions = None
    if layout.action_blocks is not None:
        actions = _columns_of_blocks(table.column(ACTION), layout.action_width, layout.action_blocks, np.float32)
        actions = actions.reshape(n * num_hands, UDHM_DIM)

    # hand_type: split each distinct string once, then gather by dictionary index.
    ht = table.column(HAND_TYPE_KEY).combine_chunks().dictionary_encode()
    per_value = []
    for s in ht.dictionary.to_pylist():
        parts = s.split(",")
        if len(parts) != num_hands:
            raise InvalidInputError(f"hand_type {s!r} names {len(parts)} hands but {OBS_STATE} has {num_hands} blocks")
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
        side=np.tile(np.array(layout.sides, dtype=str), n),
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


def _keep_episodes(table: pa.Table, wanted: np.ndarray | None) -> pa.Table:
    if wanted is None:
        return table
    return table.filter(pc.is_in(table.column("episode_index"), value_set=pa.array(wanted, pa.int64())))


def _open(root, repo_id, split: str | None, holdout: str):
    """(info, layout, data files, wanted episodes) of a converted dataset, with the split arguments checked."""
    if split is not None and split not in SPLITS:
        raise InvalidInputError(f"split must be one of {SPLITS} or None, got {split!r}")
    if holdout not in HOLDOUTS:
        raise InvalidInputError(f"holdout must be one of {HOLDOUTS}, got {holdout!r}")
    meta = UdhmDatasetMeta(resolve_root(root, repo_id))
    return meta.info, _layout(meta.info), data_files(meta.root), _split_episodes(meta, split, holdout)


def load_udhm_frames(
    root: str | Path | None = None,
    repo_id: str | None = None,
    split: str | None = None,
    drop_absent: bool = True,
    holdout: str = "auto",
) -> UdhmFrames:
    """Load a converted dataset's hand states as per-hand rows.

    split: "train" | "test" | "all" (or None): episodes from the recorded split, see `data.splits`.
    holdout: "auto" | "recorded" | "hash": what to do for datasets without a recorded test split
        (e.g. after `lerobot-edit-dataset`), see `data.splits`.
    drop_absent: drop rows whose mask is all False (a hand not present in that frame, zero-filled).
    Everything is read into memory; `iter_udhm_frames` reads the same rows in bounded pieces.
    """
    info, layout, files, wanted = _open(root, repo_id, split, holdout)
    table = pa.concat_tables(pq.read_table(f, columns=layout.columns) for f in files)
    return _frames_of_table(_keep_episodes(table, wanted), layout, info, drop_absent)


def iter_udhm_frames(
    root: str | Path | None = None,
    repo_id: str | None = None,
    split: str | None = None,
    drop_absent: bool = True,
    holdout: str = "auto",
    batch_rows: int = 65536,
) -> Iterator[UdhmFrames]:
    """The rows of `load_udhm_frames`, in the same order, in pieces of at most `batch_rows` dataset frames
    (parquet record batches), so memory is bounded by one piece whatever the dataset size."""
    info, layout, files, wanted = _open(root, repo_id, split, holdout)
    for path in files:
        for batch in pq.ParquetFile(path).iter_batches(batch_size=batch_rows, columns=layout.columns):
            table = _keep_episodes(pa.Table.from_batches([batch]), wanted)
            if table.num_rows:
                yield _frames_of_table(table, layout, info, drop_absent)
