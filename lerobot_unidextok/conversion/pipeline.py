"""Convert a registered source to a UDHM LeRobotDataset v3.0: set up -> list -> read+map (pool) -> write.

- Setup first: the reader is built from its options and lists its episodes before any episode is read;
  a bad option, an unknown hand or an empty input stops here once (`SetupError`), with the fix.
- Order and split: episodes are written in **source order**. The test set is the `round(f * N)`
  episodes with the smallest sha1 of their key (the ref relative to the input path), chosen over the
  whole source, so it does not depend on listing order, workers, shards or `max_episodes`. It is
  recorded, not made a range: `meta/info.json` keeps LeRobot's `{"train": "0:N"}` and
  `meta/unidextok_conversion.json` lists `test_episodes` and, per episode, its source and split.
- Whole robot: passthrough columns, copied features and videos of the source go through unchanged
  (`keep="all"`, default) or are dropped for a hands-only dataset (`keep="hands"`; readers with a `keep`
  option do not read them at all). `robot_type` is the source's own (reader's optional `robot_type(refs)`).
- Reliability: everything is written to `<root>.<name>.tmp-*` next to the target and moved into place
  at the end; an error or Ctrl-C removes the temp folder. An existing target is refused unless
  `overwrite`. Per-episode failures are `EpisodeError(file, reason)`: raised (`on_error="raise"`)
  or skipped and summarised (`on_error="skip"`).
- Parallel: episodes are read and mapped in a process pool and written in order by this process.
- Sharding: `shard_index/num_shards` converts one contiguous slice of the ordered episode list;
  `merge_shards` aggregates shard datasets with LeRobot's `aggregate_datasets` and merges the records.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from lerobot_unidextok.constants import (
    CONVERSION_PATH,
    EPISODES_META_GLOB,
    INFO_PATH,
    MAPPINGS,
    SAMPLE_LABELS_FILE,
    SIDES,
)
from lerobot_unidextok.conversion.card import write_card
from lerobot_unidextok.conversion.features import episode_features, episode_frames, native_layouts, udhm_features
from lerobot_unidextok.conversion.mapping import ZERO_HANDS, EpisodeError, UdhmEpisode, map_episode, to_sides
from lerobot_unidextok.conversion.registry import (
    CONVERTERS_PACKAGE,
    SetupError,
    get_source,
    import_sources,
    make_reader,
)
from lerobot_unidextok.conversion.workers import PARENT_ENV, die_with
from lerobot_unidextok.conversion.writer import UdhmDatasetWriter
from lerobot_unidextok.data.destination import Kind, claim, move_into_place, recover, release
from lerobot_unidextok.data.record import ConversionRecord, EpisodeRecord, load_record, write_record
from lerobot_unidextok.data.splits import split_order
from lerobot_unidextok.data.wrist_frame import WristFrame
from lerobot_unidextok.errors import InvalidInputError, MissingInputError, UnavailableError
from lerobot_unidextok.layout import NativeLayout
from lerobot_unidextok.utils.cli import progress_bar
from lerobot_unidextok.utils.files import temp_sibling

logger = logging.getLogger(__name__)

__all__ = [
    "ConversionError",
    "ConvertOptions",
    "ConvertReport",
    "SetupError",
    "convert",
    "merge_shards",
    "udhm_features",
]

OnError = Literal["raise", "skip"]
STOP_GRACE_S = 10.0  # an interrupted conversion waits this long for the episodes in flight before killing workers
KEEP = ("all", "hands")
SPLIT_METHOD = "sha1 of episode key (ref relative to --input); the round(f*N) smallest are test; source order kept"


@dataclass
class ConvertOptions:
    """What to convert and how (`unidextok-convert` takes the same fields as flags)."""

    source: str  # registered source name (conversion.available_sources(), --list_sources=true)
    input: str | Path  # raw dataset folder (or file) of the source
    root: str | Path  # output folder (must not exist unless `overwrite`)
    repo_id: str = "local/udhm"  # dataset id (namespace/name), used for the card and the Hub
    # keyword options of the source reader class, e.g. {"hands": {...}} (a JSON object on the command line)
    source_options: dict[str, Any] = field(default_factory=dict)
    mapping: str = "semantic"  # "semantic" (joint -> named UDHM slot) | "append_pad" (ablation)
    on_error: OnError = "raise"  # "raise": stop at the first bad episode | "skip": skip, report at the end
    num_workers: int = 1  # processes reading + mapping episodes; 1 = in this process
    overwrite: bool = False  # replace an existing dataset at root (atomically, at the end)
    test_fraction: float = 0.2  # share of episodes in the deterministic test split
    max_episodes: int | None = None  # convert only the first N episodes in source order (quick looks)
    # block layout, e.g. "right,left" (or ("right", "left")) for sources whose episodes are left or right hands;
    # None = the source's `sides`, else the first episode's
    sides: str | tuple[str, ...] | None = None
    # frame grid of time-stamped sources (ROS bags, keypoint files): streams and files at another rate are resampled
    # onto it; None = source default (bags 30, keypoint files their own rate rounded, e.g. 29.97 -> 30)
    fps: int | None = None
    # "all": the whole robot (arms, other features, videos) | "hands": UDHM blocks only (other features and videos
    # are not read, so missing video files do not matter; the native layout then names the hand columns)
    keep: str = "all"
    # a robot hand whose state is 0 in every joint and frame of an episode: "absent" (not recorded: a zero
    # block with a zero mask, listed at the end) | "keep" (convert the zeros as joint values)
    zero_hands: str = "absent"
    shard_index: int = 0  # convert one contiguous shard of the episode list (multi-machine runs by hand)
    num_shards: int = 1  # how many such shards the episode list is cut into
    progress: bool = True  # progress bar
    mp_context: str = "forkserver"  # worker start method; "fork" is unsafe in a threaded parent (pyarrow, torch)

    def __post_init__(self):
        if self.mapping not in MAPPINGS:
            raise ValueError(f"mapping must be one of {MAPPINGS}, got {self.mapping!r}")
        if self.on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {self.on_error!r}")
        if self.keep not in KEEP:
            raise ValueError(f"keep must be one of {KEEP}, got {self.keep!r}")
        if self.zero_hands not in ZERO_HANDS:
            raise ValueError(f"zero_hands must be one of {ZERO_HANDS}, got {self.zero_hands!r}")
        if self.num_workers < 1:
            raise ValueError(f"num_workers must be >= 1, got {self.num_workers}")
        if not 0.0 <= self.test_fraction < 1.0:
            raise ValueError(f"test_fraction must be in [0, 1), got {self.test_fraction}")
        if self.fps is not None and (int(self.fps) != self.fps or self.fps <= 0):
            raise ValueError(f"fps must be a positive integer (LeRobot stores int fps), got {self.fps!r}")
        if isinstance(self.sides, str):
            self.sides = tuple(side.strip() for side in self.sides.split(",") if side.strip()) or None
        if self.sides is not None:
            self.sides = tuple(self.sides)
            if not self.sides or len(set(self.sides)) != len(self.sides) or not set(self.sides) <= set(SIDES):
                raise ValueError(f"sides must be distinct values of {SIDES}, got {self.sides!r}")
        if not 0 <= self.shard_index < self.num_shards:
            raise ValueError(f"need 0 <= shard_index < num_shards, got {self.shard_index}/{self.num_shards}")

    def reader_options(self) -> dict:
        """The source options, with `fps` passed to sources that resample onto a grid and `keep` to sources
        that can skip reading what `--keep=hands` drops (other features, videos)."""
        import inspect

        options = dict(self.source_options)
        params = inspect.signature(get_source(self.source)).parameters
        if "keep" in params:
            if options.get("keep") not in (None, self.keep):
                raise SetupError(f"--keep={self.keep} and source option keep={options['keep']} disagree; give --keep")
            options["keep"] = self.keep
        if self.fps is not None:
            if "fps" not in params:
                raise SetupError(
                    f"--fps applies to sources that resample time-stamped streams; {self.source!r} has a fixed "
                    "frame rate: drop --fps"
                )
            if options.get("fps") not in (None, self.fps):
                raise SetupError(f"--fps={self.fps} and source option fps={options['fps']} disagree; give one")
            options["fps"] = int(self.fps)
        return options


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


class ConversionError(UnavailableError):
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


def episode_keys(refs: list, input_path: str | Path) -> list[str]:
    """The key of each ref that the test split hashes, the same wherever `--input` points: relative to the
    deepest folder all refs share (their dataset roots for LeRobot refs, else their files) when that lies below
    `--input`, so a dataset converted from a parent folder that holds only it gets its own keys."""
    places = [str(getattr(r, "root", r)) for r in refs]
    if len(set(places)) > 1:
        common = os.path.commonpath(places)
    else:
        common = places[0] if hasattr(refs[0], "root") else os.path.dirname(places[0])
    inside = os.path.abspath(common).startswith(os.path.abspath(input_path) + os.sep)
    return [episode_key(r, common if inside else input_path) for r in refs]


# ---------------------------------------------------------------------------------------------
# workers
# ---------------------------------------------------------------------------------------------
_WORKER: dict[str, Any] = {}


def _init_worker(source: str, source_options: dict, mapping: str, zero_hands: str, parent: int | None = None) -> None:
    if parent is not None:  # a pool worker: it ends with the conversion (and the forkserver) whatever kills them
        die_with(parent)
    import_sources()
    _WORKER["reader"] = make_reader(source, source_options)
    _WORKER["mapping"] = mapping
    _WORKER["zero_hands"] = zero_hands


def _read_and_map(ref: Any) -> UdhmEpisode | EpisodeFailure:
    reader = _WORKER["reader"]
    try:
        raw = reader.read_episode(ref)
    except Exception as exc:  # noqa: BLE001  any reader error is this episode's failure
        return EpisodeFailure(str(ref), f"reader error {type(exc).__name__}: {exc}")
    try:
        return map_episode(raw, _WORKER["mapping"], _WORKER["zero_hands"])
    except EpisodeError as exc:
        return EpisodeFailure(exc.source_file, exc.reason)
    except Exception as exc:  # noqa: BLE001
        return EpisodeFailure(raw.source_file, f"{type(exc).__name__}: {exc}")


def _iter_results(refs: list, opts: ConvertOptions, reader_options: dict):
    """Mapped episodes (or failures) in `refs` order; bounded look-ahead in the pool."""
    if opts.num_workers == 1:
        _init_worker(opts.source, reader_options, opts.mapping, opts.zero_hands)
        for ref in refs:
            yield _read_and_map(ref)
        return
    window = 4 * opts.num_workers
    import multiprocessing

    ctx = multiprocessing.get_context(opts.mp_context)
    if opts.mp_context == "forkserver":  # import once in the server; workers fork from it
        os.environ[PARENT_ENV] = str(os.getpid())  # the forkserver dies with this process (conversion.workers)
        ctx.set_forkserver_preload(
            [
                "lerobot_unidextok.conversion.workers",
                "lerobot_unidextok.conversion.pipeline",
                "lerobot_unidextok.hands",
                CONVERTERS_PACKAGE,
            ]
        )
    pool = ProcessPoolExecutor(
        opts.num_workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(opts.source, reader_options, opts.mapping, opts.zero_hands, os.getpid()),
    )
    pending: deque = deque()
    finished = False
    try:
        for ref in refs:
            pending.append(pool.submit(_read_and_map, ref))
            if len(pending) >= window:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
        finished = True
    finally:
        if finished:
            pool.shutdown(wait=True)
        else:  # an error, Ctrl-C or SIGTERM: stop the workers now instead of letting them finish their queue
            _stop_workers(pool)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued episodes, let the few in flight end (the pool then stops its workers), and kill the
    workers still busy after `STOP_GRACE_S`. Killing them at once could land while one writes its result: the
    pool's result thread then waits for the rest of that message forever, and the interpreter joins that
    thread at exit, so a SIGTERM-ed conversion hung (about one run in seven)."""
    import multiprocessing

    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + STOP_GRACE_S
    for process in list(multiprocessing.active_children()):
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.kill()


