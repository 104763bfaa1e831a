"""Per-hand rows of converted datasets on disk, memory-mapped: training data larger than memory.

    store = open_row_store(["out/egodex_udhm", "out/let_udhm"], split="train", folder="cache/train")
    store.hand_names()                      # ["human", "linkerhand_l10", ...]
    rows = store.hands["human"]             # .states_rad (n, 22) float32, .masks (n, 22) bool, .episode_index (n,)
    x = rows.states_rad[[3, 17, 42]]        # reads only the pages of those rows

`build_row_store` streams each dataset with `iter_udhm_frames` (one parquet record batch at a time, the
same rows as `load_udhm_frames`), appends each hand's rows to that hand's files and writes `index.json`
last, into a temp folder renamed into place: memory stays bounded by one record batch, whatever the
dataset size. `HandRowStore` maps the files with `np.memmap`: a training batch reads only the pages of
its rows, and processes training on one machine share those pages through the OS page cache instead
of holding one copy of the data each. Rows of a hand keep dataset order, then row order.

`open_row_store` reuses a store whose fingerprint (datasets' data files by name, size and mtime, their
`meta/info.json` and conversion record, split, holdout) matches, else rebuilds it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import CONVERSION_PATH, INFO_PATH, UDHM_DIM
from lerobot_unidextok.data.reader import data_files, iter_udhm_frames, resolve_root
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.utils.files import recover_folder, replace_folder, temp_sibling

logger = logging.getLogger(__name__)

__all__ = ["STORE_FORMAT", "HandRowStore", "HandRows", "build_row_store", "open_row_store", "store_fingerprint"]

STORE_FORMAT = 2  # 2: per-hand row counts per dataset (episode keys across datasets)
INDEX = "index.json"
# (file suffix, dtype, row shape) of the arrays kept per hand
_ARRAYS = (("states_rad", np.float32, (UDHM_DIM,)), ("masks", np.bool_, (UDHM_DIM,)), ("episode_index", np.int64, ()))


@dataclass
class HandRows:
    """One hand's rows, memory-mapped (read-only)."""

    states_rad: np.ndarray  # (n, 22) float32 radians
    masks: np.ndarray  # (n, 22) bool active UDHM slots
    episode_index: np.ndarray  # (n,) int64 (episode index within its dataset)

    def __len__(self) -> int:
        return int(self.states_rad.shape[0])


class HandRowStore:
    """Memory-mapped per-hand rows written by `build_row_store`; `keep` (hand -> sorted row indices) makes
    a view of some rows of each hand (the training rows when whole episodes are held out for selection)."""

    def __init__(self, folder: str | Path, hands: list[str] | None = None, keep: dict[str, np.ndarray] | None = None):
        self.folder = Path(folder)
        path = self.folder / INDEX
        if not path.is_file():
            raise MissingInputError(f"{self.folder} is not a row store ({INDEX} missing); build it with open_row_store")
        self.index = json.loads(path.read_text())
        if self.index.get("format") != STORE_FORMAT:
            raise ValueError(
                f"{path}: row store format {self.index.get('format')}, expected {STORE_FORMAT}; rebuild it"
            )
        names = sorted(self.index["hands"]) if hands is None else sorted(hands)
        self.keep = {h: np.asarray(v, np.int64) for h, v in (keep or {}).items() if h in names}
        self.hands: dict[str, HandRows] = {}
        for name in names:
            entry = self.index["hands"][name]
            n = int(entry["rows"])
            arrays = {}
            for key, dtype, shape in _ARRAYS:
                file = self.folder / f"{entry['file']}.{key}"
                arrays[key] = (
                    np.memmap(file, dtype=dtype, mode="r", shape=(n, *shape)) if n else np.empty((0, *shape), dtype)
                )
            self.hands[name] = HandRows(**arrays)

    def __len__(self) -> int:
        return sum(self.hand_counts().values())

    def hand_names(self) -> list[str]:
        return sorted(self.hands)

    def hand_counts(self) -> dict[str, int]:
        """Rows per hand (in the view)."""
        return {name: len(self.keep[name]) if name in self.keep else len(rows) for name, rows in self.hands.items()}

    def rows_of(self, hand: str) -> np.ndarray | None:
        """Row indices of `hand` in the view, or None for all of its rows."""
        return self.keep.get(hand)

    def episode_keys(self, hand: str) -> np.ndarray:
        """(n,) int64 episode id of every stored row of `hand` (all rows, not only the view's), unique across
        datasets: dataset position in the high bits, as `training.HandStates.episode_keys`."""
        counts = self.index["hands"][hand]["dataset_rows"]
        dataset = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
        return (dataset << 32) + np.asarray(self.hands[hand].episode_index, dtype=np.int64)

    def without(self, hands: list[str] | str) -> HandRowStore:
        """The same files without some hands (the zero-shot protocol excludes hands from training)."""
        hands = [hands] if isinstance(hands, str) else list(hands)
        return HandRowStore(self.folder, [h for h in self.hands if h not in hands], self.keep)

    def view(self, keep: dict[str, np.ndarray]) -> HandRowStore:
        """The same files restricted to rows `keep[hand]` (hands not in `keep`: all rows)."""
        return HandRowStore(self.folder, list(self.hands), {**self.keep, **keep})

    def sample_rows(self, num_rows: int, seed: int) -> dict[str, np.ndarray]:
        """Up to `num_rows` rows drawn uniformly without replacement over the view's rows, as in-memory arrays
        (`states_rad`, `masks`, `hands`, `episode_index`, `dataset_index`, and `row_index`: position in the
        view's order)."""
        total = len(self)
        pick = (
            np.arange(total)
            if num_rows >= total
            else np.random.default_rng(seed).choice(total, num_rows, replace=False)
        )
        pick = np.sort(pick)
        out = {key: [] for key in ("states_rad", "masks", "hands", "episode_index", "dataset_index")}
        offset, counts = 0, self.hand_counts()
        for name in self.hand_names():
            rows = self.hands[name]
            local = pick[(pick >= offset) & (pick < offset + counts[name])] - offset
            offset += counts[name]
            if name in self.keep:
                local = self.keep[name][local]
            out["states_rad"].append(np.asarray(rows.states_rad[local]))
            out["masks"].append(np.asarray(rows.masks[local]))
            out["episode_index"].append(np.asarray(rows.episode_index[local]))
            out["hands"].append(np.full(len(local), name))
            ends = np.cumsum(self.index["hands"][name]["dataset_rows"])
            out["dataset_index"].append(np.searchsorted(ends, local, side="right").astype(np.int64))
        empty = {"states_rad": (0, UDHM_DIM), "masks": (0, UDHM_DIM), "episode_index": (0,), "hands": (0,),
                 "dataset_index": (0,)}  # fmt: skip
        result = {k: np.concatenate(v) if v else np.empty(empty[k]) for k, v in out.items()}
        result["row_index"] = pick
        return result


