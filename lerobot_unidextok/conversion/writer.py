"""Fast LeRobotDataset v3.0 writer: whole episodes in, the same files as LeRobot's writer out.

Writes what LeRobot 0.6.1's `add_frame`/`save_episode`/`finalize` writes (same parquet schema incl. the
`huggingface` features metadata, one row group per episode, data/episodes file roll-over at
`data_files_size_in_mb`, episodes metadata columns, tasks.parquet, info.json, stats.json with q01..q99),
but from whole-episode arrays with pyarrow: no per-frame dicts, no `datasets.map`. LeRobot's own helpers
are reused for info/tasks/stats serialisation. Differences (by design): the parquet `huggingface` metadata
carries no random fingerprint, and dataset stats are aggregated once over all episodes instead of pairwise
per episode (equal up to float rounding).

Features copied from a source dataset (images, other observations, videos) are taken as they are: their
Arrow columns go into the data files unchanged (cast to the schema type only), and each source video
file is copied once, byte for byte, into `videos/<key>/chunk-XXX/file-YYY.mp4`, with every episode
pointing at its own `[from_timestamp, to_timestamp)` segment of it (no decoding, no re-encoding).
"""

from __future__ import annotations

import logging
import shutil
from copy import deepcopy
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from lerobot_unidextok.conversion.stats import episode_stats

logger = logging.getLogger(__name__)

DEFAULT_KEYS = ("timestamp", "frame_index", "episode_index", "index", "task_index")
METADATA_BUFFER_EPISODES = 256  # episodes metadata rows per parquet write
STATS_FOLD_EPISODES = 1024  # fold per-episode stats into one running aggregate this often (bounded memory)


def _lerobot():
    """Lazy import of the LeRobot pieces the writer reuses (layer rule: lerobot.datasets lazily)."""
    from lerobot.datasets import (
        compute_stats,
        dataset_metadata,
        feature_utils,
        io_utils,
        utils,
    )
    from lerobot.utils.constants import DEFAULT_FEATURES

    return (
        compute_stats,
        dataset_metadata,
        feature_utils,
        io_utils,
        utils,
        DEFAULT_FEATURES,
    )


NUMERIC_STATS_EXCLUDED = ("image", "video", "string")  # dtypes whose stats come from the source, not computed


