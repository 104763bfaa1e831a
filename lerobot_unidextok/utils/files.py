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


def replace_folder(tmp: Path, target: Path) -> None:
    """Rename the finished folder `tmp` to `target`. An existing `target` is renamed aside first and deleted
    after, so `target` is always either the old folder or the new one, never half of each."""
    if target.exists():  # the pid lets a later run remove it if this one dies between the renames
        old = target.parent / f".{target.name}.old-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        target.rename(old)
        tmp.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(target)


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