def store_fingerprint(roots: list[Path], split: str | None, holdout: str) -> str:
    """sha1 of what the store's rows depend on: each dataset's data files (name, size, mtime), its
    meta/info.json and conversion record, the split and the holdout rule."""
    h = hashlib.sha1(f"format={STORE_FORMAT};split={split};holdout={holdout}".encode())
    for root in roots:
        h.update(str(root.resolve()).encode())
        for name in (INFO_PATH, CONVERSION_PATH):
            path = root / name
            h.update(path.read_bytes() if path.is_file() else b"-")
        for f in data_files(root):
            st = f.stat()
            h.update(f"{f.relative_to(root)}:{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()


def _roots(datasets: list[str | Path]) -> list[Path]:
    if not datasets:
        raise InvalidInputError("no datasets given: pass --datasets='[path/or/repo_id, ...]'")
    roots = []
    for ds in datasets:
        path = Path(ds).expanduser()
        roots.append(resolve_root(path, None) if path.is_dir() else resolve_root(None, str(ds)))
    return roots


def build_row_store(
    datasets: list[str | Path],
    split: str | None,
    folder: str | Path,
    holdout: str = "auto",
    batch_rows: int = 4096,
) -> HandRowStore:
    """Stream the datasets' rows of `split` into a store at `folder` (replaced atomically when it exists)."""
    roots = _roots(datasets)
    folder = Path(folder).expanduser().resolve()
    folder.parent.mkdir(parents=True, exist_ok=True)
    for note in recover_folder(folder):
        logger.warning(note)
    tmp = temp_sibling(folder)
    tmp.mkdir()
    files: dict[str, dict] = {}  # hand -> {"file": stem, "rows": n, "handles": {key: file}}
    try:
        for ordinal, root in enumerate(roots):
            for frames in iter_udhm_frames(root=root, split=split, holdout=holdout, batch_rows=batch_rows):
                bad = ~np.isfinite(frames.states_rad).all(axis=1)
                if bad.any():
                    raise InvalidInputError(
                        f"{root}: {int(bad.sum())} rows with NaN/inf UDHM angles (episodes "
                        f"{np.unique(frames.episode_index[bad])[:10].tolist()}); re-convert or fix the dataset"
                    )
                for name in np.unique(frames.hands):
                    sel = frames.hands == name
                    entry = files.get(name)
                    if entry is None:
                        stem = f"hand{len(files):03d}"
                        handles = {key: open(tmp / f"{stem}.{key}", "wb") for key, _, _ in _ARRAYS}  # noqa: SIM115
                        entry = files[name] = {"file": stem, "rows": 0, "dataset_rows": [0] * len(roots),
                                               "handles": handles}  # fmt: skip
                    for key, dtype, _ in _ARRAYS:
                        np.ascontiguousarray(getattr(frames, key)[sel], dtype=dtype).tofile(entry["handles"][key])
                    entry["rows"] += int(sel.sum())
                    entry["dataset_rows"][ordinal] += int(sel.sum())
        for entry in files.values():
            for handle in entry.pop("handles").values():
                handle.close()
        if not files:
            raise InvalidInputError(f"no {split} rows in {[str(r) for r in roots]}; check the split or the datasets")
        index = {
            "format": STORE_FORMAT,
            "fingerprint": store_fingerprint(roots, split, holdout),
            "datasets": [str(r) for r in roots],
            "split": split,
            "holdout": holdout,
            "hands": files,
        }
        (tmp / INDEX).write_text(json.dumps(index, indent=1))
        replace_folder(tmp, folder)
    except BaseException:
        for entry in files.values():
            for handle in entry.get("handles", {}).values():
                handle.close()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    store = HandRowStore(folder)
    logger.info("row store %s: %d rows of %s (%s split)", folder, len(store), store.hand_counts(), split)
    return store


def open_row_store(
    datasets: list[str | Path], split: str | None, folder: str | Path, holdout: str = "auto"
) -> HandRowStore:
    """The store at `folder` when it holds these datasets' rows of `split` unchanged, else a rebuilt one."""
    folder = Path(folder).expanduser()
    index = folder / INDEX
    if index.is_file():
        try:
            stored = json.loads(index.read_text())
        except json.JSONDecodeError:
            stored = {}
        if stored.get("format") == STORE_FORMAT and stored.get("fingerprint") == store_fingerprint(
            _roots(datasets), split, holdout
        ):
            return HandRowStore(folder)
        logger.info("row store %s is out of date (datasets or split changed): rebuilding", folder)
    return build_row_store(datasets, split, folder, holdout)
