"""Where a tokenizer checkpoint is: the name resolution behind `UniDexTok.from_pretrained` (the one door).

    UniDexTok.from_pretrained("unidextok/universal-small")        # shipped in this package: no network
    UniDexTok.from_pretrained("unidextok/universal-small-residual")  # shipped too: + a residual stage (#48)
    UniDexTok.from_pretrained("outputs/small")                    # a unidextok-train run folder: its best/
    UniDexTok.from_pretrained("outputs/small/best")               # a checkpoint folder
    UniDexTok.from_pretrained("lab/unidextok-small")              # a Hub repo id (the HF cache serves it offline)
    UniDexTokConfig.from_pretrained(...)                          # the same names, config.json only

`resolve(name)`: an existing checkpoint folder as given, a run folder's `best/`, a shipped id's package folder,
else the name unchanged (a Hub repo id); a checkpoint that a killed `unidextok-train` save left set aside
(`.best.old-<pid>-*`) is named with the fix. `hub_errors(name)` turns the Hub's failures (offline and not cached,
not a repo id, no such repo) into one `CheckpointNotFoundError` that says how to fix it. `DEFAULT_TOKENIZER`
is the tokenizer of the `<type>_udt` policies and of `UniDexTokStateTokenizerStep` unless they are given
another one or an untrained preset explicitly: one of the shipped ids, set on one line. Each shipped folder is a
Hub-format checkpoint (config.json, model.safetensors, README.md card, eval.json with the card's figures);
`train/universal` is their recipe (the residual one with `--preset=small_residual`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from pathlib import Path

from lerobot_unidextok.errors import CheckpointNotFoundError

logger = logging.getLogger(__name__)

UNIVERSAL_SMALL = "unidextok/universal-small"  # the paper's single VQ, 64 codes a hand, greedy code search
UNIVERSAL_SMALL_RESIDUAL = "unidextok/universal-small-residual"  # + one residual stage, 128 codes, nearest codes (#48)
DEFAULT_TOKENIZER = UNIVERSAL_SMALL_RESIDUAL  # the one line that picks the default of the step and the <type>_udt ones
# every id that has been DEFAULT_TOKENIZER: a config saved with one of them and a preset (the field written out as it
# was by default) meant the untrained preset, and still does (`untrained_preset`)
DEFAULTS_SO_FAR = tuple(dict.fromkeys((DEFAULT_TOKENIZER, UNIVERSAL_SMALL)))
HERE = Path(__file__).resolve().parent
SHIPPED: dict[str, Path] = {
    UNIVERSAL_SMALL: HERE / "universal-small",
    UNIVERSAL_SMALL_RESIDUAL: HERE / "universal-small-residual",
}
CONFIG_FILE = "config.json"
RUN_BEST = "best"  # the checkpoint a unidextok-train run folder keeps for use


def shipped_folder(name: str) -> Path | None:
    """The package folder of shipped id `name`, or None when `name` is not a shipped id."""
    folder = SHIPPED.get(str(name))
    return folder if folder is not None and (folder / CONFIG_FILE).is_file() else None


def resolve(name: str | Path, checkpoint: bool = False) -> str:
    """A folder as given (a `unidextok-train` run folder: its `best/`); a shipped id's package folder; else `name`
    unchanged (a Hub repo id). `checkpoint=True`: a folder that holds no tokenizer is a CheckpointNotFoundError."""
    path = Path(name).expanduser()
    if path.is_dir():
        if (path / CONFIG_FILE).is_file():
            return str(name)
        if (path / RUN_BEST / CONFIG_FILE).is_file():
            logger.info("%s is a unidextok-train run folder: using its %s/ checkpoint", path, RUN_BEST)
            return str(path / RUN_BEST)
        refuse_set_aside(path / RUN_BEST)
        if not checkpoint:
            return str(name)
        raise CheckpointNotFoundError(
            f"{path} holds no tokenizer: expected {CONFIG_FILE} + model.safetensors, or a unidextok-train run "
            f"folder with {RUN_BEST}/ (pass that folder or its {RUN_BEST}/)"
        )
    refuse_set_aside(path)
    folder = shipped_folder(str(name))
    return str(folder) if folder is not None else str(name)


def refuse_set_aside(folder: Path) -> None:
    """A CheckpointNotFoundError when the checkpoint `folder` is missing because a `unidextok-train` save was killed
    between its two renames (`utils.files.replace_folder`): the old one is beside it as `.<name>.old-<pid>-*`."""
    if folder.exists() or not folder.parent.is_dir():
        return
    marker = f".{folder.name}.old-"  # the exact name, never a glob pattern (a name may hold [ or *)
    olds = [p for p in folder.parent.iterdir() if p.name.startswith(marker) and (p / CONFIG_FILE).is_file()]
    if not olds:
        return
    old = max(olds, key=lambda p: p.stat().st_mtime)
    pid = old.name[len(marker) :].split("-")[0]
    raise CheckpointNotFoundError(
        f"{folder} is missing: a unidextok-train run (pid {pid}) was killed while replacing it, and set it aside as "
        f"{old}; any unidextok-train into {folder.parent} puts it back (e.g. --resume=true with the run's flags), "
        f"or rename {old.name} to {folder.name}"
    )


@contextlib.contextmanager
def hub_errors(name: str) -> Iterator[None]:
    """Turn huggingface_hub's failures to find `name` into a CheckpointNotFoundError naming the fix."""
    from huggingface_hub.errors import (  # the Hub client: only when a name goes to the HF cache / Hub
        EntryNotFoundError,
        HFValidationError,
        LocalEntryNotFoundError,
        OfflineModeIsEnabled,
        RepositoryNotFoundError,
    )

    not_here = f"{name!r} is not a folder here, nor a shipped id ({', '.join(SHIPPED)})"
    try:
        yield
    except (LocalEntryNotFoundError, OfflineModeIsEnabled) as err:
        raise CheckpointNotFoundError(
            f"{not_here}, and as a Hub repo id it is not in the local HF cache while the Hub is unreachable "
            f"(HF_HUB_OFFLINE or no network): run `unidextok-pull --repo_id={name}` first, or unset HF_HUB_OFFLINE"
        ) from err
    except HFValidationError as err:
        raise CheckpointNotFoundError(f"{not_here}, nor a Hub repo id (namespace/name)") from err
    except (RepositoryNotFoundError, EntryNotFoundError) as err:
        raise CheckpointNotFoundError(
            f"{not_here}, and the Hub has no UniDexTok checkpoint {name!r} ({type(err).__name__}); check the id, or "
            "HF_TOKEN for a private repo"
        ) from err


