"""Convert a registered source to a UDHM LeRobotDataset v3.0: list -> split -> read+map (pool) -> write.

- Split: deterministic 80/20 by episode. Each episode's key is its ref as a string, relative to the
  input path; the `round(test_fraction * N)` episodes with the smallest sha1(key) are the test set.
  Train episodes are written first (in source order), then test ones, so `splits` are two ranges.
- Reliability: everything is written to `<root>.<name>.tmp-*` next to the target and moved into place
  at the end; an error or Ctrl-C removes the temp folder. An existing target is refused unless
  `overwrite`. Per-episode failures are `EpisodeError(file, reason)`: raised (`on_error="raise"`)
  or skipped and summarised (`on_error="skip"`).
- Parallel: episodes are read and mapped in a process pool and written in order by this process.
- Sharding: `shard_index/num_shards` converts one contiguous slice of the ordered episode list;
  `merge_shards` aggregates shard datasets with LeRobot's `aggregate_datasets` and restores the splits.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import time
import uuid
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from tqdm import tqdm

from lerobot_unidextok.constants import (
    ACTION,
    HAND_TYPE_KEY,
    OBS_STATE,
    SIDES,
    UDHM_MASK_KEY,
)
from lerobot_unidextok.conversion.card import write_card
from lerobot_unidextok.conversion.mapping import (
    MAPPINGS,
    EpisodeError,
    UdhmEpisode,
    map_episode,
    state_names,
    to_layout,
)
from lerobot_unidextok.conversion.registry import CONVERTERS_PACKAGE, get_source
from lerobot_unidextok.conversion.writer import UdhmDatasetWriter

logger = logging.getLogger(__name__)

OnError = Literal["raise", "skip"]
CONVERSION_SETTINGS_PATH = (
    "meta/unidextok_conversion.json"  # settings and counts (LeRobot drops unknown info.json keys)
)


@dataclass
class ConvertOptions:
    """What to convert and how (the CLI config carries the same fields)."""

    source: str
    input: str | Path
    root: str | Path
    repo_id: str = "local/udhm"
    source_options: dict[str, Any] = field(default_factory=dict)  # kwargs of the source reader class
    mapping: str = "semantic"  # "semantic" | "append_pad"
    on_error: OnError = "raise"
    num_workers: int = 1  # processes reading + mapping episodes; 1 = in this process
    overwrite: bool = False
    test_fraction: float = 0.2
    max_episodes: int | None = None  # first N episodes of the ordered list (quick looks)
    sides: tuple[str, ...] | None = None  # block layout, e.g. ("right", "left"); None = source's `sides` or 1st episode
    shard_index: int = 0
    num_shards: int = 1
    progress: bool = True
    mp_context: str = "forkserver"  # worker start method; "fork" is unsafe in a threaded parent (pyarrow, torch)

    def __post_init__(self):
        if self.mapping not in MAPPINGS:
            raise ValueError(f"mapping must be one of {MAPPINGS}, got {self.mapping!r}")
        if self.on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {self.on_error!r}")
        if self.num_workers < 1:
            raise ValueError(f"num_workers must be >= 1, got {self.num_workers}")
        if not 0.0 <= self.test_fraction < 1.0:
            raise ValueError(f"test_fraction must be in [0, 1), got {self.test_fraction}")
        if self.sides is not None:
            self.sides = tuple(self.sides)
            if not self.sides or len(set(self.sides)) != len(self.sides) or not set(self.sides) <= set(SIDES):
                raise ValueError(f"sides must be distinct values of {SIDES}, got {self.sides!r}")
        if not 0 <= self.shard_index < self.num_shards:
            raise ValueError(f"need 0 <= shard_index < num_shards, got {self.shard_index}/{self.num_shards}")


@dataclass
class EpisodeFailure:
    source_file: str
    reason: str


@dataclass
class ConvertReport:
    root: Path
    num_episodes: int
    num_frames: int
    num_train: int
    num_test: int
    seconds: float
    failures: list[EpisodeFailure] = field(default_factory=list)
    hands: list[str] = field(default_factory=list)

    @property
    def frames_per_second(self) -> float:
        return self.num_frames / self.seconds if self.seconds > 0 else float("inf")


class ConversionError(RuntimeError):
    """The conversion stopped; nothing was written at the target."""


# ---------------------------------------------------------------------------------------------
# split
# ---------------------------------------------------------------------------------------------
def episode_key(ref: Any, input_path: str | Path) -> str:
    """Stable string of an episode ref: its text with the input path prefix removed."""
    text = str(ref)
    for prefix in {str(Path(input_path)), str(Path(input_path).resolve())}:
        text = text.replace(prefix + os.sep, "").replace(prefix, "")
    return text


def split_order(keys: list[str], test_fraction: float = 0.2) -> tuple[list[int], list[int]]:
    """(train, test) positions: test = the round(f * N) keys with the smallest sha1; each list in input order."""
    num_test = round(test_fraction * len(keys)) if len(keys) > 1 else 0
    ranked = sorted(range(len(keys)), key=lambda i: hashlib.sha1(keys[i].encode()).hexdigest())
    test = set(ranked[:num_test])
    return [i for i in range(len(keys)) if i not in test], sorted(test)


# ---------------------------------------------------------------------------------------------
# workers
# ---------------------------------------------------------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_worker(source: str, source_options: dict, mapping: str) -> None:
    _import_sources()
    _WORKER["reader"] = get_source(source)(**source_options)
    _WORKER["mapping"] = mapping


def _import_sources() -> None:
    from lerobot_unidextok.conversion.registry import _import_converters

    _import_converters()


def _read_and_map(ref: Any) -> UdhmEpisode | EpisodeFailure:
    reader = _WORKER["reader"]
    try:
        raw = reader.read_episode(ref)
    except Exception as exc:  # noqa: BLE001  any reader error is this episode's failure
        return EpisodeFailure(str(ref), f"reader error {type(exc).__name__}: {exc}")
    try:
        return map_episode(raw, _WORKER["mapping"])
    except EpisodeError as exc:
        return EpisodeFailure(exc.source_file, exc.reason)
    except Exception as exc:  # noqa: BLE001
        return EpisodeFailure(raw.source_file, f"{type(exc).__name__}: {exc}")


def _iter_results(refs: list, opts: ConvertOptions):
    """Mapped episodes (or failures) in `refs` order; bounded look-ahead in the pool."""
    if opts.num_workers == 1:
        _init_worker(opts.source, opts.source_options, opts.mapping)
        for ref in refs:
            yield _read_and_map(ref)
        return
    window = 4 * opts.num_workers
    import multiprocessing

    ctx = multiprocessing.get_context(opts.mp_context)
    if opts.mp_context == "forkserver":  # import once in the server; workers fork from it
        ctx.set_forkserver_preload(
            [
                "lerobot_unidextok.conversion.pipeline",
                "lerobot_unidextok.hands",
                CONVERTERS_PACKAGE,
            ]
        )
    with ProcessPoolExecutor(
        opts.num_workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(opts.source, opts.source_options, opts.mapping),
    ) as pool:
        pending: deque = deque()
        it = iter(refs)
        try:
            for ref in it:
                pending.append(pool.submit(_read_and_map, ref))
                if len(pending) >= window:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for fut in pending:
                fut.cancel()


# ---------------------------------------------------------------------------------------------
# features
# ---------------------------------------------------------------------------------------------
def udhm_features(sides: tuple[str, ...], with_action: bool) -> dict[str, dict]:
    """LeRobot features of the converted-dataset contract for hand blocks `sides`."""
    names = state_names(sides)
    dim = len(names)
    features = {OBS_STATE: {"dtype": "float32", "shape": (dim,), "names": names}}
    if with_action:
        features[ACTION] = {"dtype": "float32", "shape": (dim,), "names": names}
    features[HAND_TYPE_KEY] = {"dtype": "string", "shape": (1,), "names": None}
    features[UDHM_MASK_KEY] = {"dtype": "bool", "shape": (dim,), "names": names}
    return features


def _episode_frames(ep: UdhmEpisode) -> dict[str, np.ndarray | str]:
    frames: dict[str, np.ndarray | str] = {
        OBS_STATE: ep.state_rad,
        HAND_TYPE_KEY: ep.hand_type,
        UDHM_MASK_KEY: ep.mask,
    }
    if ep.action_rad is not None:
        frames[ACTION] = ep.action_rad
    return frames


def _int_fps(fps: float, src: str) -> int:
    if abs(fps - round(fps)) > 1e-3:
        raise EpisodeError(src, f"fps {fps} is not an integer; LeRobot datasets store integer fps")
    return round(fps)


# ---------------------------------------------------------------------------------------------
# convert
# ---------------------------------------------------------------------------------------------
def input_is_synthetic(input_path: Path) -> bool:
    """True when `input_path` is (inside) a sample written by `conversion.samples` (its labels file says so),
    so the card is marked synthetic even for formats whose reader cannot carry the marker."""
    from lerobot_unidextok.conversion.samples import LABELS_FILE

    path = input_path.resolve()
    for folder in [path, *path.parents][:3]:
        labels = folder / LABELS_FILE
        if labels.is_file():
            try:
                return bool(json.loads(labels.read_text()).get("synthetic", False))
            except (json.JSONDecodeError, AttributeError):
                return False
    return False


def _temp_dir(target: Path) -> Path:
    return target.parent / f".{target.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"


def _remove_stale_temps(target: Path) -> None:
    """Delete temp folders of earlier runs on `target` whose process is gone (killed with SIGKILL)."""
    for path in target.parent.glob(f".{target.name}.tmp-*"):
        try:
            pid = int(path.name.rsplit(".tmp-", 1)[1].split("-")[0])
        except (IndexError, ValueError):
            continue
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            logger.warning("removing stale temp folder of a dead conversion run: %s", path)
            shutil.rmtree(path, ignore_errors=True)
        except PermissionError:
            pass


def _move_into_place(tmp: Path, target: Path, overwrite: bool) -> None:
    if target.exists():
        if not overwrite:  # appeared while we were converting
            raise ConversionError(f"{target} appeared during conversion; result left in {tmp}")
        old = target.parent / f".{target.name}.old-{uuid.uuid4().hex[:8]}"
        target.rename(old)
        tmp.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(target)


def convert(opts: ConvertOptions) -> ConvertReport:
    """Convert `opts.source` at `opts.input` into a UDHM LeRobotDataset at `opts.root`."""
    t0 = time.perf_counter()
    target = Path(opts.root).expanduser().resolve()
    if target.exists() and not opts.overwrite:
        raise FileExistsError(f"{target} already exists; pass --overwrite=true to replace it, or choose another --root")
    input_path = Path(opts.input).expanduser()
    if not input_path.exists():
        raise FileNotFoundError(f"--input {input_path} does not exist")
    _import_sources()
    reader_cls = get_source(opts.source)
    reader = reader_cls(**opts.source_options)
    refs = list(reader.list_episodes(input_path))
    if not refs:
        raise ValueError(f"source {opts.source!r} found no episodes under {input_path}; check --input")
    train_pos, test_pos = split_order([episode_key(r, input_path) for r in refs], opts.test_fraction)
    ordered = [(refs[i], "train") for i in train_pos] + [(refs[i], "test") for i in test_pos]
    if opts.max_episodes is not None:
        ordered = ordered[: opts.max_episodes]
    if opts.num_shards > 1:
        bounds = np.linspace(0, len(ordered), opts.num_shards + 1).round().astype(int)
        ordered = ordered[bounds[opts.shard_index] : bounds[opts.shard_index + 1]]
        if not ordered:
            raise ValueError(f"shard {opts.shard_index}/{opts.num_shards} is empty ({len(refs)} episodes)")

    target.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale_temps(target)
    tmp = _temp_dir(target)
    writer: UdhmDatasetWriter | None = None
    layout = None
    failures: list[EpisodeFailure] = []
    counts = {"train": 0, "test": 0}
    hands_seen: dict[str, None] = {}
    stats = {"trimmed_frames": 0, "absent_hand_frames": 0}
    synthetic = bool(getattr(reader_cls, "synthetic", False)) or input_is_synthetic(input_path)
    sides = opts.sides or (tuple(reader_cls.sides) if getattr(reader_cls, "sides", None) else None)
    bar = tqdm(
        total=len(ordered),
        desc=f"convert {opts.source}",
        unit="ep",
        disable=not opts.progress,
    )
    try:
        for (ref, split), result in zip(ordered, _iter_results([r for r, _ in ordered], opts), strict=True):
            try:
                if isinstance(result, EpisodeFailure):
                    raise EpisodeError(result.source_file, result.reason)
                fps = _int_fps(result.fps, result.source_file)
                if sides is not None:
                    result = to_layout(result, sides)
                if writer is None:
                    layout = (result.layout, fps)
                    writer = UdhmDatasetWriter(
                        tmp,
                        opts.repo_id,
                        fps,
                        udhm_features(result.sides, result.action_rad is not None),
                        robot_type="udhm",  # one value for every conversion: aggregate_datasets requires equal robot_type
                    )
                elif (result.layout, fps) != layout:
                    (first_sides, act), f0 = layout
                    raise EpisodeError(
                        result.source_file,
                        f"hand layout sides={result.sides} action={result.action_rad is not None} fps={fps} differs "
                        f"from the dataset's sides={first_sides} action={act} fps={f0} (set by its first episode); for a "
                        "source whose episodes are left or right hands pass --sides=right,left",
                    )
                if split == "test" and counts["test"] == 0 and writer.num_episodes != counts["train"]:
                    raise AssertionError("train episodes must precede test episodes")
                writer.add_episode(_episode_frames(result), task=result.task)
            except EpisodeError as exc:
                if opts.on_error == "raise":
                    raise ConversionError(
                        f"episode {exc.source_file}: {exc.reason}\n(use --on_error=skip to skip bad episodes)"
                    ) from exc
                failures.append(EpisodeFailure(exc.source_file, exc.reason))
                logger.warning("skipped %s: %s", exc.source_file, exc.reason)
            else:
                counts[split] += 1
                for h in result.hands:
                    hands_seen[h] = None
                synthetic |= result.synthetic
                stats["trimmed_frames"] += result.trimmed_frames
                stats["absent_hand_frames"] += result.absent_hand_frames
            bar.update(1)
            elapsed = time.perf_counter() - t0
            if writer is not None:
                bar.set_postfix(
                    frames=writer.num_frames,
                    fps=f"{writer.num_frames / max(elapsed, 1e-9):,.0f}",
                )
        bar.close()
        if writer is None:
            raise ConversionError(
                f"no episode of {opts.source!r} could be converted ({len(failures)} failed); first: "
                + (f"{failures[0].source_file}: {failures[0].reason}" if failures else "none")
            )
        num_train, num_total = counts["train"], writer.num_episodes
        splits = {"train": f"0:{num_train}", "test": f"{num_train}:{num_total}"}
        writer.finalize(splits=splits)
        (layout_sides, with_action), fps = layout
        settings = {
            "source": opts.source,
            "license": getattr(reader_cls, "license", "unknown"),
            "description": getattr(reader_cls, "description", ""),
            "source_options": opts.source_options,
            "mapping": opts.mapping,
            "on_error": opts.on_error,
            "test_fraction": opts.test_fraction,
            "split_method": "sha1 of episode key (ref relative to --input); smallest round(f*N) are test",
            "shard": f"{opts.shard_index}/{opts.num_shards}",
            "max_episodes": opts.max_episodes,
            "sides": list(layout_sides),
            "hands": list(hands_seen),
            "has_action": with_action,
            "synthetic": synthetic,
            "skipped_episodes": len(failures),
            **stats,
        }
        _record_settings(tmp, settings)
        write_card(
            tmp,
            repo_id=opts.repo_id,
            source=opts.source,
            description=getattr(reader_cls, "description", ""),
            license_text=getattr(reader_cls, "license", "unknown"),
            settings=settings,
            num_episodes=num_total,
            num_frames=writer.num_frames,
            splits=splits,
            failures=[asdict(f) for f in failures],
        )
        _move_into_place(tmp, target, opts.overwrite)
    except BaseException:
        bar.close()
        if writer is not None:
            writer.abort()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    report = ConvertReport(
        root=target,
        num_episodes=num_total,
        num_frames=writer.num_frames,
        num_train=num_train,
        num_test=num_total - num_train,
        seconds=time.perf_counter() - t0,
        failures=failures,
        hands=list(hands_seen),
    )
    if failures:
        logger.warning("%d episode(s) skipped:\n%s", len(failures), format_failures(failures))
    return report


def format_failures(failures: list[EpisodeFailure], limit: int = 50) -> str:
    lines = [f"  {f.source_file}: {f.reason}" for f in failures[:limit]]
    if len(failures) > limit:
        lines.append(f"  ... and {len(failures) - limit} more")
    return "\n".join(lines)


def _record_settings(root: Path, settings: dict) -> None:
    (root / CONVERSION_SETTINGS_PATH).write_text(json.dumps(settings, indent=2, default=str))


def read_settings(root: str | Path) -> dict:
    """Conversion settings recorded next to the dataset metadata ({} if absent)."""
    path = Path(root) / CONVERSION_SETTINGS_PATH
    return json.loads(path.read_text()) if path.is_file() else {}


# ---------------------------------------------------------------------------------------------
# shards
# ---------------------------------------------------------------------------------------------
def merge_shards(
    shard_roots: list[str | Path],
    root: str | Path,
    repo_id: str = "local/udhm",
    overwrite: bool = False,
) -> Path:
    """Aggregate shard datasets (in shard order) with LeRobot's `aggregate_datasets`; restore splits."""
    from lerobot.datasets.aggregate import aggregate_datasets

    target = Path(root).expanduser().resolve()
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} already exists; pass overwrite=True or choose another root")
    shard_roots = [Path(r) for r in shard_roots]
    infos = [json.loads((r / "meta" / "info.json").read_text()) for r in shard_roots]
    num_train = sum(int(i["splits"]["train"].split(":")[1]) - int(i["splits"]["train"].split(":")[0]) for i in infos)
    # Shards are contiguous slices of one ordered list (train episodes first), so train stays a prefix.
    tmp = _temp_dir(target)
    try:
        aggregate_datasets(
            repo_ids=[f"{repo_id}_shard{k}" for k in range(len(shard_roots))],
            aggr_repo_id=repo_id,
            roots=shard_roots,
            aggr_root=tmp,
        )
        path = tmp / "meta" / "info.json"
        info = json.loads(path.read_text())
        total = int(info["total_episodes"])
        info["splits"] = {"train": f"0:{num_train}", "test": f"{num_train}:{total}"}
        path.write_text(json.dumps(info, indent=4))
        shard_settings = [read_settings(r) for r in shard_roots]
        settings = dict(shard_settings[0])
        settings["shard"] = f"merged {len(shard_roots)} shards"
        for key in ("skipped_episodes", "trimmed_frames", "absent_hand_frames"):
            settings[key] = sum(s.get(key, 0) for s in shard_settings)
        settings["hands"] = sorted({h for s in shard_settings for h in s.get("hands", [])})
        settings["synthetic"] = any(s.get("synthetic", False) for s in shard_settings)
        _record_settings(tmp, settings)
        write_card(
            tmp,
            repo_id=repo_id,
            source=settings.get("source", "unknown"),
            description=settings.get("description", ""),
            license_text=settings.get("license", "unknown"),
            settings=settings,
            num_episodes=total,
            num_frames=int(info["total_frames"]),
            splits=info["splits"],
        )
        _move_into_place(tmp, target, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target
