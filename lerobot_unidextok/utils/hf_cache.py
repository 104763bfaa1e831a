"""Find a LeRobot dataset by repo id on this machine, without any network access.

A dataset can be in three places, looked up in this order:

1. `$HF_LEROBOT_HOME/<repo_id>` (default `$HF_HOME/lerobot/<repo_id>`): datasets LeRobot created or
   copied there; what `LeRobotDataset(repo_id)` reads first.
2. the Hugging Face hub cache (`$HF_HUB_CACHE`, default `$HF_HOME/hub`): what `unidextok-pull
   --repo_type=dataset` and `huggingface_hub.snapshot_download` fill.
3. LeRobot's own snapshot cache `$HF_LEROBOT_HOME/hub` (a `LeRobotDataset(repo_id)` download).

In a hub cache, a repo lives in `datasets--<namespace>--<name>/` with `refs/<revision>` holding a commit
and `snapshots/<commit>/` the files (huggingface_hub's documented cache layout). LeRobot datasets are
pulled at tag `v3.0` (the codebase version LeRobot resolves), so that ref is tried before `main`.
"""

from __future__ import annotations

import os
from pathlib import Path

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.errors import MissingInputError

DATASET_REVISIONS = ("v3.0", "main")  # refs tried in a hub cache, in order


def hf_home() -> Path:
    return Path(os.environ.get("HF_HOME") or Path("~/.cache/huggingface")).expanduser()


def lerobot_home() -> Path:
    return Path(os.environ.get("HF_LEROBOT_HOME") or hf_home() / "lerobot").expanduser()


def hub_cache() -> Path:
    return Path(os.environ.get("HF_HUB_CACHE") or hf_home() / "hub").expanduser()


def cached_repo_snapshot(
    cache: Path, repo_id: str, repo_type: str = "dataset", revisions=DATASET_REVISIONS
) -> Path | None:
    """The snapshot folder of `repo_id` in hub cache `cache` for the first of `revisions` that is cached."""
    repo_dir = Path(cache) / f"{repo_type}s--{repo_id.replace('/', '--')}"
    for revision in revisions:
        ref = repo_dir / "refs" / revision
        commit = ref.read_text().strip() if ref.is_file() else revision  # a commit hash is its own snapshot name
        snapshot = repo_dir / "snapshots" / commit
        if snapshot.is_dir():
            return snapshot
    return None


def dataset_candidates(repo_id: str) -> list[Path]:
    """Where `repo_id` is looked for, in order (the first two hub caches resolved to their snapshot)."""
    places = [lerobot_home() / repo_id]
    for cache in (hub_cache(), lerobot_home() / "hub"):
        snapshot = cached_repo_snapshot(cache, repo_id)
        places.append(snapshot if snapshot is not None else cache / f"datasets--{repo_id.replace('/', '--')}")
    return places


def find_dataset(repo_id: str) -> Path | None:
    """The local folder of dataset `repo_id` (one holding meta/info.json), or None."""
    return next((p for p in dataset_candidates(repo_id) if (p / INFO_PATH).is_file()), None)


def dataset_root(repo_id: str) -> Path:
    """Like `find_dataset`, but a FileNotFoundError listing every place looked at and how to fill one."""
    root = find_dataset(repo_id)
    path = Path(repo_id).expanduser()
    if root is None and path.is_dir():
        raise MissingInputError(
            f"{path} is a folder but not a LeRobot dataset (no {INFO_PATH}): pass the root of a converted dataset "
            "(the --root of unidextok-convert)"
        )
    if root is None and (path.is_absolute() or repo_id.startswith((".", "~")) or repo_id.count("/") != 1):
        raise MissingInputError(
            f"dataset folder {path} does not exist: pass the root of a converted dataset (the --root of "
            "unidextok-convert) or a repo id 'namespace/name'"
        )
    if root is None:
        looked = "\n  ".join(str(p) for p in dataset_candidates(repo_id))
        raise MissingInputError(
            f"dataset {repo_id!r} is not on this machine; looked in\n  {looked}\n"
            f"Pull it with `unidextok-pull --repo_id={repo_id} --repo_type=dataset`, or pass the dataset folder "
            "instead of the repo id"
        )
    return root
