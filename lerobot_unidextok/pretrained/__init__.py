"""Tokenizers shipped inside the package, resolvable by id with no network and an empty HF cache.

    UniDexTok.from_pretrained("unidextok/universal-small")        # this folder's universal-small/
    unidextok-eval --checkpoint=unidextok/universal-small
    lerobot-train --policy.type=act_udt ...                        # the default `udt_pretrained`

Resolution of a name (`resolve`): an existing local folder, then a shipped id, then the name unchanged (the
HF cache / Hub). `DEFAULT_TOKENIZER` is the tokenizer of the `<type>_udt` policies and of
`UniDexTokStateTokenizerStep` unless they are given another one or an untrained preset explicitly.
Each shipped folder is a Hub-format checkpoint (config.json, model.safetensors, README.md card, eval.json with
the card's figures); `lerobot_unidextok/configs/train/universal.yaml` is its recipe. Imports nothing of the package.
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_TOKENIZER = "unidextok/universal-small"
HERE = Path(__file__).resolve().parent
SHIPPED: dict[str, Path] = {"unidextok/universal-small": HERE / "universal-small"}


def shipped_folder(name: str) -> Path | None:
    """The package folder of shipped id `name`, or None when `name` is not a shipped id."""
    folder = SHIPPED.get(str(name))
    return folder if folder is not None and (folder / "config.json").is_file() else None


def resolve(name: str | Path) -> str:
    """A local folder as given; else the shipped folder of a shipped id; else `name` (a Hub repo id)."""
    if Path(name).expanduser().is_dir():
        return str(name)
    folder = shipped_folder(str(name))
    return str(folder) if folder is not None else str(name)


__all__ = ["DEFAULT_TOKENIZER", "SHIPPED", "resolve", "shipped_folder"]
