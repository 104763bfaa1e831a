"""Writing results safely: a finished folder moved into place in one step, results as plain JSON, cache keys."""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import shutil
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np


def temp_sibling(target: Path) -> Path:
    """A fresh hidden folder name beside `target` to write into, named per run: this process's id (so a later run
    can tell a dead writer's leftovers from a live one's) and a random part (so two runs, or two writers of one
    run, never share one)."""
    return target.parent / f".{target.name}{_TMP}{_run_tag()}"


def temp_file_sibling(path: Path) -> Path:
    """`temp_sibling` for a file: `.<stem>.tmp-<pid>-<random><suffix>` beside `path` (the suffix kept, for writers
    that pick a format by it)."""
    return path.parent / f".{path.stem}{_TMP}{_run_tag()}{path.suffix}"


def replace_folder(tmp: Path, target: Path) -> None:
    """Rename the finished folder `tmp` to `target`. An existing `target` is renamed aside first and deleted
    after, so `target` is always either the old folder or the new one, never half of each. A kill between the
    two renames leaves `target` missing, the old folder aside and the new one finished: `recover_folder`
    puts the old one back."""
    if target.exists():  # named with the tag (pid and random part) of `tmp`: the two folders of one replacement
        prefix = f".{target.name}{_TMP}"
        tag = tmp.name[len(prefix):] if tmp.name.startswith(prefix) else _run_tag()
        old = target.parent / f".{target.name}{_OLD}{tag}"
        target.rename(old)
        tmp.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(target)


@dataclass(frozen=True)
class Leftover:
    """A hidden folder a writer of `target` left beside it: `.<target>.tmp-<pid>-<random>` (what it was writing)
    or `.<target>.old-<pid>-<random>` (the old `target`, set aside while it replaced it)."""

    path: Path
    pid: int
    set_aside: bool  # an `.old-` folder (else a `.tmp-` one)

    @property
    def running(self) -> bool:
        """Whether its writer still runs (`writer_running`)."""
        return writer_running(self.pid, self.path)


