"""Read LeRobot datasets (v2.1 and v3.0) straight from their parquet and meta files.

Shared by the `dexora`, `linkerhand` and `lerobot` readers. lerobot 0.6 refuses v2.1 datasets, so both
layouts are read with pyarrow only, following LeRobot's own layout code (huggingface/lerobot
`src/lerobot/datasets/io_utils.py`, `dataset_metadata.py` for v3.0; `scripts/convert_dataset_v21_to_v30.py`
`legacy_load_*` for v2.1): v2.1 one `episode_%06d.parquet` (and one mp4 per video key) per episode, v3.0
many episodes per `file-%03d.parquet` / mp4 located through `meta/episodes/*.parquet`.

Besides the hand columns, an episode read here carries what the converted dataset keeps of the robot:
the other features' Arrow columns unchanged, the video segments and the source's per-episode stats of
image/video features (which cannot be recomputed without decoding).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from lerobot_unidextok.blocks import flatten_names
from lerobot_unidextok.constants import EPISODES_META_GLOB, INFO_PATH
from lerobot_unidextok.conversion.episode import VideoSegment
from lerobot_unidextok.errors import SourceFormatError

logger = logging.getLogger(__name__)

SUPPORTED_VERSIONS = ("v2.0", "v2.1", "v3.0")
DEFAULT_KEYS = ("timestamp", "frame_index", "episode_index", "index", "task_index")  # rebuilt by the writer
VISUAL_DTYPES = ("image", "video")


class LeRobotFormatError(SourceFormatError):
    """A LeRobot dataset file is missing, unreadable or lacks a field; the message names both."""


@dataclass(frozen=True)
class LeRobotEpisodeRef:
    """One episode of a LeRobot dataset folder (picklable)."""

    root: str
    episode_index: int
    absent_sides: tuple[str, ...] = ()  # hands whose columns are 0 throughout the dataset (never recorded)

    def __str__(self) -> str:
        return f"{self.root}#episode_{self.episode_index:06d}"


# ---------------------------------------------------------------------------------------------
# meta
# ---------------------------------------------------------------------------------------------


def find_dataset_roots(input_path: str | Path) -> list[Path]:
    """`input_path` itself if it holds `meta/info.json`, else its sub-folders that do (sorted)."""
    path = Path(input_path)
    if not path.exists():
        raise FileNotFoundError(f"input path {path} does not exist")
    if (path / INFO_PATH).is_file():
        return [path]
    roots = sorted(p.parent.parent for p in path.glob(f"*/{INFO_PATH}"))
    if not roots:
        raise LeRobotFormatError(
            f"{path} is not a LeRobot dataset: no meta/info.json in it or in its sub-folders; "
            "point --input at the dataset root (the folder containing meta/ and data/)"
        )
    return roots


def load_info(root: str | Path) -> dict:
    """`meta/info.json`, checked for the fields the readers use."""
    path = Path(root) / INFO_PATH
    try:
        info = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise LeRobotFormatError(f"{path}: missing; a LeRobot dataset needs meta/info.json") from exc
    except json.JSONDecodeError as exc:
        raise LeRobotFormatError(f"{path}: not valid JSON ({exc})") from exc
    for key in ("codebase_version", "fps", "features", "data_path"):
        if key not in info:
            raise LeRobotFormatError(f"{path}: missing field {key!r}")
    if info["codebase_version"] not in SUPPORTED_VERSIONS:
        raise LeRobotFormatError(
            f"{path}: codebase_version {info['codebase_version']!r} is not supported; expected one of "
            f"{SUPPORTED_VERSIONS}"
        )
    return info


def feature_names(info: dict, key: str, root: str | Path, notes: list[str] | None = None) -> list[str]:
    """Flat names of a vector feature, checked against its declared shape. When the two disagree (seen:
    `observation.state` shape [30] with 28 names) the data decide: rows as wide as the names keep the names,
    and the disagreement is one line in `notes`; otherwise a LeRobotFormatError says what to fix."""
    where = f"{Path(root) / 'meta' / 'info.json'} features[{key!r}]"
    if key not in info["features"]:
        raise LeRobotFormatError(f"{where}: missing; available features: {sorted(info['features'])}")
    feature = info["features"][key]
    if feature.get("names") is None:
        raise LeRobotFormatError(f"{where}: has no 'names'; name the hand columns explicitly")
    try:
        names = flatten_names(feature["names"])
    except ValueError as exc:
        raise LeRobotFormatError(f"{where}: {exc}") from None
    size = int(np.prod(feature.get("shape", [len(names)])))
    if len(names) != size:
        width = data_width(Path(root), info, key)
        if width != len(names):
            raise LeRobotFormatError(
                f"{where}: {len(names)} names for shape {feature.get('shape')}, and the data rows are {width} wide: "
                "which columns the names belong to cannot be told; fix the names in meta/info.json"
            )
        if notes is not None:
            notes.append(
                f"{where}: shape {feature.get('shape')} disagrees with its {len(names)} names; the data rows are "
                f"{width} wide, so the names are used"
            )
    return names


def data_width(root: Path, info: dict, key: str) -> int | None:
    """How wide the vector column `key` is in the dataset's first data file (None when it cannot be read)."""
    import pyarrow.parquet as pq

    files = sorted(root.glob("data/**/*.parquet"))
    if not files:
        return None
    try:
        column = pq.ParquetFile(files[0]).read_row_group(0, columns=[key]).column(0)
    except Exception:  # noqa: BLE001 - an unreadable file is reported where the episode is read
        return None
    first = column[0].as_py() if len(column) else None
    return len(first) if isinstance(first, list) else None