def _int_fps(fps: float, src: str) -> int:
    if abs(fps - round(fps)) > 1e-3:
        raise EpisodeError(
            src,
            f"fps {fps} is not an integer; LeRobot datasets store integer fps: resample the source onto a "
            "fixed grid (--fps for time-stamped sources)",
        )
    return round(fps)


# ---------------------------------------------------------------------------------------------
# convert
# ---------------------------------------------------------------------------------------------
def input_is_synthetic(input_path: Path) -> bool:
    """True when `input_path` is (inside) a sample written by `samples` (its labels file says so),
    so the card is marked synthetic even for formats whose reader cannot carry the marker."""
    path = input_path.resolve()
    for folder in [path, *path.parents][:3]:
        labels = folder / SAMPLE_LABELS_FILE
        if labels.is_file():
            try:
                return bool(json.loads(labels.read_text()).get("synthetic", False))
            except (json.JSONDecodeError, AttributeError):
                return False
    return False


@dataclass
class _Plan:
    """The ordered work of one run: (ref, key, split) in source order, after max_episodes and sharding."""

    items: list[tuple[Any, str, str]]
    num_listed: int
    robot_type: str | None = None  # the source's own robot type, of the whole listing (equal in every shard)
    wrist_frame: WristFrame | None = None  # what the source's recorder wrote of its wrist (data/wrist_frame.py)


