"""Configs shipped with the package, usable by name from any folder (a pip install or a clone alike).

This folder is the checkout's top-level `configs/`, installed as `lerobot_unidextok.configs` (pyproject.toml's
package-dir; docs/architecture.md, "Folders and import names").

    unidextok-train --config_path=train/small ...               # our CLIs take a shipped name or a file
    lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) ...   # LeRobot's CLIs take a file: its path
    unidextok-config                                            # lists the shipped configs

A name is `<group>/<name>` (`train/small`, `lerobot/act_udt_cpu`, `convert/slurm`), with or without `.yaml`;
a bare `<name>` works when one group has it. Imports only the package's error classes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lerobot_unidextok.errors import MissingInputError

CONFIGS_DIR = Path(__file__).resolve().parent


def shipped_configs() -> dict[str, Path]:
    """`<group>/<name>` -> file of every shipped config, sorted by name."""
    return {f"{p.parent.name}/{p.stem}": p for p in sorted(CONFIGS_DIR.glob("*/*.yaml"))}


def shipped_config(name: str) -> Path | None:
    """The file of shipped config `name` (`train/small`, `train/small.yaml`, or `small` when unambiguous), or
    None when no shipped config has that name."""
    key = str(name).removesuffix(".yaml").removeprefix("configs/").strip("/")
    configs = shipped_configs()
    if key in configs:
        return configs[key]
    matches = [path for full, path in configs.items() if full.split("/", 1)[1] == key]
    return matches[0] if len(matches) == 1 else None


def resolve_config_path(config_path: str, what: str = "--config_path") -> str:
    """An existing file as given; else the shipped config of that name; else a FileNotFoundError naming `what`
    (the flag or field) and listing the shipped configs."""
    if Path(config_path).expanduser().is_file():
        return config_path
    shipped = shipped_config(config_path)
    if shipped is not None:
        return str(shipped)
    raise MissingInputError(
        f"{what} {config_path} not found: no such file and no shipped config of that name; shipped configs: "
        f"{', '.join(shipped_configs())} (`unidextok-config` prints their paths)"
    )


def main(argv: list[str] | None = None) -> None:
    """`unidextok-config [<name>]`: the path of a shipped config (for `lerobot-train --config_path=...`), or the
    shipped configs with their paths."""
    parser = argparse.ArgumentParser(
        prog="unidextok-config",
        description="Print the path of a config shipped with lerobot_unidextok, e.g. "
        "lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) ...",
    )
    parser.add_argument("name", nargs="?", help="<group>/<name> (train/small) or a unique <name>; none: list them")
    parser.add_argument("--list", action="store_true", help="list every shipped config with its path")
    args = parser.parse_args(argv)
    if args.list or not args.name:
        for name, path in shipped_configs().items():
            print(f"{name:24s} {path}")
        return
    path = shipped_config(args.name)
    if path is None:
        print(f"error: no shipped config {args.name!r}; shipped: {', '.join(shipped_configs())}", file=sys.stderr)
        raise SystemExit(2)
    print(path)


__all__ = ["CONFIGS_DIR", "main", "resolve_config_path", "shipped_config", "shipped_configs"]