def _read_jsonl(path: Path) -> list[dict]:
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError as exc:
        raise LeRobotFormatError(f"{path}: missing") from exc
    rows = []
    for i, line in enumerate(lines):
        if line.strip():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise LeRobotFormatError(f"{path}: line {i + 1} is not valid JSON ({exc})") from exc
    return rows


def list_episodes(root: str | Path) -> list[LeRobotEpisodeRef]:
    """Every episode of one dataset folder, by episode index (episode metadata that disagrees with
    `meta/info.json`'s counts is said once: the episodes that exist are converted)."""
    root = Path(root)
    info = load_info(root)
    if info["codebase_version"] == "v3.0":
        table = _episodes_table_v30(root)
        indices = sorted(int(i) for i in table["episode_index"])
        lengths = table.get("length", [])
    else:
        rows = _episodes_jsonl(str(root))
        indices = sorted(rows)
        lengths = [r.get("length") for r in rows.values()]
    note = count_note(info, len(indices), lengths)
    if note:
        logger.warning("%s: %s", root, note)
    return [LeRobotEpisodeRef(str(root), i) for i in indices]


def count_note(info: dict, num_episodes: int, lengths: list) -> str | None:
    """What `meta/info.json`'s `total_episodes` / `total_frames` claim that the episode metadata does not
    hold, or None."""
    said = []
    if "total_episodes" in info and int(info["total_episodes"]) != num_episodes:
        said.append(f"total_episodes is {info['total_episodes']}, the episode metadata lists {num_episodes}")
    if "total_frames" in info and lengths and all(n is not None for n in lengths):
        if int(info["total_frames"]) != sum(int(n) for n in lengths):
            said.append(f"total_frames is {info['total_frames']}, the episodes' lengths add up to {sum(lengths)}")
    if not said:
        return None
    return "meta/info.json disagrees with the episode metadata (" + "; ".join(said) + "): the episodes that exist are read"


def _episodes_jsonl(root_str: str) -> dict[int, dict]:
    """v2.1 `meta/episodes.jsonl` rows by episode index, cached per file state (workers read many episodes)."""
    path = Path(root_str) / "meta" / "episodes.jsonl"
    stat = path.stat() if path.is_file() else None
    return _episodes_jsonl_cached(str(path), (stat.st_mtime_ns, stat.st_size) if stat else None)