def plan_episodes(reader, opts: ConvertOptions, input_path: Path) -> _Plan:
    """List the source once and choose the test set; setup errors surface here, before any episode work."""
    try:
        refs = list(reader.list_episodes(input_path))
    except (ValueError, FileNotFoundError, ImportError) as exc:  # ImportError: a missing extra (rosbags, h5py)
        raise SetupError(f"source {opts.source!r} cannot list {input_path}: {exc}") from exc
    if not refs:
        raise SetupError(f"source {opts.source!r} found no episodes under {input_path}; check --input")
    keys = episode_keys(refs, input_path)
    test = set(split_order(keys, opts.test_fraction)[1])
    items = [(ref, key, "test" if i in test else "train") for i, (ref, key) in enumerate(zip(refs, keys, strict=True))]
    if opts.max_episodes is not None:
        items = items[: opts.max_episodes]
    if opts.num_shards > 1:
        bounds = np.linspace(0, len(items), opts.num_shards + 1).round().astype(int)
        items = items[bounds[opts.shard_index] : bounds[opts.shard_index + 1]]
        if not items:
            raise SetupError(f"shard {opts.shard_index}/{opts.num_shards} is empty ({len(refs)} episodes)")
    return _Plan(items, len(refs), source_robot_type(reader, refs), source_wrist_frame(reader, refs))


