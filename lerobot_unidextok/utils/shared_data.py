"""Where the shared real recordings and robot URDFs live: one rule for the demo, `hands check`, the experiments,
the benchmarks and the tests.

`$UNIDEXTOK_REAL_DATA` / `$UNIDEXTOK_URDF_DIR` when set; otherwise `shared/data/real` / `shared/data/urdf` beside
the project folder (the checkout a command runs in: `../shared/data/...` seen from it). A pip user without that
folder gets a path that does not exist, and every caller treats that as "not here" (synthetic data, a skipped
test, a note naming the variable).
"""

from __future__ import annotations

import os
from pathlib import Path

REAL_DATA_ENV = "UNIDEXTOK_REAL_DATA"
URDF_DIR_ENV = "UNIDEXTOK_URDF_DIR"


def _shared(env: str, folder: str, project_root: str | Path | None) -> Path:
    explicit = os.environ.get(env, "").strip()
    if explicit:
        return Path(explicit).expanduser()
    root = Path.cwd() if project_root is None else Path(project_root)
    return root.resolve().parent / "shared" / "data" / folder


def real_data_dir(project_root: str | Path | None = None) -> Path:
    """The real recordings: `$UNIDEXTOK_REAL_DATA`, else `<project_root>/../shared/data/real` (`project_root`
    defaults to the current folder, the checkout when run from it). It may not exist."""
    return _shared(REAL_DATA_ENV, "real", project_root)


def urdf_dir(project_root: str | Path | None = None) -> Path:
    """The robot hands' URDFs: `$UNIDEXTOK_URDF_DIR`, else `<project_root>/../shared/data/urdf`. It may not exist."""
    return _shared(URDF_DIR_ENV, "urdf", project_root)


__all__ = ["REAL_DATA_ENV", "URDF_DIR_ENV", "real_data_dir", "urdf_dir"]