def _copy_file(src: Path, dst: Path) -> None:
    """A byte copy of a source video file (never decoded or re-encoded)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)


class UdhmDatasetWriter:
    """Write a LeRobotDataset v3.0 episode by episode from whole arrays.

    Usage: `w = UdhmDatasetWriter(root, repo_id, fps, features)`; `w.add_episode({...}, task)` per
    episode; `w.finalize(splits=...)`. `root` must not exist (like `LeRobotDataset.create`).
    Features the writer computes from arrays are 1-D numeric or string; `copied` features (any dtype and
    shape, e.g. images) arrive as Arrow columns, `video` features as source file segments.
    """

    def __init__(
        self,
        root: str | Path,
        repo_id: str,
        fps: int,
        features: dict[str, dict],
        robot_type: str | None = None,
        data_files_size_in_mb: int | None = None,
        chunks_size: int | None = None,
    ):
        (
            compute_stats,
            dataset_metadata,
            feature_utils,
            io_utils,
            utils,
            default_features,
        ) = _lerobot()
        if int(fps) != fps or fps <= 0:
            raise ValueError(f"fps must be a positive integer (LeRobot stores int fps), got {fps!r}")
        for key in features:
            if key in default_features:
                raise ValueError(f"feature {key!r} is written by the writer itself; remove it from features")
            if "/" in key:
                raise ValueError(f"feature key {key!r} contains '/', which LeRobot forbids; rename it")
        self.root = Path(root)
        self.repo_id = repo_id
        self.root.mkdir(parents=True, exist_ok=False)
        self.features = {**deepcopy(features), **default_features}
        for ft in self.features.values():
            ft["shape"] = tuple(ft["shape"])
        self.video_keys = [k for k, ft in features.items() if ft["dtype"] == "video"]
        self.info = feature_utils.create_empty_dataset_info(
            dataset_metadata.CODEBASE_VERSION,
            int(fps),
            self.features,
            use_videos=bool(self.video_keys),
            robot_type=robot_type,
            chunks_size=chunks_size,
            data_files_size_in_mb=data_files_size_in_mb,
        )
        io_utils.write_info(self.info, self.root)
        self._io = io_utils
        self._utils = utils
        self._aggregate_stats = compute_stats.aggregate_stats
        self.schema: pa.Schema = feature_utils.get_hf_features_from_features(self.features).arrow_schema
        self._video_files: dict[tuple[str, str], tuple[int, int]] = {}  # (key, source path) -> (chunk, file)
        self._video_next: dict[str, tuple[int, int]] = {k: (0, 0) for k in self.video_keys}
        self.fps = int(fps)
        self.tasks: dict[str, int] = {}
        self.num_episodes = 0
        self.num_frames = 0
        self._episode_stats: list[dict] = []
        # data file state
        self._data_writer: pq.ParquetWriter | None = None
        self._data_chunk, self._data_file = 0, 0
        self._data_path: Path | None = None
        self._file_start_frame = 0
        # episodes metadata state
        self._meta_rows: list[dict] = []
        self._meta_writer: pq.ParquetWriter | None = None
        self._meta_chunk, self._meta_file = 0, 0
        self._meta_episodes_in_file = 0
        self._finalized = False

    # -- data ------------------------------------------------------------------------------------
    def _column(self, key: str, values: np.ndarray, num: int) -> pa.Array:
        ft = self.features[key]
        field_type = self.schema.field(key).type
        if ft["dtype"] == "string":
            values = np.asarray(values)
            if values.ndim == 0 or values.size == 1:
                return pa.array([str(values.reshape(-1)[0])] * num, type=pa.string())
            return pa.array(values.reshape(num).tolist(), type=pa.string())
        dtype = np.dtype(ft["dtype"])
        values = np.asarray(values)
        expected = (num,) if ft["shape"] == (1,) else (num, *ft["shape"])
        if values.shape != expected and not (ft["shape"] == (1,) and values.shape == (num, 1)):
            raise ValueError(f"feature {key!r}: expected an array of shape {expected}, got {values.shape}")
        if values.dtype != dtype:
            raise ValueError(f"feature {key!r}: expected dtype {dtype}, got {values.dtype}; cast before writing")
        if ft["shape"] == (1,):
            return pa.array(values.reshape(num), type=field_type)
        flat = pa.array(np.ascontiguousarray(values).reshape(-1), type=field_type.value_type)
        return pa.FixedSizeListArray.from_arrays(flat, type=field_type)

    def _next_data_file(self) -> None:
        if self._data_writer is not None:
            self._data_writer.close()
            self._data_writer = None
            self._data_chunk, self._data_file = self._utils.update_chunk_file_indices(
                self._data_chunk, self._data_file, self.info.chunks_size
            )
        self._file_start_frame = self.num_frames

    def add_episode(
        self,
        frames: dict[str, np.ndarray],
        task: str,
        copied: dict[str, pa.Array] | None = None,
        videos: dict | None = None,
        copied_stats: dict[str, dict] | None = None,
    ) -> int:
        """Append one episode. `frames`: the features this writer builds, as (T, *shape) arrays of their
        dtype (strings may be one value for the whole episode); `copied`: the other features as Arrow
        columns taken unchanged; `videos`: {key: VideoSegment} of each video feature; `copied_stats`: the
        source's per-episode stats of copied features the writer cannot compute (images, videos).
        Returns the episode index."""
        if self._finalized:
            raise RuntimeError("writer already finalized")
        copied, videos, copied_stats = copied or {}, videos or {}, copied_stats or {}
        num = self._check_episode(frames, task, copied, videos)
        ep_index = self.num_episodes
        if task not in self.tasks:
            self.tasks[task] = len(self.tasks)
        table, ep_arrays = self._episode_table(frames, copied, num, ep_index, self.tasks[task])
        self._write_data(table, num)
        stats = self._add_stats(ep_arrays, copied_stats, num)
        row = {
            "episode_index": ep_index,
            "tasks": [task],
            "length": num,
            "data/chunk_index": self._data_chunk,
            "data/file_index": self._data_file,
            "dataset_from_index": self.num_frames,
            "dataset_to_index": self.num_frames + num,
        }
        for key in self.video_keys:
            row.update(self._add_video(key, videos[key]))
        for key, st in stats.items():
            for name, value in st.items():
                row[f"stats/{key}/{name}"] = value.tolist()
        self._add_meta_row(row)
        self.num_episodes += 1
        self.num_frames += num
        return ep_index

    def _check_episode(self, frames: dict, task: str, copied: dict, videos: dict) -> int:
        """The episode's length, after checking it brings exactly the features and one length for all."""
        given = set(frames) | set(copied) | set(videos)
        missing = [k for k in self.features if k not in DEFAULT_KEYS and k not in given]
        extra = [k for k in given if k not in self.features or k in DEFAULT_KEYS]
        extra += [k for k in videos if k in self.features and k not in self.video_keys]
        if missing or extra:
            raise ValueError(f"episode features mismatch: missing {missing}, unexpected {extra}")
        if not isinstance(task, str):
            raise TypeError(f"task must be a str, got {type(task).__name__}")
        lengths = {k: np.asarray(v).shape[0] for k, v in frames.items() if np.asarray(v).ndim > 0}
        lengths.update({k: len(v) for k, v in copied.items()})
        num = next(iter(lengths.values()), 0)
        if num == 0 or any(n != num for n in lengths.values()):
            raise ValueError(f"episode arrays must share a non-zero length, got {lengths}")
        return num

    def _episode_table(
        self, frames: dict, copied: dict, num: int, ep_index: int, task_index: int
    ) -> tuple[pa.Table, dict[str, np.ndarray]]:
        """(the episode's rows in the schema, {key: values} of the features whose stats the writer computes)."""
        frame_index = np.arange(num, dtype=np.int64)
        default = {
            "timestamp": frame_index / self.fps,  # float64, as LeRobot's list of Python floats
            "frame_index": frame_index,
            "episode_index": np.full(num, ep_index, dtype=np.int64),
            "index": np.arange(self.num_frames, self.num_frames + num, dtype=np.int64),
            "task_index": np.full(num, task_index, dtype=np.int64),
        }
        columns = []
        ep_arrays = {}
        for key in self.schema.names:  # video features have no data column
            if key in DEFAULT_KEYS:
                values = default[key]
                columns.append(
                    pa.array(
                        values.astype(np.dtype(self.features[key]["dtype"])),
                        type=self.schema.field(key).type,
                    )
                )
            elif key in copied:
                column = self._copied_column(key, copied[key])
                columns.append(column)
                ft = self.features[key]
                if ft["dtype"] not in NUMERIC_STATS_EXCLUDED and len(ft["shape"]) == 1:  # stats as LeRobot computes
                    flat = (
                        column.flatten()
                        if pa.types.is_list(column.type) or pa.types.is_fixed_size_list(column.type)
                        else column
                    )
                    values = flat.to_numpy(zero_copy_only=False)
                    ep_arrays[key] = values.reshape(num, -1) if ft["shape"] != (1,) else values.reshape(num)
                continue
            else:
                values = frames[key]
                columns.append(self._column(key, values, num))
            ep_arrays[key] = values
        return pa.Table.from_arrays(columns, schema=self.schema), ep_arrays

    def _copied_column(self, key: str, column: pa.Array | pa.ChunkedArray) -> pa.Array:
        """A source's Arrow column cast to the schema type of feature `key` (a clear error when it cannot be)."""
        column = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
        try:
            return column.cast(self.schema.field(key).type)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
            raise ValueError(
                f"copied feature {key!r}: column type {column.type} does not fit the feature "
                f"{self.features[key]['dtype']} {self.features[key]['shape']} ({exc})"
            ) from exc

    def _write_data(self, table: pa.Table, num: int) -> None:
        """Append the rows to the current data file, rolling over as LeRobot does: size + estimate >= limit."""
        if self._data_writer is not None:
            size_mb = self._data_path.stat().st_size / 1024**2
            in_file = self.num_frames - self._file_start_frame
            per_frame = size_mb / in_file if in_file > 0 else 0
            if size_mb + per_frame * num >= self.info.data_files_size_in_mb:
                self._next_data_file()
        if self._data_writer is None:
            self._data_path = self.root / self.info.data_path.format(
                chunk_index=self._data_chunk, file_index=self._data_file
            )
            self._data_path.parent.mkdir(parents=True, exist_ok=True)
            self._data_writer = pq.ParquetWriter(
                self._data_path,
                schema=self.schema,
                compression="snappy",
                use_dictionary=True,
            )
            self._file_start_frame = self.num_frames
        self._data_writer.write_table(table)

    def _add_stats(self, ep_arrays: dict, copied_stats: dict[str, dict], num: int) -> dict[str, dict]:
        """The episode's stats (computed, plus the source's for images / videos), kept for stats.json."""
        stats = episode_stats(
            {k: (v if np.asarray(v).ndim > 0 else np.full(num, v)) for k, v in ep_arrays.items()},
            self.features,
        )
        for key, st in copied_stats.items():  # images / videos: the source's own per-episode stats
            if key in self.features and key not in stats:
                stats[key] = {name: np.asarray(value) for name, value in st.items()}
        self._episode_stats.append(stats)
        if len(self._episode_stats) >= STATS_FOLD_EPISODES:  # count-weighted, so folding in blocks is exact
            self._episode_stats = [self._aggregate_stats(self._episode_stats)]
        return stats

    # -- videos ----------------------------------------------------------------------------------
    def _add_video(self, key: str, segment) -> dict:
        """Copy the segment's source file once (byte for byte) and point the episode at its time range."""
        src = Path(segment.path)
        if (key, str(src)) not in self._video_files:
            if not src.is_file():
                raise ValueError(f"video {key!r}: source file {src} is missing")
            chunk, file = self._video_next[key]
            _copy_file(src, self.root / self.info.video_path.format(video_key=key, chunk_index=chunk, file_index=file))
            self._video_files[(key, str(src))] = (chunk, file)
            self._video_next[key] = self._utils.update_chunk_file_indices(chunk, file, self.info.chunks_size)
        chunk, file = self._video_files[(key, str(src))]
        return {
            f"videos/{key}/chunk_index": chunk,
            f"videos/{key}/file_index": file,
            f"videos/{key}/from_timestamp": float(segment.from_s),
            f"videos/{key}/to_timestamp": float(segment.to_s),
        }

    # -- episodes metadata -----------------------------------------------------------------------
    def _add_meta_row(self, row: dict) -> None:
        if self._meta_writer is not None and self._meta_episodes_in_file > 0:
            path = self._meta_writer.where
            size_mb = Path(path).stat().st_size / 1024**2 if Path(path).exists() else 0.0
            if size_mb + size_mb / self._meta_episodes_in_file >= self.info.data_files_size_in_mb:
                self._flush_meta()
                self._meta_writer.close()
                self._meta_writer = None
                self._meta_chunk, self._meta_file = self._utils.update_chunk_file_indices(
                    self._meta_chunk, self._meta_file, self.info.chunks_size
                )
                self._meta_episodes_in_file = 0
        row["meta/episodes/chunk_index"] = self._meta_chunk
        row["meta/episodes/file_index"] = self._meta_file
        self._meta_rows.append(row)
        if len(self._meta_rows) >= METADATA_BUFFER_EPISODES:
            self._flush_meta()

    def _flush_meta(self) -> None:
        if not self._meta_rows:
            return
        combined = {k: [r[k] for r in self._meta_rows] for k in self._meta_rows[0]}
        table = pa.Table.from_pydict(combined)
        if self._meta_writer is None:
            path = self.root / f"meta/episodes/chunk-{self._meta_chunk:03d}/file-{self._meta_file:03d}.parquet"
            path.parent.mkdir(parents=True, exist_ok=True)
            self._meta_writer = pq.ParquetWriter(path, schema=table.schema, compression="snappy", use_dictionary=True)
        else:
            table = table.select(self._meta_writer.schema.names).cast(self._meta_writer.schema)
        self._meta_writer.write_table(table)
        self._meta_episodes_in_file += len(self._meta_rows)
        self._meta_rows = []

    # -- finalize --------------------------------------------------------------------------------
    def finalize(self, splits: dict[str, str] | None = None) -> None:
        """Close files and write tasks, info.json (with `splits`) and stats.json. Idempotent."""
        if self._finalized:
            return
        if self.num_episodes == 0:
            raise ValueError("no episodes were written; a LeRobotDataset needs at least one episode")
        import pandas as pd

        if self._data_writer is not None:
            self._data_writer.close()
            self._data_writer = None
        self._flush_meta()
        if self._meta_writer is not None:
            self._meta_writer.close()
            self._meta_writer = None
        tasks = pd.DataFrame(
            {"task_index": list(self.tasks.values())},
            index=pd.Index(list(self.tasks), name="task"),
        )
        self._io.write_tasks(tasks, self.root)
        self.info.total_episodes = self.num_episodes
        self.info.total_frames = self.num_frames
        self.info.total_tasks = len(self.tasks)
        self.info.splits = splits if splits is not None else {"train": f"0:{self.num_episodes}"}
        self._io.write_info(self.info, self.root)
        self._io.write_stats(self._aggregate_stats(self._episode_stats), self.root)
        self._finalized = True

    def abort(self) -> None:
        """Close open files without writing metadata (the caller removes the folder)."""
        for w in (self._data_writer, self._meta_writer):
            if w is not None:
                try:
                    w.close()
                except Exception as exc:  # noqa: BLE001  best effort on the error path
                    logger.debug("closing a parquet writer on abort failed: %s", exc)
        self._data_writer = self._meta_writer = None