def untrained_preset(pretrained: str | None, preset: str | None) -> str | None:
    """The preset of an untrained tokenizer when one is asked for, else None (load `pretrained`): `preset` given
    with `pretrained` left at the default (`DEFAULT_TOKENIZER`, or an id that was the default when a config was
    saved: `DEFAULTS_SO_FAR`), or `pretrained=None` (then `preset`, else "small"). The rule of
    `UniDexTokStateTokenizerStep`, the `<type>_udt` configs and their cards."""
    if pretrained is None:
        return preset or "small"
    return preset if pretrained in DEFAULTS_SO_FAR else None


def config_path(name: str | Path, revision: str | None = None) -> Path:
    """The `config.json` of checkpoint `name` (resolved as `resolve` does; from the HF cache / Hub for a repo
    id, the config alone)."""
    resolved = resolve(name, checkpoint=True) if revision is None else str(name)
    if Path(resolved).is_dir():
        return Path(resolved) / CONFIG_FILE
    from huggingface_hub import hf_hub_download  # the Hub client: only for a repo id

    with hub_errors(str(name)):
        return Path(hf_hub_download(repo_id=resolved, filename=CONFIG_FILE, revision=revision))


__all__ = ["DEFAULTS_SO_FAR", "DEFAULT_TOKENIZER", "SHIPPED", "UNIVERSAL_SMALL", "UNIVERSAL_SMALL_RESIDUAL",
           "config_path", "hub_errors", "refuse_set_aside", "resolve", "shipped_folder", "untrained_preset"]
