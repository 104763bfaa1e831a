"""Where a conversion, a shard merge or a mix writes, and how nothing is lost on the way.

- `check_output`: a root that is, holds or sits inside an input is refused (the input would be replaced), and
  `--overwrite=true` replaces only a dataset this tool wrote (its `meta/unidextok_conversion.json`), never the
  raw recording at the default root nor a folder of other files.
- Everything is written into a temporary sibling folder (`temp_dir`) and renamed into place at the end
  (`move_into_place`; an old dataset is renamed aside first and deleted after). Temporary and set-aside
  folders carry the writing process's id, so the next run removes those of dead processes (`remove_stale`).
"""

from __future__ import annotations

import logging
import os
import shutil
import uuid
from pathlib import Path

from lerobot_unidextok.constants import CONVERSION_PATH, INFO_PATH
from lerobot_unidextok.errors import ExistingOutputError
from lerobot_unidextok.utils.files import replace_folder

logger = logging.getLogger(__name__)


class OutputError(ExistingOutputError):
    """The output folder cannot be written as asked; the message names why and the fix."""


def written_by_us(folder: Path) -> bool:
    """Whether `folder` is a dataset written by unidextok-convert / -mix (a LeRobot dataset with our record)."""
    return (folder / INFO_PATH).is_file() and (folder / CONVERSION_PATH).is_file()


def check_output(target: Path, inputs: list[Path], overwrite: bool) -> None:
    """Refuse a `target` that would replace an input or anything this tool did not write."""
    target = target.expanduser().resolve()
    for source in inputs:
        source = source.expanduser().resolve()
        if target == source or source.is_relative_to(target) or target.is_relative_to(source):
            raise OutputError(
                f"--root {target} is, holds or sits inside the input {source}: writing there would replace the input "
                "(the default --root is $HF_LEROBOT_HOME/<repo_id>); choose another --root"
            )
    if not target.exists():
        return
    ours = written_by_us(target)
    if not overwrite:
        raise OutputError(
            f"{target} already exists; "
            + ("pass --overwrite=true to replace this converted dataset, or " if ours else "")
            + "choose another --root"
        )
    if not ours:
        raise OutputError(
            f"{target} is not a dataset written by unidextok-convert or unidextok-mix (no {CONVERSION_PATH}), so "
            "--overwrite=true does not replace it: choose another --root"
        )


def temp_dir(target: Path) -> Path:
    """A fresh temporary folder name beside `target`, carrying this process's id."""
    return target.parent / f".{target.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"


def remove_stale(target: Path) -> None:
    """Delete temporary and set-aside folders of earlier runs on `target` whose process is gone (a kill -9,
    or a kill between the two renames of an overwrite)."""
    for path in [*target.parent.glob(f".{target.name}.tmp-*"), *target.parent.glob(f".{target.name}.old-*")]:
        try:
            pid = int(path.name.rsplit(".tmp-" if ".tmp-" in path.name else ".old-", 1)[1].split("-")[0])
        except (IndexError, ValueError):
            continue
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            logger.warning("removing the leftover folder of a dead run: %s", path)
            shutil.rmtree(path, ignore_errors=True)
        except PermissionError:
            pass


def move_into_place(tmp: Path, target: Path, overwrite: bool) -> None:
    """Rename the finished `tmp` to `target` (an existing target only with `overwrite`, checked again now)."""
    if target.exists() and not (overwrite and written_by_us(target)):
        shutil.rmtree(tmp, ignore_errors=True)
        raise OutputError(f"{target} appeared while writing; nothing was written there: choose another --root")
    replace_folder(tmp, target)


__all__ = ["OutputError", "check_output", "move_into_place", "remove_stale", "temp_dir", "written_by_us"]