@lru_cache(maxsize=8)
def _episodes_jsonl_cached(path_str: str, stamp: tuple | None) -> dict[int, dict]:
    path = Path(path_str)
    out = {}
    for row in _read_jsonl(path):
        if "episode_index" not in row:
            raise LeRobotFormatError(f"{path}: a row lacks 'episode_index'")
        out[int(row["episode_index"])] = row
    return out


def list_all_episodes(input_path: str | Path) -> list[LeRobotEpisodeRef]:
    """Episodes of every LeRobot dataset found under `input_path`, dataset by dataset."""
    return [ref for root in find_dataset_roots(input_path) for ref in list_episodes(root)]


def robot_type_of(refs: list) -> str | None:
    """The `robot_type` of the LeRobot datasets the episode refs come from (distinct values, sorted,
    joined with ","); None when none records one."""
    roots = sorted({r.root for r in refs if isinstance(r, LeRobotEpisodeRef)})
    types = sorted({str(t) for t in (load_info(root).get("robot_type") for root in roots) if t})
    return ",".join(types) or None


def _episodes_table_v30(root: Path) -> dict[str, list]:
    """All rows of `meta/episodes/*.parquet`, cached per folder and file state (workers read many episodes)."""
    files = sorted(root.glob(EPISODES_META_GLOB))
    stamp = tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    return _episodes_table_cached(str(root), stamp)


_EPISODE_COLUMNS = ("episode_index", "tasks", "length", "data/chunk_index", "data/file_index")


def _wanted_episode_column(name: str, visual: tuple[str, ...]) -> bool:
    """Episode metadata columns read: the basics, video segments and the stats of image/video features only."""
    if name in _EPISODE_COLUMNS or name.startswith("videos/"):
        return True
    return name.startswith("stats/") and name.split("/")[1] in visual


@lru_cache(maxsize=8)
def _episodes_table_cached(root_str: str, stamp: tuple) -> dict[str, list]:
    import pyarrow.parquet as pq

    root = Path(root_str)
    files = [Path(f) for f, _, _ in stamp]
    if not files:
        raise LeRobotFormatError(f"{root / 'meta' / 'episodes'}: no chunk-*/file-*.parquet episode metadata")
    info = load_info(root)
    visual = tuple(k for k, ft in info["features"].items() if ft.get("dtype") in VISUAL_DTYPES)
    columns: dict[str, list] = {}
    for f in files:
        try:
            present = pq.read_schema(f).names
            table = pq.read_table(f, columns=[c for c in present if _wanted_episode_column(c, visual)]).to_pydict()
        except Exception as exc:  # noqa: BLE001 - pyarrow raises several types for corrupt files
            raise LeRobotFormatError(f"{f}: unreadable parquet ({exc})") from exc
        for key, values in table.items():
            columns.setdefault(key, []).extend(values)
    for key in ("episode_index", "data/chunk_index", "data/file_index"):
        if key not in columns:
            raise LeRobotFormatError(f"{files[0]}: missing column {key!r}")
    return columns


# ---------------------------------------------------------------------------------------------
# episode data
# ---------------------------------------------------------------------------------------------


@dataclass
class EpisodeColumns:
    """The vector columns, copied columns, videos and task of one episode."""

    source_file: str
    fps: float
    columns: dict[str, np.ndarray]  # feature key -> (T, D) in the stored dtype (float32 stays float32)
    task: str
    info: dict
    copied: dict = field(default_factory=dict)  # feature key -> (T,) pyarrow array, unchanged
    videos: dict[str, VideoSegment] = field(default_factory=dict)
    stats: dict[str, dict] = field(default_factory=dict)  # source per-episode stats of image/video features
    timestamp_note: str | None = None  # `timestamp_note` of the source timestamps (None: they step by 1/fps)
    notes: list[str] = field(default_factory=list)  # episode metadata that disagrees with the data (`length_note`)


def other_features(info: dict, used: set[str]) -> tuple[dict[str, dict], dict[str, dict]]:
    """(copied, videos): the features of a dataset besides `used` ones and LeRobot's index columns."""
    copied, videos = {}, {}
    for key, ft in info["features"].items():
        if key in used or key in DEFAULT_KEYS:
            continue
        (videos if ft.get("dtype") == "video" else copied)[key] = ft
    return copied, videos


