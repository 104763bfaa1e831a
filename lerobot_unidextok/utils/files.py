"""Writing results safely: a finished folder moved into place in one step, results as plain JSON, cache keys."""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import uuid
from pathlib import Path

import numpy as np


def temp_sibling(target: Path) -> Path:
    """A fresh hidden folder name beside `target` to write into, carrying this process's id (so a later run
    can tell a dead writer's leftovers from a live one's)."""
    return target.parent / f".{target.name}{_TMP}{os.getpid()}-{uuid.uuid4().hex[:8]}"


def replace_folder(tmp: Path, target: Path) -> None:
    """Rename the finished folder `tmp` to `target`. An existing `target` is renamed aside first and deleted
    after, so `target` is always either the old folder or the new one, never half of each. A kill between the
    two renames leaves `target` missing, the old folder aside and the new one finished: `recover_folder`
    puts the old one back."""
    if target.exists():  # the pid lets a later run tell whether this one is gone
        old = target.parent / f".{target.name}{_OLD}{os.getpid()}-{uuid.uuid4().hex[:8]}"
        target.rename(old)
        tmp.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(target)


def recover_folder(target: Path) -> list[str]:
    """Tidy what dead writers of `target` left beside it, and say what was done (one line per action).

    - An old folder set aside by a dead writer while `target` is missing: that writer was killed between the
      two renames of `replace_folder`, so this is `target` as it was: renamed back, never deleted. The new
      folder it had finished (its hidden temp folder) is kept beside it as `<target>.unfinished-<pid>`, for
      the user to keep or delete.
    - An old folder set aside by a dead writer while `target` exists: the replacement happened and only the
      deletion it asked for was cut short: deleted.
    - A dead writer's temp folder otherwise: a write cut short, half done: deleted.
    Folders of live processes are left alone (a run writing there now)."""
    target = Path(target)
    if not target.parent.is_dir():
        return []
    notes: list[str] = []
    leftovers = [(p, _writer_pid(p, _OLD)) for p in target.parent.glob(f".{target.name}{_OLD}*")]
    olds = sorted((p for p, pid in leftovers if _dead(pid)), key=lambda p: p.stat().st_mtime)
    tmps = [(p, _writer_pid(p, _TMP)) for p in target.parent.glob(f".{target.name}{_TMP}*")]
    if olds and not target.exists():
        old = olds.pop()
        pid = _writer_pid(old, _OLD)
        old.rename(target)
        notes.append(f"{target} restored: a run (pid {pid}) was killed while replacing it, and had set it aside")
        for tmp in [p for p, p_pid in tmps if p_pid == pid]:
            kept = target.parent / f"{target.name}.unfinished-{pid}"
            tmp.rename(kept)
            notes.append(f"{kept}: what that run had written to replace it (kept; delete it if you do not need it)")
    for old in olds:
        shutil.rmtree(old, ignore_errors=True)
        notes.append(f"removed {old.name}: the folder an earlier run replaced {target.name} with is in place, only "
                     "the deletion of the old one had been cut short")  # fmt: skip
    for tmp, pid in tmps:
        if tmp.exists() and _dead(pid):
            shutil.rmtree(tmp, ignore_errors=True)
            notes.append(f"removed {tmp.name}: the unfinished output of a run that was killed (pid {pid})")
    return notes


_TMP, _OLD = ".tmp-", ".old-"


def _dead(pid: int | None) -> bool:
    """A leftover's writer is gone: no such process, or this one (its own leftovers are from an earlier, failed
    attempt of this same run)."""
    return pid is not None and (pid == os.getpid() or not process_alive(pid))


def _writer_pid(path: Path, marker: str) -> int | None:
    try:
        return int(path.name.rsplit(marker, 1)[1].split("-")[0])
    except (IndexError, ValueError):
        return None


def process_alive(pid: int) -> bool:
    """Whether process `pid` runs (signal 0: probed, nothing delivered)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
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