def source_wrist_frame(reader, refs: list) -> WristFrame | None:
    """The wrist frame the source recorded (the reader's optional `wrist_frame(refs)`), or None."""
    method = getattr(reader, "wrist_frame", None)
    return method(refs) if callable(method) else None


def kept_wrist_frame(frame: WristFrame | None, hands_seen, passthrough: dict[str, list[str]]) -> dict:
    """The record's `wrist_frame`: the source's, for the hands converted, when the state and action keep its
    columns (`--keep=hands` drops them); {} otherwise."""
    if frame is None:
        return {}
    centres = {h: c for h, c in frame.grasp_centre_in_wrist_m.items() if h in hands_seen}
    missing = frame.missing_columns(passthrough.get("observation.state", []), passthrough.get("action", []))
    if missing or not centres:
        logger.warning("the source records a wrist frame, not kept: %s", f"its columns {missing} are not in the "
                       "converted state and action" if missing else f"it has no grasp centre for {list(hands_seen)}")
        return {}
    return WristFrame(frame.columns, frame.rotation, centres).to_dict()


def source_robot_type(reader, refs: list) -> str | None:
    """The robot type the source records (LeRobot's `robot_type` in meta/info.json), from the reader's
    optional `robot_type(refs)` method (or `robot_type` class attribute); None when the format records none
    (LeRobot's own default)."""
    method = getattr(reader, "robot_type", None)
    if not callable(method):  # a fixed type as a class attribute, or none
        return str(method) if method else None
    try:
        return method(refs) or None
    except (ValueError, FileNotFoundError) as exc:
        raise SetupError(f"source {type(reader).__name__} cannot read the robot type: {exc}") from exc


