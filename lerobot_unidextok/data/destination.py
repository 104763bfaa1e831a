"""Where a command writes: one owner for every writer's destination.

Every writer (`unidextok-convert` and its shard merge and `--executor.logging_dir`, `unidextok-mix`,
`unidextok-train`'s run folder, `unidextok-eval`'s report, `unidextok-deploy`, `unidextok-view`,
`unidextok-sim-record`) calls `claim` (a folder) or `claim_files` (files) before it writes or deletes anything,
and after it has checked its other inputs and flags:

- what dead writers left beside the destination is tidied first (`utils.files.recover_folder`: a folder set
  aside by a run killed between the two renames of a replacement is restored, never deleted), and said;
- a destination that is, holds or sits inside one of the command's inputs is refused;
- a destination inside a dataset or a checkpoint is refused: their files are one unit that other tools read
  whole (a report written as `<dataset>/meta/stats.json` replaces the dataset's statistics);
- a destination that cannot be made is refused up front, before the work: a file where a parent folder should
  be, a parent folder this process may not write (read-only, no permission);
- a destination another run is writing now (a live writer's temp or set-aside folder beside it,
  `utils.files.live_writers`) is refused, naming that run's pid;
- a folder destination is then locked for this run (`.<name>.lock` beside it, an exclusive `fcntl.flock` the
  kernel drops when the process ends): a second writer that starts while the first still reads its inputs, before
  any temp folder exists, is refused as it starts, naming the first's pid, not after its own whole run. The lock
  is released when the writer moves its output into place or fails (`release`), or when the process exits; a
  lock file left by a killed run is taken over, with a note naming its pid;
- an existing destination is refused, unless it holds what this writer writes and the user asked to replace
  it (`--overwrite=true`; `unidextok-train --resume=true` continues its own run). A converted dataset is not a
  mix, a mix is not a converted dataset, a folder of other files is neither. A writer recognises its own by
  what it leaves: a dataset's `meta/info.json` and conversion record, a checkpoint's `config.json` and weights,
  a run folder's `best/`/`last/`, a conversion logging folder's `run_settings.json` (`LOGGING_MARKER`).

Folder writers then write into `utils.files.temp_sibling(target)` and move it into place with
`utils.files.replace_folder`, so the destination is always whole: the old one or the new one.
"""

from __future__ import annotations

import atexit
import fcntl
import json
import logging
import os
import shutil
from enum import StrEnum
from pathlib import Path

from lerobot_unidextok.constants import CONVERSION_PATH, INFO_PATH
from lerobot_unidextok.data.record import RecordError, load_record
from lerobot_unidextok.errors import ExistingOutputError
from lerobot_unidextok.utils.files import live_writers, recover_folder, replace_folder

logger = logging.getLogger(__name__)

MIX_SOURCE = "mix"  # the `source` of a mixed dataset's conversion record


class DestinationError(ExistingOutputError):
    """The destination cannot be written as asked; the message names what is there and the fix."""


class Kind(StrEnum):
    """What a folder holds, as far as the writers are concerned."""

    CONVERTED = "a dataset written by unidextok-convert"
    MIX = "a mixed dataset written by unidextok-mix"
    DATASET = "a LeRobot dataset"
    TOKENIZER = "a tokenizer checkpoint"
    TOKENIZER_RUN = "a unidextok-train run folder"
    POLICY = "a policy checkpoint"
    LOGGING = "a unidextok-convert logging folder (--executor.logging_dir)"


# folders whose files are one unit: nothing is written inside them
UNITS = (Kind.CONVERTED, Kind.MIX, Kind.DATASET, Kind.TOKENIZER, Kind.POLICY)
RUN_FILES = ("best", "last", "eval.json", "row_store", "folds")  # what a unidextok-train run folder holds
# the file a sharded conversion leaves in its logging folder: its settings (the resume guard), with these keys
LOGGING_MARKER, LOGGING_MARKER_KEYS = "run_settings.json", ("executor", "num_shards", "root")


