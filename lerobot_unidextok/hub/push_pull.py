"""Push tokenizer checkpoints / converted datasets to a Hub and pull them into the local HF cache.

Honours HF_ENDPOINT, HF_TOKEN, HF_HOME / HF_HUB_CACHE and HF_HUB_OFFLINE, read at call time.
huggingface_hub is imported lazily so `import lerobot_unidextok.hub` stays cheap.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

logger = logging.getLogger(__name__)

REPO_TYPES = ("model", "dataset")
DATASET_CODEBASE_TAG = "v3.0"  # LeRobot refuses dataset repos without a v3.x tag


def _endpoint(endpoint: str | None) -> str | None:
    return endpoint or os.environ.get("HF_ENDPOINT") or None


def _offline() -> bool:
    return os.environ.get("HF_HUB_OFFLINE", "0").upper() in ("1", "ON", "YES", "TRUE")


def _check_repo(repo_id: str, repo_type: str) -> None:
    if repo_type not in REPO_TYPES:
        raise ValueError(f"repo_type must be one of {REPO_TYPES}, got {repo_type!r}")
    if repo_id.count("/") != 1 or not all(repo_id.split("/")):
        raise ValueError(f"repo_id must look like 'namespace/name', got {repo_id!r}")


def detect_repo_type(local_dir: Path) -> str:
    """'dataset' for a LeRobotDataset folder (meta/info.json), 'model' for a checkpoint (config.json)."""
    if (local_dir / "meta" / "info.json").is_file():
        return "dataset"
    if (local_dir / "config.json").is_file():
        return "model"
    raise ValueError(
        f"{local_dir} is neither a LeRobotDataset (meta/info.json) nor a checkpoint (config.json); "
        "pass repo_type explicitly"
    )


def cache_dir() -> str | None:
    """HF_HUB_CACHE, else $HF_HOME/hub, else huggingface_hub's default (None)."""
    if os.environ.get("HF_HUB_CACHE"):
        return os.environ["HF_HUB_CACHE"]
    if os.environ.get("HF_HOME"):
        return str(Path(os.environ["HF_HOME"]) / "hub")
    return None


def push(
    local_dir: str | Path,
    repo_id: str,
    repo_type: str | None = None,
    private: bool = False,
    token: str | None = None,
    endpoint: str | None = None,
    training_data: list[str] | None = None,
    commit_message: str | None = None,
) -> str:
    """Upload a folder; returns the commit id.

    Models get a generated model card unless the folder already has README.md; datasets must be
    LeRobot v3.0 and get the `v3.0` tag LeRobot resolves on download.
    """
    from huggingface_hub import HfApi
    from huggingface_hub.errors import RevisionNotFoundError

    local_dir = Path(local_dir)
    if not local_dir.is_dir():
        raise FileNotFoundError(f"{local_dir} is not a folder; pass the checkpoint or dataset directory")
    repo_type = repo_type or detect_repo_type(local_dir)
    _check_repo(repo_id, repo_type)
    if _offline():
        raise RuntimeError("HF_HUB_OFFLINE is set: unset it (or set HF_HUB_OFFLINE=0) to push")

    api = HfApi(endpoint=_endpoint(endpoint), token=token or os.environ.get("HF_TOKEN"))
    with tempfile.TemporaryDirectory(prefix="unidextok-push-") as staging:
        upload_dir = local_dir
        if repo_type == "dataset":
            info = json.loads((local_dir / "meta" / "info.json").read_text())
            if info.get("codebase_version") != DATASET_CODEBASE_TAG:
                raise ValueError(
                    f"{local_dir} is LeRobot dataset {info.get('codebase_version')!r}; only "
                    f"{DATASET_CODEBASE_TAG} is supported: re-convert it with unidextok-convert"
                )
        elif not (local_dir / "README.md").is_file():
            from lerobot_unidextok.hub.card import tokenizer_card

            # Stage a copy so the user's folder is not modified.
            upload_dir = Path(staging) / "repo"
            shutil.copytree(local_dir, upload_dir)
            (upload_dir / "README.md").write_text(tokenizer_card(local_dir, repo_id, training_data))

        api.create_repo(repo_id, repo_type=repo_type, private=private, exist_ok=True)
        commit = api.upload_folder(
            repo_id=repo_id,
            repo_type=repo_type,
            folder_path=upload_dir,
            commit_message=commit_message or f"Upload {repo_type} with lerobot-unidextok",
            ignore_patterns=[".cache/**", "**/.cache/**", "images/**"],
        )
    if repo_type == "dataset":
        try:
            api.delete_tag(repo_id, tag=DATASET_CODEBASE_TAG, repo_type=repo_type)
        except RevisionNotFoundError:
            pass
        api.create_tag(repo_id, tag=DATASET_CODEBASE_TAG, repo_type=repo_type)
    logger.info("pushed %s %s at %s", repo_type, repo_id, commit.oid)
    return commit.oid