def checked_paths(opts: ConvertOptions) -> tuple[Path, Path]:
    """(output root, input path) of a conversion; refuses an existing root without --overwrite and a missing input."""
    target = recover(opts.root)  # before anything can fail: a dead run's half-replaced dataset is put back
    input_path = Path(opts.input).expanduser()
    if not input_path.exists():
        raise MissingInputError(f"--input {input_path} does not exist")
    claim(target, Kind.CONVERTED, inputs=[input_path], overwrite=opts.overwrite)
    return target, input_path


def convert(opts: ConvertOptions) -> ConvertReport:
    """Convert `opts.source` at `opts.input` into a UDHM LeRobotDataset at `opts.root`."""
    t0 = time.perf_counter()
    target, input_path = checked_paths(opts)
    try:
        return _convert_into(target, input_path, opts, t0)
    finally:
        release(target)  # the destination's lock (data/destination.py), however the conversion ended


def _convert_into(target: Path, input_path: Path, opts: ConvertOptions, t0: float) -> ConvertReport:
    """The conversion of `input_path` into the claimed `target`."""
    import_sources()
    reader_cls = get_source(opts.source)
    reader_options = opts.reader_options()
    reader = make_reader(opts.source, reader_options)
    plan = plan_episodes(reader, opts, input_path)

    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(target)
    state = _RunState(
        robot_type=plan.robot_type,
        synthetic=bool(getattr(reader_cls, "synthetic", False)) or input_is_synthetic(input_path),
        sides=opts.sides or (tuple(reader_cls.sides) if getattr(reader_cls, "sides", None) else None),
    )

    bar = progress_bar(total=len(plan.items), desc=f"convert {opts.source}", unit="ep", disable=not opts.progress)
    try:
        results = _iter_results([ref for ref, _, _ in plan.items], opts, reader_options)
        for (_, key, split), result in zip(plan.items, results, strict=True):
            try:
                state.add(result, key, split, opts, tmp)
            except EpisodeError as exc:
                if opts.on_error == "raise":
                    raise ConversionError(
                        f"episode {exc.source_file}: {exc.reason}\n(use --on_error=skip to skip bad episodes)"
                    ) from exc
                state.failures.append(EpisodeFailure(exc.source_file, exc.reason))
                logger.warning("skipped %s: %s", exc.source_file, exc.reason)
            if state.writer is not None:
                elapsed = time.perf_counter() - t0
                bar.set_postfix(
                    frames=state.writer.num_frames, fps=f"{state.writer.num_frames / max(elapsed, 1e-9):,.0f}"
                )
            bar.update(1)  # after the postfix: one refresh writes both
        bar.close()
        if state.writer is None:
            first = state.failures[0] if state.failures else None
            raise ConversionError(
                f"no episode of {opts.source!r} could be converted ({len(state.failures)} failed); first: "
                + (f"{first.source_file}: {first.reason}" if first else "none")
            )
        record = state.finish(opts, reader_cls, plan)
        write_card(
            tmp,
            repo_id=opts.repo_id,
            record=record,
            num_frames=state.writer.num_frames,
            features=state.writer.features,
            failures=[asdict(f) for f in state.failures],
        )
        move_into_place(tmp, target, Kind.CONVERTED, opts.overwrite)
    except BaseException:
        bar.close()
        if state.writer is not None:
            state.writer.abort()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    num_total = state.writer.num_episodes
    report = ConvertReport(
        root=target,
        num_episodes=num_total,
        num_frames=state.writer.num_frames,
        num_train=num_total - len(state.test_episodes),
        num_test=len(state.test_episodes),
        seconds=time.perf_counter() - t0,
        failures=state.failures,
        hands=list(state.hands_seen),
    )
    if state.zero_hands:
        shown = ", ".join(state.zero_hands[:5]) + (f" and {len(state.zero_hands) - 5} more" if len(state.zero_hands) > 5 else "")
        logger.warning(
            "%d episode(s) have a hand whose state is 0 in every joint and frame, converted as absent (not recorded; "
            "--zero_hands=keep converts the zeros as values): %s", len(state.zero_hands), shown,
        )  # fmt: skip
    if state.timestamp_notes:
        notes = state.timestamp_notes
        logger.warning(
            "%d episode(s) have source timestamps that do not step by 1/fps; the converted timestamps are rebuilt as "
            "frame_index / %d, right only if the frames were recorded 1/fps apart: %s", len(notes), state.writer.fps,
            "; ".join(notes[:5]) + (f" and {len(notes) - 5} more" if len(notes) > 5 else ""),
        )  # fmt: skip
    if state.source_notes:
        notes = state.source_notes
        logger.warning(
            "%d episode(s) have source metadata that disagrees with their data, or a single frame; converted as their "
            "data holds them: %s", len(notes), "; ".join(notes[:5]) + (f" and {len(notes) - 5} more" if len(notes) > 5 else ""),
        )  # fmt: skip
    if state.failures:
        logger.warning("%d episode(s) skipped:\n%s", len(state.failures), format_failures(state.failures))
    return report