def read_episode(
    ref: LeRobotEpisodeRef, keys: list[str], copy_keys: tuple[str, ...] = (), video_keys: tuple[str, ...] = ()
) -> EpisodeColumns:
    """Read the vector features `keys` of one episode as (T, D) arrays, frames in `frame_index` order;
    `copy_keys` as unchanged Arrow columns and `video_keys` as segments of the source video files."""
    import pyarrow.parquet as pq

    root = Path(ref.root)
    info = load_info(root)
    version = info["codebase_version"]
    meta_row: dict = {}
    if version == "v3.0":
        table = _episodes_table_v30(root)
        row = table["episode_index"].index(ref.episode_index)
        meta_row = {k: v[row] for k, v in table.items()}
        chunk, file = int(meta_row["data/chunk_index"]), int(meta_row["data/file_index"])
        path = root / info["data_path"].format(chunk_index=chunk, file_index=file)
        tasks = meta_row.get("tasks")
    else:
        chunk = ref.episode_index // int(info.get("chunks_size", 1000))
        path = root / info["data_path"].format(episode_chunk=chunk, episode_index=ref.episode_index)
        tasks = None
        meta_row = {"length": _episodes_jsonl(str(root)).get(ref.episode_index, {}).get("length")}
    if not path.is_file():
        raise LeRobotFormatError(f"{path}: data file of episode {ref.episode_index} is missing")
    vector_keys = list(keys)
    keys = [*vector_keys, *(k for k in copy_keys if k not in vector_keys)]
    wanted = [*keys, "episode_index", "frame_index", "task_index", "timestamp"]
    try:
        pf = pq.ParquetFile(path)
        schema_names = pf.schema_arrow.names
        missing = [k for k in [*keys, "episode_index"] if k not in schema_names]
        if missing:
            raise LeRobotFormatError(f"{path}: missing column(s) {missing}; columns present: {schema_names}")
        columns_read = [k for k in wanted if k in schema_names]
        if version == "v3.0":  # files hold many episodes: skip row groups of other episodes
            table = pq.read_table(path, columns=columns_read, filters=[("episode_index", "=", ref.episode_index)])
        else:
            table = pf.read(columns=columns_read)
    except LeRobotFormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - truncated parquet raises ArrowInvalid/OSError
        raise LeRobotFormatError(f"{path}: unreadable parquet ({exc})") from exc

    data = {k: table[k] for k in table.column_names}
    episode = data["episode_index"].to_numpy()
    rows = np.flatnonzero(episode == ref.episode_index)
    if rows.size == 0:
        raise LeRobotFormatError(f"{path}: no rows with episode_index == {ref.episode_index}")
    if "frame_index" in data:
        rows = rows[np.argsort(data["frame_index"].to_numpy()[rows], kind="stable")]
    import pyarrow as pa

    take = pa.array(rows)
    copied = {key: _combined(data[key]).take(take) for key in copy_keys}
    columns = {key: _vector_column(data[key], rows, path, key, ref.episode_index) for key in vector_keys}
    task = _task_text(root, info, tasks, data, rows)
    fps = float(info["fps"])
    note = timestamp_note(data["timestamp"].to_numpy()[rows], fps) if "timestamp" in data else None
    notes = [n for n in (length_note(meta_row.get("length"), len(rows)),) if n]
    videos = {key: _video_segment(root, info, ref.episode_index, meta_row, key, len(rows) / fps) for key in video_keys}
    stats = _source_stats(root, info, ref.episode_index, meta_row, (*copy_keys, *video_keys))
    return EpisodeColumns(str(path), fps, columns, task, info, copied, videos, stats, note, notes)


