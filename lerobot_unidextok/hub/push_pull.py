"""Push tokenizer checkpoints / converted datasets to a Hub and pull them into the local HF cache.

Honours HF_ENDPOINT, HF_TOKEN, HF_HOME / HF_HUB_CACHE and HF_HUB_OFFLINE, read at call time.
huggingface_hub is imported lazily so `import lerobot_unidextok.hub` stays cheap.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import tempfile
from pathlib import Path

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.errors import InvalidInputError, MissingInputError, UnavailableError
from lerobot_unidextok.hub.card import card_status, model_card, with_repo_id, with_training_data
from lerobot_unidextok.pretrained import resolve as resolve_pretrained
from lerobot_unidextok.utils.hf_cache import DATASET_REVISIONS, cached_repo_snapshot, hub_cache, lerobot_home
from lerobot_unidextok.utils.number_checks import nonfinite_tensors, nonfinite_text

logger = logging.getLogger(__name__)

REPO_TYPES = ("model", "dataset")
DATASET_CODEBASE_TAG = "v3.0"  # LeRobot refuses dataset repos without a v3.x tag


def _endpoint(endpoint: str | None) -> str | None:
    return endpoint or os.environ.get("HF_ENDPOINT") or None


def _offline() -> bool:
    return os.environ.get("HF_HUB_OFFLINE", "0").upper() in ("1", "ON", "YES", "TRUE")


def _check_repo(repo_id: str, repo_type: str) -> None:
    if repo_type not in REPO_TYPES:
        raise InvalidInputError(f"repo_type must be one of {REPO_TYPES}, got {repo_type!r}")
    if repo_id.count("/") != 1 or not all(repo_id.split("/")):
        raise InvalidInputError(f"repo_id must look like 'namespace/name', got {repo_id!r}")


def detect_repo_type(local_dir: Path) -> str:
    """'dataset' for a LeRobotDataset folder (meta/info.json), 'model' for a checkpoint (config.json)."""
    if (local_dir / INFO_PATH).is_file():
        return "dataset"
    if (local_dir / "config.json").is_file():
        return "model"
    raise InvalidInputError(
        f"{local_dir} is neither a LeRobotDataset (meta/info.json) nor a checkpoint (config.json); "
        "pass repo_type explicitly"
    )


def check_loadable(local_dir: Path, repo_type: str) -> None:
    """Read back what a push would upload, so a damaged folder (a truncated safetensors, a JSON file cut
    short, an unreadable parquet file) is refused before anything reaches the Hub; a model must load as its users
    load it and hold no NaN/inf in any tensor (a policy's statistics included)."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    if repo_type == "dataset":
        import pyarrow.parquet as pq

        checks = [(path, pq.read_metadata) for path in sorted(local_dir.glob("**/*.parquet"))]
    else:
        # a policy's weights are read once, by the strict load below (policies.checkpoint), not here as well
        policy = (local_dir / "policy_preprocessor.json").is_file()
        checks = [(path, load_file) for path in sorted(local_dir.glob("*.safetensors"))
                  if not (policy and path.name == "model.safetensors")]  # fmt: skip
    for path in [*sorted(local_dir.glob("*.json")), *sorted(local_dir.glob("meta/*.json"))]:
        checks.append((path, lambda p: json.loads(p.read_text())))
    for path, read in checks:
        try:
            read(path)
        except (SafetensorError, OSError, ValueError) as e:  # pyarrow's ArrowInvalid is a ValueError
            raise InvalidInputError(
                f"{path} cannot be read ({type(e).__name__}: {e}): nothing was pushed; re-create it (re-train, "
                "re-save or re-convert) and push again"
            ) from None
    if repo_type == "model":
        check_model_loads(local_dir)  # a policy: also every tensor finite (policies.checkpoint)
        tokenizer = not (local_dir / "policy_preprocessor.json").is_file()
        for path in sorted(local_dir.glob("*.safetensors")) if tokenizer else []:  # no NaN/inf in what is pushed
            found = nonfinite_tensors(path)
            if found:
                raise InvalidInputError(
                    f"{path}: {nonfinite_text(found)}, so nothing was pushed: a model with them outputs NaN; the "
                    "training diverged or the file was edited: push an earlier checkpoint, or train again"
                )


def check_model_loads(local_dir: Path) -> None:
    """Load a checkpoint as its users will: a policy (LeRobot's factory: config, weights, processors) or a
    tokenizer (`UniDexTok.from_pretrained`: config keys and weight shapes checked). A folder that reads but
    does not load (an unknown config key, a hidden_dim the weights do not have) is refused before the push."""
    from lerobot_unidextok.errors import UserError

    try:
        if (local_dir / "policy_preprocessor.json").is_file():
            from lerobot_unidextok.policies.checkpoint import check_policy_checkpoint  # LeRobot: only for a policy

            check_policy_checkpoint(local_dir)
        else:
            from lerobot_unidextok.tokenizer import UniDexTok

            UniDexTok.from_pretrained(str(local_dir))
    except UserError as e:
        raise InvalidInputError(f"{local_dir} does not load, so nothing was pushed: {e}") from e


def check_dataset_valid(local_dir: Path, shown: int = 3) -> None:
    """Validate a dataset as `unidextok-convert --validate=true` does (`conversion.validate`); refuse an INVALID
    one, naming its first `shown` failed checks, before anything reaches the Hub."""
    from lerobot_unidextok.conversion.validate import validate_dataset

    failed = validate_dataset(local_dir).failed()
    if failed:
        first = "; ".join(f"{c.name}: {' '.join(c.detail.split())[:160]}" for c in failed[:shown])
        more = f" (and {len(failed) - shown} more)" if len(failed) > shown else ""
        raise InvalidInputError(
            f"{local_dir} fails validation ({first}{more}), so nothing was pushed: `unidextok-convert "
            f"--validate=true --root={local_dir}` shows every check; convert it again (unidextok-convert, or "
            "unidextok-mix for a mix) and push the new folder"
        )


def cache_dir() -> str:
    """HF_HUB_CACHE, else $HF_HOME/hub, else huggingface_hub's default (~/.cache/huggingface/hub)."""
    return str(hub_cache())


def checkpoint_folder(local_dir: Path) -> Path:
    """The folder to upload for `local_dir`: itself, or the checkpoint inside a training run folder
    (unidextok-train: `best/`; lerobot-train: `checkpoints/last/pretrained_model/`, or `pretrained_model/`)."""
    if (local_dir / "config.json").is_file() or (local_dir / INFO_PATH).is_file():
        return local_dir
    for inner in ("best", "pretrained_model", "checkpoints/last/pretrained_model"):
        if (local_dir / inner / "config.json").is_file():
            logger.info("%s is a training run: uploading its checkpoint %s", local_dir, local_dir / inner)
            return local_dir / inner
    return local_dir


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
    """Upload a folder (or a tokenizer shipped in the package, by its id); returns the commit id.

    Models get a generated card (tokenizer or policy card) when the folder has none or only
    huggingface_hub's generic one; a card written by this package (e.g. by unidextok-train) is kept, with
    `repo_id` as its title and in its usage code and `training_data` filled in; a hand-written card is kept
    as it is. A training run folder uploads its
    checkpoint. Datasets must be LeRobot v3.0 and pass `unidextok-convert --validate=true`'s checks, and get
    the `v3.0` tag LeRobot resolves. A policy checkpoint must load strictly (`policies.checkpoint`).
    """
    from huggingface_hub import HfApi
    from huggingface_hub.errors import RevisionNotFoundError

    local_dir = Path(resolve_pretrained(local_dir))  # a shipped id (unidextok/universal-small): its package folder
    if not local_dir.is_dir():
        raise MissingInputError(f"{local_dir} is not a folder; pass the checkpoint or dataset directory")
    local_dir = checkpoint_folder(local_dir)
    repo_type = repo_type or detect_repo_type(local_dir)
    _check_repo(repo_id, repo_type)
    if _offline():
        raise UnavailableError("HF_HUB_OFFLINE is set: unset it (or set HF_HUB_OFFLINE=0) to push")

    check_loadable(local_dir, repo_type)
    if repo_type == "dataset":
        info = json.loads((local_dir / INFO_PATH).read_text())
        if info.get("codebase_version") != DATASET_CODEBASE_TAG:
            raise InvalidInputError(
                f"{local_dir} is LeRobot dataset {info.get('codebase_version')!r}; only "
                f"{DATASET_CODEBASE_TAG} is supported: re-convert it with unidextok-convert"
            )
        check_dataset_valid(local_dir)
    api = HfApi(endpoint=_endpoint(endpoint), token=token or os.environ.get("HF_TOKEN"))
    with tempfile.TemporaryDirectory(prefix="unidextok-push-") as staging:
        upload_dir = local_dir
        if repo_type == "model":
            readme = local_dir / "README.md"
            status = card_status(readme)
            card = None
            if status in ("missing", "generic"):  # write our card (tokenizer or policy)
                card = model_card(local_dir, repo_id, training_data)
            elif status == "ours":  # e.g. unidextok-train's card: named after this repo, with the data repo ids
                card = with_repo_id(readme.read_text(), local_dir, repo_id)
                card = with_training_data(card, training_data) if training_data else card
            elif status == "custom" and training_data:
                logger.warning(
                    "%s is a hand-written README: uploaded unchanged, without --training_data %s (delete it to "
                    "get a generated card)",
                    readme,
                    training_data,
                )
            if card is not None:  # staged, so the user's folder is not modified
                upload_dir = Path(staging) / "repo"
                shutil.copytree(local_dir, upload_dir, ignore=shutil.ignore_patterns(".cache"))
                (upload_dir / "README.md").write_text(card)

        with _hub_refusals(f"push to {repo_type} {repo_id}", endpoint):
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

    Afterwards `UniDexTok.from_pretrained(repo_id)` works with HF_HUB_OFFLINE=1; a pulled dataset is
    linked at `$HF_LEROBOT_HOME/<repo_id>`, so `LeRobotDataset(repo_id)`, `lerobot-train
    --dataset.repo_id=...`, `unidextok-train/-eval --datasets=[repo_id]` and `cached_snapshot` all find it.
    """
    import httpx
    from huggingface_hub import HfApi, snapshot_download
    from huggingface_hub.errors import HfHubHTTPError, RepositoryNotFoundError, RevisionNotFoundError

    _check_repo(repo_id, repo_type)
    if _offline():
        raise UnavailableError(
            f"HF_HUB_OFFLINE is set, so {repo_id} cannot be downloaded: unset HF_HUB_OFFLINE "
            "(or set HF_HUB_OFFLINE=0) and run the pull again"
        )
    if revision is None and repo_type == "dataset":
        revision = DATASET_CODEBASE_TAG
    token = token or os.environ.get("HF_TOKEN")
    # Ask the Hub first: snapshot_download answers a refusal (a rejected token, a missing repo) with the cached
    # snapshot when there is one, so a pull would report success with stale files.
    api = HfApi(endpoint=_endpoint(endpoint), token=token)
    try:
        commit = api.repo_info(repo_id, repo_type=repo_type, revision=revision).sha
    except (RepositoryNotFoundError, RevisionNotFoundError) as e:
        raise MissingInputError(
            f"the Hub has no {repo_type} {repo_id}{f' at revision {revision}' if revision else ''} readable with "
            f"this token ({_reason(e)}): check the repo id, --revision and --token / HF_TOKEN"
        ) from None
    except HfHubHTTPError as e:  # 401 / 403 (a rejected token, a gated repo) or the Hub failing
        raise UnavailableError(
            f"the Hub refused {repo_type} {repo_id} ({_reason(e)}): check --token / HF_TOKEN and your access; "
            f"nothing was pulled{_cached_note(repo_id, repo_type, revision)}"
        ) from None
    except (httpx.ConnectError, httpx.TimeoutException) as e:
        cached = cached_repo_snapshot(hub_cache(), repo_id, repo_type, [revision or "main"])
        if cached is None:
            raise UnavailableError(
                f"the Hub at {_endpoint(endpoint) or 'huggingface.co'} cannot be reached ({e}) and {repo_type} "
                f"{repo_id} is not in the local HF cache ({cache_dir()}): pull again when online"
            ) from None
        logger.warning("the Hub cannot be reached (%s): using the cached snapshot %s, which may be older than the "
                       "Hub's", e, cached)  # fmt: skip
        commit, path = None, str(cached)
    if commit is not None:
        path = snapshot_download(repo_id, repo_type=repo_type, revision=commit, cache_dir=cache_dir(), token=token,
                                 endpoint=_endpoint(endpoint))  # fmt: skip
        if (revision or "main") != commit:  # the ref a later offline read resolves (main, v3.0)
            _record_ref(repo_id, repo_type, revision or "main", commit)
        logger.info("pulled %s %s at %s into %s", repo_type, repo_id, commit[:8], path)
    if repo_type == "dataset":
        link = link_into_lerobot_home(repo_id, Path(path))
        if link is not None:
            logger.info("linked %s -> %s: LeRobotDataset(%r) finds it without root", link, path, repo_id)
    return Path(path)


@contextlib.contextmanager
def _hub_refusals(what: str, endpoint: str | None):
    """A Hub that refuses (401/403, a server error) or cannot be reached, as one UnavailableError."""
    import httpx
    from huggingface_hub.errors import HfHubHTTPError

    try:
        yield
    except HfHubHTTPError as e:
        raise UnavailableError(f"the Hub refused the {what} ({_reason(e)}): check --token / HF_TOKEN and your "
                               "write access") from None  # fmt: skip
    except (httpx.ConnectError, httpx.TimeoutException) as e:
        raise UnavailableError(f"the Hub at {_endpoint(endpoint) or 'huggingface.co'} cannot be reached ({e}): "
                               f"the {what} did not happen; try again when online") from None  # fmt: skip


def _reason(error: Exception) -> str:
    response = getattr(error, "response", None)
    status = f"HTTP {response.status_code}" if response is not None else type(error).__name__
    return f"{status}: {str(error).splitlines()[0]}"


def _cached_note(repo_id: str, repo_type: str, revision: str | None) -> str:
    cached = cached_repo_snapshot(hub_cache(), repo_id, repo_type, [revision or "main"])
    return f" (the cached snapshot {cached} is left as it was)" if cached is not None else ""


def _record_ref(repo_id: str, repo_type: str, revision: str, commit: str) -> None:
    """Point the cache's ref `revision` at `commit`, as snapshot_download does when it resolves a name."""
    from huggingface_hub.file_download import repo_folder_name

    ref = Path(cache_dir()) / repo_folder_name(repo_id=repo_id, repo_type=repo_type) / "refs" / revision
    ref.parent.mkdir(parents=True, exist_ok=True)
    ref.write_text(commit)


def cached_snapshot(repo_id: str, repo_type: str = "model", revision: str | None = None) -> Path:
    """The cached snapshot of `repo_id` without any network access; clear error when absent.

    Datasets are pulled at tag `v3.0`, so without `revision` that tag is tried before `main`.
    """
    _check_repo(repo_id, repo_type)
    revisions = (revision,) if revision else (DATASET_REVISIONS if repo_type == "dataset" else ("main",))
    snapshot = cached_repo_snapshot(hub_cache(), repo_id, repo_type, revisions)
    if snapshot is None:
        flag = "" if repo_type == "model" else f" --repo_type={repo_type}"
        raise MissingInputError(
            f"{repo_type} {repo_id} (revision {' or '.join(revisions)}) is not in the local HF cache "
            f"({cache_dir()}): run `unidextok-pull --repo_id={repo_id}{flag}` (or unset HF_HUB_OFFLINE) first"
        )
    return snapshot


def link_into_lerobot_home(repo_id: str, snapshot: Path) -> Path | None:
    """Make a pulled dataset visible to LeRobot by repo id: `$HF_LEROBOT_HOME/<repo_id>` -> the snapshot.

    Then `LeRobotDataset(repo_id)` and `lerobot-train --dataset.repo_id=<repo_id>` find it without `root`
    and offline. An existing real folder there is left alone (returns None).
    """
    link = lerobot_home() / repo_id
    if link.is_symlink():
        link.unlink()
    elif link.exists():
        logger.info("%s exists and is not a link from unidextok-pull: left as it is", link)
        return None
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(snapshot, target_is_directory=True)
    return link


def cache_via_loopback(local_dir: str | Path, repo_id: str, repo_type: str | None = None) -> Path:
    """Publish a folder into the local HF cache through a throwaway loopback Hub (demos, no network).

    Afterwards `UniDexTok.from_pretrained(repo_id)` resolves from the cache under HF_HUB_OFFLINE=1
    (in this process: pass `local_files_only=True`, huggingface_hub reads the variable at import).
    """
    from lerobot_unidextok.hub.loopback import LoopbackHub

    repo_type = repo_type or detect_repo_type(Path(local_dir))
    with LoopbackHub() as hub:  # stops when the block ends
        push(local_dir, repo_id, repo_type, endpoint=hub.url)
        return pull(repo_id, repo_type, endpoint=hub.url)