@dataclass
class _RunState:
    """What one conversion run accumulates while it writes episodes in order."""

    synthetic: bool
    sides: tuple[str, ...] | None
    robot_type: str | None = None
    writer: UdhmDatasetWriter | None = None
    signature: tuple | None = None  # UdhmEpisode.signature of the first episode: every episode must match it
    fps: int = 0
    native: dict[str, NativeLayout] = field(default_factory=dict)
    failures: list[EpisodeFailure] = field(default_factory=list)
    records: list[EpisodeRecord] = field(default_factory=list)
    test_episodes: list[int] = field(default_factory=list)
    hands_seen: dict[str, None] = field(default_factory=dict)
    zero_hands: list[str] = field(default_factory=list)  # "<episode key>: <sides>" converted as absent (all 0)
    timestamp_notes: list[str] = field(default_factory=list)  # "<episode key>: <what is wrong>" (converters/_lerobot_files.py)
    source_notes: list[str] = field(default_factory=list)  # "<episode key>: <metadata that disagrees with the data>"
    counts: dict[str, int] = field(default_factory=lambda: {"trimmed_frames": 0, "absent_hand_frames": 0})

    def add(self, result: UdhmEpisode | EpisodeFailure, key: str, split: str, opts: ConvertOptions, tmp: Path) -> None:
        if isinstance(result, EpisodeFailure):
            raise EpisodeError(result.source_file, result.reason)
        fps = _int_fps(result.fps, result.source_file)
        if opts.sides is not None:
            _refuse_dropped_sides(result, opts.sides)
        if self.sides is not None:
            result = to_sides(result, self.sides)
        if opts.keep == "hands":
            result = result.without_robot()
        if self.writer is None:
            self.signature, self.fps = result.signature, fps
            try:
                features = episode_features(result)
            except ValueError as exc:
                raise EpisodeError(result.source_file, str(exc)) from exc
            # the source's robot type, the same in every shard (aggregate_datasets requires equal robot_type);
            # UDHM itself is marked by the hand_type / udhm_mask features and meta/unidextok_conversion.json
            self.writer = UdhmDatasetWriter(tmp, opts.repo_id, fps, features, robot_type=self.robot_type)
            self.native = native_layouts(result, opts.mapping)
        elif (result.signature, fps) != (self.signature, self.fps):
            raise EpisodeError(result.source_file, _signature_difference(result, fps, self.signature, self.fps))
        index = self.writer.add_episode(
            episode_frames(result),
            task=result.task,
            copied=result.copied,
            videos=result.videos,
            copied_stats=result.copied_stats,
        )
        own_native = native_layouts(result, opts.mapping)
        self.records.append(
            EpisodeRecord(
                episode_index=index,
                source=key,
                split=split,
                length=result.num_frames,
                hand_type=result.hand_type,
                origin=dict(result.source_episode),
                # mixed hand models: this episode decodes with its own layouts
                native_layouts=own_native if own_native != self.native else {},
            )
        )
        if split == "test":
            self.test_episodes.append(index)
        for h in result.hands:
            self.hands_seen[h] = None
        self.synthetic |= result.synthetic
        self.counts["trimmed_frames"] += result.trimmed_frames
        self.counts["absent_hand_frames"] += result.absent_hand_frames
        if result.zero_hand_sides:
            self.zero_hands.append(f"{key} ({', '.join(result.zero_hand_sides)})")
        if result.extra.get("timestamp_note"):
            self.timestamp_notes.append(f"{key}: {result.extra['timestamp_note']}")
        self.source_notes += [f"{key}: {note}" for note in result.extra.get("source_notes", ())]

    def finish(self, opts: ConvertOptions, reader_cls: type, plan: _Plan) -> ConversionRecord:
        total = self.writer.num_episodes
        self.writer.finalize(splits={"train": f"0:{total}"})  # LeRobot's own convention: one range, all episodes
        sides, with_action, passthrough, copied, videos = self.signature
        record = ConversionRecord(
            source=opts.source,
            license=getattr(reader_cls, "license", "unknown"),
            description=getattr(reader_cls, "description", ""),
            source_options=opts.source_options,
            robot_type=self.robot_type,
            synthetic=self.synthetic,
            mapping=opts.mapping,
            on_error=opts.on_error,
            keep=opts.keep,
            fps=self.fps,
            test_fraction=opts.test_fraction,
            split_method=SPLIT_METHOD,
            shard=f"{opts.shard_index}/{opts.num_shards}",
            max_episodes=opts.max_episodes,
            sides=list(sides),
            hands=list(self.hands_seen),
            has_action=with_action,
            passthrough={k: list(names) for k, names in passthrough},
            copied_features=list(copied),
            video_features=list(videos),
            listed_episodes=plan.num_listed,
            skipped_episodes=len(self.failures),
            trimmed_frames=self.counts["trimmed_frames"],
            absent_hand_frames=self.counts["absent_hand_frames"],
            zero_hand_episodes=len(self.zero_hands),
            num_episodes=total,
            test_episodes=self.test_episodes,
            native_layouts=self.native,
            episodes=self.records,
            wrist_frame=kept_wrist_frame(plan.wrist_frame, self.hands_seen, dict(passthrough)),
        )
        write_record(self.writer.root, record)
        return record