def length_note(recorded, num_frames: int) -> str | None:
    """What is odd about an episode's length: its metadata records another length than its data holds, or it
    has a single frame (nothing moves in it); None otherwise. The data's frames are what is converted."""
    said = []
    if recorded is not None and int(recorded) != num_frames:
        said.append(f"its episode metadata says {int(recorded)} frames, its data holds {num_frames}")
    if num_frames == 1:
        said.append("it has a single frame")
    return "; ".join(said) or None


def timestamp_note(timestamps_s: np.ndarray, fps: float) -> str | None:
    """What is wrong with an episode's source timestamps (the writer rebuilds them as frame_index / fps, which
    is right only when the frames were recorded 1/fps apart), or None when they step by 1/fps."""
    t = np.asarray(timestamps_s, dtype=np.float64)
    bad = int((~np.isfinite(t)).sum())  # NaN compares false with everything: no step would look wrong
    if bad:
        return f"timestamps are not numbers (NaN or infinite) at {bad} of {len(t)} frames"
    if len(t) < 2:
        return None
    if not t.any():
        return "timestamps all 0"
    steps = np.diff(t)
    repeated = int((steps <= 0).sum())
    if repeated:
        return f"timestamps repeat or go back at {repeated} of {len(t)} frames"
    off = np.abs(steps * fps - 1.0) > 0.5
    if off.any():
        return f"{int(off.sum())} of {len(t) - 1} frame steps are not 1/fps = {1 / fps:.4g} s (frames dropped or doubled?)"
    return None


def _combined(column):
    import pyarrow as pa

    return column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column


def _video_segment(
    root: Path, info: dict, episode_index: int, meta_row: dict, key: str, duration_s: float
) -> VideoSegment:
    """Where episode `episode_index` of video feature `key` sits in the source files (v3.0 or v2.1)."""
    if info["codebase_version"] == "v3.0":
        try:
            chunk, file = int(meta_row[f"videos/{key}/chunk_index"]), int(meta_row[f"videos/{key}/file_index"])
            start, end = float(meta_row[f"videos/{key}/from_timestamp"]), float(meta_row[f"videos/{key}/to_timestamp"])
        except KeyError as exc:
            raise LeRobotFormatError(f"{root / 'meta' / 'episodes'}: missing column {exc} of video {key!r}") from exc
        path = root / info["video_path"].format(video_key=key, chunk_index=chunk, file_index=file)
    else:
        chunk = episode_index // int(info.get("chunks_size", 1000))
        path = root / info["video_path"].format(episode_chunk=chunk, video_key=key, episode_index=episode_index)
        start, end = 0.0, _video_duration_s(path, duration_s)
    if not path.is_file():
        moved = moved_file(root, path)
        if moved is None:
            raise LeRobotFormatError(f"{path}: video {key!r} of episode {episode_index} is missing")
        path = moved
    return VideoSegment(str(path), start, end)


def video_folder_note(root: Path, info: dict) -> str | None:
    """One line when the dataset's videos are not under the folder `info.json`'s `video_path` names but under
    another one that holds them (seen: `video/` for `videos/`), which the reader then uses; else None."""
    template = info.get("video_path")
    if not template or not any(ft.get("dtype") == "video" for ft in info["features"].values()):
        return None
    top = Path(template).parts[0]
    if (root / top).is_dir():
        return None
    others = [d.name for d in sorted(root.iterdir()) if d.is_dir() and any(d.rglob("*.mp4"))]
    if not others:
        return f"meta/info.json video_path {template!r}: no {top}/ folder and no videos elsewhere"
    return f"meta/info.json video_path says {top}/, but the videos are under {others[0]}/: reading them there"


def moved_file(root: Path, path: Path) -> Path | None:
    """`path` under another top folder of `root` than `info.json`'s template says (seen: `video/` for `videos/`),
    when exactly one holds it; None otherwise."""
    rel = path.relative_to(root)
    found = [d / Path(*rel.parts[1:]) for d in sorted(root.iterdir()) if d.is_dir() and d.name != rel.parts[0]]
    found = [p for p in found if p.is_file()]
    return found[0] if len(found) == 1 else None