def leftovers(target: Path) -> list[Leftover]:
    """The temp and set-aside folders of writers of exactly `target`: names that start with `.<target name>.tmp-`
    or `.old-` followed by nothing but `<pid>` or `<pid>-<hex>`. Keyed by the exact name, never a glob: a root
    named `ds[1]` finds `.ds[1].old-*` and never `.ds1.old-*`; `ds` never takes `ds.v2`'s or `ds.old-3`'s."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    found = []
    for marker, set_aside in ((_TMP, False), (_OLD, True)):
        prefix = f".{target.name}{marker}"
        for path in target.parent.iterdir():
            match = _RUN_TAG.fullmatch(path.name[len(prefix):]) if path.name.startswith(prefix) else None
            if match is not None and path.is_dir():
                found.append(Leftover(path, int(match[1]), set_aside))
    return sorted(found, key=lambda x: x.path.name)


def live_writers(target: Path) -> list[Leftover]:
    """Leftovers of `target` whose writer is another process that still runs: `target` is being written now."""
    return [x for x in leftovers(target) if x.pid != os.getpid() and x.running]


def recover_folder(target: Path) -> list[str]:
    """Tidy what dead writers of `target` left beside it (`leftovers`), and say what was done, one line each.

    - An old folder set aside by a dead writer while `target` is missing or an empty folder (a script's
      `mkdir -p` after the kill): that writer was killed between the two renames of `replace_folder`, so this is
      `target` as it was: renamed back, never deleted. The new folder that writer had finished (its temp
      folder, same pid) is kept beside it as `<target>.unfinished-<pid>` (a free name: `-2`, `-3`... when taken),
      for the user to keep or delete.
    - An old folder set aside by a dead writer while `target` holds something and no temp folder of that writer
      (same pid) is left: the replacement happened and only the deletion it asked for was cut short: deleted.
    - An old folder of a dead writer whose temp folder is still there while `target` holds something else: the
      replacement never happened and something else took the name; nothing is deleted: both are made visible
      (`<target>.set-aside-<pid>`, `<target>.unfinished-<pid>`) and named.
    - A dead writer's temp folder otherwise: a write cut short, half done: deleted.
    - An old folder whose writer still runs (`writer_running`): a replacement under way, or a writer that hangs
      between its renames: left alone and named, with what to do.
    A rename or deletion that fails (a read-only folder) is named, never raised."""
    target = Path(target)
    notes: list[str] = []
    found = leftovers(target)
    dead = [x for x in found if x.pid == os.getpid() or not x.running]
    olds = sorted((x for x in dead if x.set_aside), key=lambda x: x.path.stat().st_mtime)
    tmps = [x for x in dead if not x.set_aside]
    kept: set[Path] = set()

    def keep_visible(tmp: Leftover, label: str) -> None:
        visible = _free_name(target.parent, f"{target.name}.{label}-{tmp.pid}")
        if _try(notes, tmp.path.rename, visible):
            kept.add(tmp.path)
            notes.append(f"{visible}: what that run had written to replace {target.name} (kept; delete it if you do "
                         "not need it)")  # fmt: skip

    if olds and _missing_or_empty(target):
        old = olds.pop()
        if target.is_dir():
            _try(notes, target.rmdir)
        if _try(notes, old.path.rename, target):
            notes.append(f"{target} restored: a run (pid {old.pid}) was killed while replacing it, and had set it "
                         "aside")  # fmt: skip
            for tmp in (t for t in tmps if t.pid == old.pid):
                keep_visible(tmp, "unfinished")
    for old in olds:
        mine = [t for t in tmps if t.pid == old.pid and t.path not in kept]
        if not mine:
            if _try(notes, shutil.rmtree, old.path):
                notes.append(f"removed {old.path.name}: the folder an earlier run replaced {target.name} with is in "
                             "place, only the deletion of the old one had been cut short")  # fmt: skip
            continue
        visible = _free_name(target.parent, f"{target.name}.set-aside-{old.pid}")
        if _try(notes, old.path.rename, visible):
            notes.append(f"{visible}: {target.name} as it was before a run (pid {old.pid}) was killed while replacing "
                         f"it; {target} now holds something else, so both are kept: keep what you need, delete the "
                         "rest")  # fmt: skip
        for tmp in mine:
            keep_visible(tmp, "unfinished")
    for tmp in tmps:
        if tmp.path not in kept and tmp.path.exists() and _try(notes, shutil.rmtree, tmp.path):
            notes.append(f"removed {tmp.path.name}: the unfinished output of a run that was killed (pid {tmp.pid})")
    for old in (x for x in found if x.set_aside and x not in dead):
        notes.append(f"{old.path} is {target.name} set aside by pid {old.pid}, which still runs (it started before "
                     f"the folder was set aside): left alone; if pid {old.pid} is not replacing {target.name} (the "
                     f"folder came from another machine or container), put it back: "
                     f"mv '{old.path}' '{target}'")  # fmt: skip
    return notes


_TMP, _OLD = ".tmp-", ".old-"
_RUN_TAG = re.compile(r"(\d+)(?:-[0-9a-f]+)?")  # what follows `.tmp-` / `.old-`: <pid>[-<random hex>]
START_SLACK_S = 1.0  # a process that started this much after a leftover's last change cannot be its writer


def _run_tag() -> str:
    return f"{os.getpid()}-{uuid.uuid4().hex[:8]}"


def _missing_or_empty(target: Path) -> bool:
    return not target.exists() or (target.is_dir() and not target.is_symlink() and not any(target.iterdir()))


def _free_name(parent: Path, name: str) -> Path:
    """`parent/name`, or `name-2`, `name-3`... the first that does not exist."""
    path, n = parent / name, 1
    while path.exists() or path.is_symlink():
        n += 1
        path = parent / f"{name}-{n}"
    return path


def _try(notes: list[str], action, *args) -> bool:
    """Run one rename or deletion of the recovery; a failure becomes a note (the recovery never raises)."""
    try:
        action(*args)
    except OSError as exc:
        notes.append(f"could not tidy {args[0]}: {exc.strerror or exc}; left as it is")
        return False
    return True


def writer_running(pid: int, leftover: Path) -> bool:
    """Whether the process that left `leftover` (named with `pid`) still runs.

    A pid is reused once its process has ended, so "a process `pid` runs" is not enough. The writer ran when it
    last changed `leftover` (its status-change time, ctime, which a rename or a new entry sets), and two processes
    never hold one pid at the same time: so a process `pid` that started before that time IS the writer, and one
    that started after it (by more than `START_SLACK_S`, the clocks' granularity) is a later process that reused
    the pid, and the writer is gone. When the start time cannot be read (no /proc), a live pid counts as the
    writer: left alone and reported, never deleted."""
    if not process_alive(pid):
        return False
    started = process_start_s(pid)
    if started is None:
        return True
    try:
        changed = leftover.lstat().st_ctime
    except OSError:
        return True
    return started <= changed + START_SLACK_S


def process_start_s(pid: int) -> float | None:
    """When process `pid` started, in seconds since the epoch (Linux /proc; None elsewhere or when it is gone).
    /proc/<pid>/stat gives it in clock ticks since boot (CLOCK_BOOTTIME); the boot time is now minus that clock."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        ticks = int(stat.rsplit(")", 1)[1].split()[19])  # field 22, counted after the name in parentheses
        boot_s = time.time() - time.clock_gettime(time.CLOCK_BOOTTIME)
        return boot_s + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError, AttributeError):
        return None


def process_alive(pid: int) -> bool:
    """Whether process `pid` runs (signal 0: probed, nothing delivered; 0 and below name process groups, not a
    process)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except (OverflowError, OSError):
        return False
    return True


def jsonable(x):
    """`x` with numpy scalars and arrays as Python numbers and lists, NaN as None, paths and dict keys as strings."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if math.isnan(float(x)) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, Path):
        return str(x)
    return x


def fingerprint(*parts) -> str:
    """12 hex digits of one sha1 over `parts` (bytes as they are, numpy arrays by their bytes, anything else
    as sorted JSON): the key of a cache folder, the same for the same inputs."""
    h = hashlib.sha1()
    for p in parts:
        if isinstance(p, bytes):
            h.update(p)
        elif isinstance(p, np.ndarray):
            h.update(p.tobytes())
        else:
            h.update(json.dumps(p, sort_keys=True, default=str).encode())
    return h.hexdigest()[:12]