def _refuse_dropped_sides(ep: UdhmEpisode, sides: tuple[str, ...]) -> None:
    """`--sides` orders the blocks; it does not choose hands. An episode holding a side it leaves out is a setup
    error, not a bad episode: `--on_error=skip` would skip every episode that has that hand."""
    dropped = [s for s in ep.sides if s not in sides]
    if dropped:
        every = ",".join([*sides, *dropped])
        raise SetupError(
            f"--sides={','.join(sides)} leaves out the {'/'.join(dropped)} hand that {ep.source_file} holds: --sides "
            f"orders the blocks of every hand the source has, it does not choose hands (and --on_error=skip would "
            f"skip every episode with that hand). Pass --sides={every}, or leave it unset; to convert only the "
            f"{'/'.join(sides)} hand, name only it in the source's options (the lerobot source: "
            f"--source_options='{{\"hands\": {{\"{sides[0]}\": \"<hand spec>:<column prefix>\"}}}}')"
        )


def _signature_difference(ep: UdhmEpisode, fps: int, signature: tuple, signature_fps: int) -> str:
    names = ("hand sides", "actions", "passthrough columns", "copied features", "videos")
    diffs = [f"{n} {a} vs {b}" for n, a, b in zip(names, ep.signature, signature, strict=True) if a != b]
    if fps != signature_fps:
        diffs.append(f"fps {fps} vs {signature_fps}")
    hint = (
        "; for a source whose episodes are left or right hands pass --sides=right,left"
        if ep.signature[0] != signature[0]
        else ""
    )
    if fps != signature_fps:
        hint += f"; pass --fps={signature_fps} to resample time-stamped sources (bags, keypoint files) onto one grid"
    return f"episode differs from the dataset's (set by its first episode): {'; '.join(diffs)}{hint}"


def format_failures(failures: list[EpisodeFailure], limit: int = 50) -> str:
    lines = [f"  {f.source_file}: {f.reason}" for f in failures[:limit]]
    if len(failures) > limit:
        lines.append(f"  ... and {len(failures) - limit} more")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# shards