def _video_duration_s(path: Path, fallback_s: float) -> float:
    """A v2.1 episode video's duration (LeRobot's own probe, as its v2.1 -> v3.0 converter does)."""
    if not path.is_file():
        return fallback_s
    from lerobot.datasets.video_utils import get_video_duration_in_s

    return float(get_video_duration_in_s(path))


def _source_stats(root: Path, info: dict, episode_index: int, meta_row: dict, keys: tuple[str, ...]) -> dict:
    """The source's per-episode stats of the image/video features among `keys` (v3.0 columns or v2.1 jsonl)."""
    visual = [k for k in keys if info["features"][k].get("dtype") in VISUAL_DTYPES]
    if not visual:
        return {}
    out: dict[str, dict] = {}
    if info["codebase_version"] == "v3.0":
        for key in visual:
            prefix = f"stats/{key}/"
            stats = {
                c[len(prefix) :]: np.asarray(v) for c, v in meta_row.items() if c.startswith(prefix) and v is not None
            }
            if stats:
                out[key] = stats
        return out
    by_episode = _episodes_stats_v21(str(root))
    for key, stats in by_episode.get(episode_index, {}).items():
        if key in visual:
            out[key] = {name: np.asarray(value) for name, value in stats.items()}
    return out


@lru_cache(maxsize=8)
def _episodes_stats_v21(root_str: str) -> dict[int, dict]:
    path = Path(root_str) / "meta" / "episodes_stats.jsonl"
    if not path.is_file():
        return {}
    return {int(r["episode_index"]): r.get("stats", {}) for r in _read_jsonl(path)}


def _vector_column(column, rows: np.ndarray, path: Path, key: str, episode_index: int) -> np.ndarray:
    """(T, D) of a list / fixed-size-list (or scalar) parquet column at `rows`, in the stored number type."""
    import pyarrow as pa

    column = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if column.null_count:
        raise LeRobotFormatError(f"{path}: column {key!r} has null rows in episode {episode_index}")
    if pa.types.is_fixed_size_list(column.type) or pa.types.is_list(column.type):
        lengths = set(column.value_lengths().to_numpy(zero_copy_only=False).tolist()) if len(column) else {0}
        if len(lengths) != 1:
            raise LeRobotFormatError(f"{path}: column {key!r} has rows of different lengths {sorted(lengths)}")
        flat = column.flatten().to_numpy(zero_copy_only=False)
        values = flat.reshape(len(column), -1)
    else:
        values = column.to_numpy(zero_copy_only=False).reshape(len(column), -1)
    if not np.issubdtype(values.dtype, np.number) and values.dtype != np.bool_:
        raise LeRobotFormatError(f"{path}: column {key!r} is not numeric ({column.type})")
    return values[rows]


def _task_text(root: Path, info: dict, tasks: object, data: dict, rows: np.ndarray) -> str:
    if tasks:  # v3.0 episode metadata holds the task strings
        return "; ".join(str(t) for t in tasks)
    if "task_index" not in data:
        return ""
    task_indices = sorted({int(i) for i in data["task_index"].to_numpy()[rows]})
    if info["codebase_version"] == "v3.0":
        import pyarrow.parquet as pq

        path = root / "meta" / "tasks.parquet"
        if not path.is_file():
            return ""
        frame = pq.read_table(path).to_pandas()
        by_index = {int(i): str(t) for t, i in zip(frame.index, frame["task_index"], strict=True)}
    else:
        path = root / "meta" / "tasks.jsonl"
        if not path.is_file():
            return ""
        by_index = {int(r["task_index"]): str(r["task"]) for r in _read_jsonl(path)}
    return "; ".join(by_index.get(i, "") for i in task_indices)


def select_columns(names: list[str], wanted: list[str], where: str) -> np.ndarray:
    """Indices of `wanted` in `names`; a clear error lists the missing ones and what exists."""
    index = {n: i for i, n in enumerate(names)}
    missing = [n for n in wanted if n not in index]
    if missing:
        raise LeRobotFormatError(f"{where}: unknown names {missing}; available names: {names}")
    return np.array([index[n] for n in wanted], dtype=np.int64)