def kind_of(folder: Path) -> Kind | None:
    """What `folder` holds (None: nothing a writer of this package recognises, or not a folder)."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    if (folder / INFO_PATH).is_file():
        if not (folder / CONVERSION_PATH).is_file():
            return Kind.DATASET
        try:
            record = load_record(folder)
        except RecordError:  # ours, but its record is damaged: still not something another writer may take
            return Kind.CONVERTED
        return Kind.MIX if record is not None and record.source == MIX_SOURCE else Kind.CONVERTED
    if (folder / "config.json").is_file() and (folder / "model.safetensors").is_file():
        return Kind.POLICY if (folder / "policy_preprocessor.json").is_file() else Kind.TOKENIZER
    if _is_logging_folder(folder):
        return Kind.LOGGING
    if any((folder / name).exists() for name in RUN_FILES):
        return Kind.TOKENIZER_RUN
    return None


def _is_logging_folder(folder: Path) -> bool:
    try:
        settings = json.loads((folder / LOGGING_MARKER).read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(settings, dict) and all(key in settings for key in LOGGING_MARKER_KEYS)


def recover(target: str | Path) -> Path:
    """Put back what a dead writer of `target` left half-replaced, and say so (`utils.files.recover_folder`);
    `claim` does it first, and a writer that reads its inputs before it claims calls it at its start, so a
    failing run never leaves the destination missing. Returns `target` resolved."""
    target = Path(target).expanduser().resolve()
    for note in recover_folder(target):
        logger.warning(note)
    return target


def enclosing_unit(path: Path) -> tuple[Path, Kind] | None:
    """The nearest folder above `path` that is a dataset or a checkpoint, if any."""
    for parent in Path(path).expanduser().resolve().parents:
        kind = kind_of(parent)
        if kind in UNITS:
            return parent, kind
    return None


def claim(target: str | Path, writes: Kind, *, inputs: list[Path] | tuple[Path, ...] = (), overwrite: bool = False,
          resume: bool = False, flag: str = "--root") -> Path:  # fmt: skip
    """Check that this writer may write the folder `target` and lock it for this process (module docstring);
    returns it resolved.

    `writes`: the kind this writer produces; `overwrite`: the user asked to replace an existing one of that
    kind; `resume`: continue into an existing one (training); `flag`: the option that named `target`, for the
    messages."""
    target = recover(target)
    _refuse_inputs(target, inputs, flag)
    _refuse_inside_a_unit(target, f"{flag} {target}", flag)
    _refuse_unwritable(target, flag, inside=resume)
    _refuse_live_writers(target, flag)
    _refuse_existing(target, writes, overwrite, resume, flag)
    _lock(target, flag)
    return target


def _refuse_existing(target: Path, writes: Kind, overwrite: bool, resume: bool, flag: str) -> None:
    if not target.exists():
        return
    if not target.is_dir():
        raise DestinationError(f"{flag} {target} is a file, not a folder: choose another {flag}")
    there = kind_of(target)
    if there is None and not any(target.iterdir()):
        return  # an empty folder (made by the user beforehand) is as good as none
    if there != writes:
        what = there.value if there is not None else "other files"
        raise DestinationError(
            f"{flag} {target} holds {what}, not {writes.value}: nothing is replaced there "
            f"(--overwrite=true only replaces {writes.value}); choose another {flag}"
        )
    if resume or overwrite:
        return
    fix = "--resume=true to continue it, --overwrite=true to replace it" if writes is Kind.TOKENIZER_RUN else (
        "--overwrite=true to replace it")  # fmt: skip
    raise DestinationError(f"{flag} {target} already holds {writes.value}: pass {fix}, or choose another {flag}")


# ---------------------------------------------------------------------------------------------
# the lock of a destination being written
# ---------------------------------------------------------------------------------------------
_HELD: dict[Path, tuple[int, Path]] = {}  # destination -> (open lock file descriptor, lock file) of this process
_OWNER_PID = os.getpid()  # the process whose locks _HELD holds (a forked child inherits the dict, not the locks' use)


def lock_path(target: Path) -> Path:
    """The lock file of the destination `target`: `.<name>.lock` beside it."""
    return target.parent / f".{target.name}.lock"


def _lock(target: Path, flag: str) -> None:
    """Take the lock of `target` for this process (module docstring), or refuse naming the run that holds it.
    Taken again by the process that holds it, it is held once."""
    if target in _HELD:
        return
    path = lock_path(target)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise DestinationError(
                f"{flag} {target} is being written by another run now: pid {holder} (it holds {path}); wait for it "
                f"to end, or choose another {flag}"
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:  # released (and removed) by its holder between our open and our lock
            same = False
        if same:
            break
        os.close(fd)  # locked a file its holder had just removed: lock the one at `path` now
    left = os.pread(fd, 64, 0).decode(errors="replace").strip()
    if left and left != str(os.getpid()):
        logger.warning("%s: took over the lock of pid %s, a run that ended without releasing it", path, left)
    os.ftruncate(fd, 0)
    os.pwrite(fd, str(os.getpid()).encode(), 0)
    _HELD[target] = (fd, path)


def release(target: str | Path) -> None:
    """Release this process's lock of the destination `target` and remove its lock file (nothing when it holds
    none). Writers call it when their output is in place or they failed; the rest are released at exit."""
    held = _HELD.pop(Path(target).expanduser().resolve(), None)
    if held is None:
        return
    fd, path = held
    try:
        path.unlink(missing_ok=True)  # while still locked: a writer waiting on this file locks a fresh one
    finally:
        os.close(fd)


@atexit.register
def _release_all() -> None:
    """At exit, the locks this process took (a forked child that ran its parent's exit handlers would otherwise
    remove the lock files its parent still holds)."""
    if os.getpid() != _OWNER_PID:
        return
    for target in list(_HELD):
        release(target)


def move_into_place(tmp: Path, target: Path, writes: Kind, overwrite: bool) -> None:
    """Rename the finished folder `tmp` to `target` (`utils.files.replace_folder`), after checking again that
    nothing else appeared at `target` while this writer worked (then `tmp` is removed and nothing replaced)."""
    if target.exists() and not (overwrite and kind_of(target) == writes) and any(target.iterdir()):
        shutil.rmtree(tmp, ignore_errors=True)
        raise DestinationError(f"{target} appeared while writing; nothing was written there: choose another place")
    if target.is_dir() and not any(target.iterdir()):
        target.rmdir()  # an empty folder made beforehand: replaced by the finished one
    replace_folder(tmp, target)
    release(target)


def claim_files(paths: list[Path], *, inputs: list[Path] | tuple[Path, ...] = (), flag: str = "--output",
                is_ours=None) -> list[Path]:  # fmt: skip
    """Check that a writer of the files `paths` (a report, a video) may write them: not an input, not inside a
    dataset or a checkpoint, and an existing file only when `is_ours(path)` says this writer wrote it (it is
    then rewritten, as a report is). Returns the paths resolved."""
    out = []
    for path in paths:
        path = Path(path).expanduser().resolve()
        _refuse_inputs(path, inputs, flag)
        _refuse_inside_a_unit(path, f"{flag} would write {path}, which", flag)
        _refuse_unwritable(path, flag, inside=True)  # an earlier report is rewritten in place
        _refuse_live_writers(path, flag)
        if path.is_dir():
            raise DestinationError(f"{flag} would write {path}, which is a folder: choose another {flag}")
        if path.exists() and not (is_ours is not None and is_ours(path)):
            raise DestinationError(
                f"{flag} would replace {path}, a file this command did not write: choose another {flag}"
            )
        out.append(path)
    return out


def is_json_with(*keys: str):
    """An `is_ours` for `claim_files`: a JSON object file holding all of `keys`."""

    def check(path: Path) -> bool:
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, UnicodeDecodeError, ValueError):
            return False
        return isinstance(data, dict) and all(k in data for k in keys)

    return check


def _refuse_inside_a_unit(path: Path, what: str, flag: str) -> None:
    unit = enclosing_unit(path)
    if unit is not None:
        raise DestinationError(
            f"{what} sits inside {unit[1].value} ({unit[0]}), whose files other tools read as one unit: choose a "
            f"{flag} outside it"
        )


def _refuse_unwritable(target: Path, flag: str, inside: bool = False) -> None:
    """Refuse, before the work, a `target` whose parent folder cannot be made or written: the nearest existing
    folder above it is a file, or this process may not create entries in it (`os.access`: a read-only file
    system, no permission). `inside`: the writer also writes an existing `target` itself (a resumed run's folder,
    a report rewritten in place)."""
    parent = target.parent
    while not parent.exists() and not parent.is_symlink() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise DestinationError(
            f"{flag} {target} cannot be made: {parent} is a file, not a folder; choose another {flag}"
        )
    for path in [parent] + ([target] if inside and target.exists() else []):
        if not os.access(path, os.W_OK | (os.X_OK if path.is_dir() else 0)):
            raise DestinationError(
                f"{flag} {target} cannot be written: {path} is read-only or not writable by this user; choose "
                f"another {flag}, or make {path} writable"
            )


def _refuse_live_writers(target: Path, flag: str) -> None:
    busy = live_writers(target)
    if busy:
        what = ", ".join(f"pid {x.pid} ({x.path.name})" for x in busy)
        raise DestinationError(
            f"{flag} {target} is being written by another run now: {what}; wait for it to end, or choose another "
            f"{flag} (if that pid is not writing here, as when the folder came from another machine or container, "
            "move it out of the way)"
        )


def _refuse_inputs(target: Path, inputs, flag: str) -> None:
    for source in inputs:
        source = Path(source).expanduser().resolve()
        if target == source or source.is_relative_to(target) or target.is_relative_to(source):
            raise DestinationError(
                f"{flag} {target} is, holds or sits inside the input {source}: writing there would change the "
                f"input; choose another {flag}"
            )


__all__ = ["LOGGING_MARKER", "MIX_SOURCE", "UNITS", "DestinationError", "Kind", "claim", "claim_files",
           "enclosing_unit", "is_json_with", "kind_of", "lock_path", "move_into_place", "recover", "release"]  # fmt: skip