def pull(
    repo_id: str,
    repo_type: str = "model",
    revision: str | None = None,
    token: str | None = None,
    endpoint: str | None = None,
) -> Path:
    """Download a repo into the standard HF cache (snapshot_download); returns the snapshot folder.

    Afterwards `UniDexTok.from_pretrained(repo_id)` works with HF_HUB_OFFLINE=1, and a pulled
    dataset loads with `LeRobotDataset(repo_id, root=<returned path>)`.
    """
    from huggingface_hub import snapshot_download

    _check_repo(repo_id, repo_type)
    if _offline():
        raise RuntimeError(
            f"HF_HUB_OFFLINE is set, so {repo_id} cannot be downloaded: unset HF_HUB_OFFLINE "
            "(or set HF_HUB_OFFLINE=0) and run the pull again"
        )
    if revision is None and repo_type == "dataset":
        revision = DATASET_CODEBASE_TAG
    path = snapshot_download(
        repo_id,
        repo_type=repo_type,
        revision=revision,
        cache_dir=cache_dir(),
        token=token or os.environ.get("HF_TOKEN"),
        endpoint=_endpoint(endpoint),
    )
    logger.info("pulled %s %s into %s", repo_type, repo_id, path)
    return Path(path)


def cached_snapshot(repo_id: str, repo_type: str = "model", revision: str | None = None) -> Path:
    """The cached snapshot of `repo_id` without any network access; clear error when absent."""
    from huggingface_hub import snapshot_download
    from huggingface_hub.errors import LocalEntryNotFoundError

    _check_repo(repo_id, repo_type)
    try:
        return Path(
            snapshot_download(
                repo_id,
                repo_type=repo_type,
                revision=revision,
                cache_dir=cache_dir(),
                local_files_only=True,
            )
        )
    except LocalEntryNotFoundError as err:
        flag = "" if repo_type == "model" else f" --repo_type={repo_type}"
        raise FileNotFoundError(
            f"{repo_type} {repo_id} is not in the local HF cache ({cache_dir() or 'default'}): run "
            f"`unidextok-pull --repo_id={repo_id}{flag}` (or unset HF_HUB_OFFLINE) first"
        ) from err


def cache_via_loopback(local_dir: str | Path, repo_id: str, repo_type: str | None = None) -> Path:
    """Publish a folder into the local HF cache through a throwaway loopback Hub (demos, no network).

    Afterwards `UniDexTok.from_pretrained(repo_id)` resolves from the cache under HF_HUB_OFFLINE=1
    (in this process: pass `local_files_only=True`, huggingface_hub reads the variable at import).
    """
    from lerobot_unidextok.hub.loopback import LoopbackHub

    repo_type = repo_type or detect_repo_type(Path(local_dir))
    with LoopbackHub(lifetime_s=300) as hub:
        push(local_dir, repo_id, repo_type, endpoint=hub.url)
        return pull(repo_id, repo_type, endpoint=hub.url)