# ---------------------------------------------------------------------------------------------
def merge_shards(
    shard_roots: list[str | Path],
    root: str | Path,
    repo_id: str = "local/udhm",
    overwrite: bool = False,
) -> Path:
    """Aggregate shard datasets (in shard order) with LeRobot's `aggregate_datasets`; merge the records.

    Shards are contiguous slices of one source-ordered list, so concatenating them in shard order gives
    the single-run dataset; episode indices in the records and test lists are offset by the episodes
    of the shards before.
    """
    from lerobot.datasets.aggregate import aggregate_datasets

    target = Path(root).expanduser().resolve()
    shard_roots = [Path(r) for r in shard_roots]
    shard_records = [load_record(r) for r in shard_roots]
    missing = [str(r) for r, rec in zip(shard_roots, shard_records, strict=True) if rec is None]
    if missing:
        raise InvalidInputError(f"not converted shards (no {CONVERSION_PATH}): {missing}")
    claim(target, Kind.CONVERTED, inputs=shard_roots, overwrite=overwrite)
    tmp = temp_sibling(target)
    try:
        aggregate_datasets(
            repo_ids=[f"{repo_id}_shard{k}" for k in range(len(shard_roots))],
            aggr_repo_id=repo_id,
            roots=shard_roots,
            aggr_root=tmp,
        )
        _restate_bookkeeping_stats(tmp)
        path = tmp / INFO_PATH
        info = json.loads(path.read_text())
        total = int(info["total_episodes"])
        info["splits"] = {"train": f"0:{total}"}
        path.write_text(json.dumps(info, indent=4))
        offset, episodes, test = 0, [], []
        base = shard_records[0].native_layouts
        for rec in shard_records:
            for e in rec.episodes:
                # an episode decodes with its own layouts, else its shard's: the merged dataset keeps shard 0's
                own = e.native_layouts or (rec.native_layouts if rec.native_layouts != base else {})
                episodes.append(dataclasses.replace(e, episode_index=e.episode_index + offset, native_layouts=own))
            test += [i + offset for i in rec.test_episodes]
            offset += rec.num_episodes
        if offset != total:
            raise ValueError(f"shard records count {offset} episodes, the merged dataset {total}")
        record = dataclasses.replace(
            shard_records[0],
            shard=f"merged {len(shard_roots)} shards",
            skipped_episodes=sum(r.skipped_episodes for r in shard_records),
            trimmed_frames=sum(r.trimmed_frames for r in shard_records),
            absent_hand_frames=sum(r.absent_hand_frames for r in shard_records),
            zero_hand_episodes=sum(r.zero_hand_episodes for r in shard_records),
            hands=sorted({h for r in shard_records for h in r.hands}),
            synthetic=any(r.synthetic for r in shard_records),
            num_episodes=total,
            episodes=episodes,
            test_episodes=test,
        )
        write_record(tmp, record)
        write_card(
            tmp,
            repo_id=repo_id,
            record=record,
            num_frames=int(info["total_frames"]),
            features=info["features"],
        )
        move_into_place(tmp, target, Kind.CONVERTED, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        release(target)
        raise
    return target


BOOKKEEPING_KEYS = ("index", "episode_index", "task_index")


def _restate_bookkeeping_stats(root: Path) -> None:
    """meta/stats.json of `index`, `episode_index`, `task_index` from the merged per-episode stats.

    LeRobot 0.6.1's `aggregate_datasets` re-numbers these columns and shifts their per-episode stats in
    meta/episodes, but writes meta/stats.json from the shards' own stats.json, which describe the
    shard-local numbers (a 2-shard merge had index mean 54 instead of 108). Aggregating the corrected
    per-episode stats once, as a single-run conversion does, gives the single-run values.
    """
    import pyarrow.parquet as pq
    from lerobot.datasets.compute_stats import aggregate_stats
    from lerobot.datasets.io_utils import load_stats, write_stats

    stats = load_stats(root) or {}
    keys = [k for k in BOOKKEEPING_KEYS if k in stats]
    if not keys:
        return
    files = sorted(root.glob(EPISODES_META_GLOB))
    names = [f"stats/{k}/{n}" for k in keys for n in stats[k]]
    table = pq.read_table(files, columns=names)
    # each cell is a one-value list (scalar features): (E, 1) per column
    values = {c: table.column(c).combine_chunks().flatten().to_numpy().reshape(table.num_rows, 1) for c in names}
    per_episode = [{k: {n: values[f"stats/{k}/{n}"][e] for n in stats[k]} for k in keys} for e in range(table.num_rows)]
    if per_episode:
        stats.update(aggregate_stats(per_episode))
        write_stats(stats, root)
