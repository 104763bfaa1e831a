"""draccus parsing for the command-line tools: one help line per flag, config checks as their own errors.

Six draccus (0.11) habits this corrects:

- every nested config (`--coverage.*`, `--executor.*`, `--train.*`) gets a whole-group flag registered
  twice, once by the parent as `--<field name>` and once by the nested wrapper as `--<dotted path>`.
  At the top level the second shadows the first, but argparse keeps the shadowed copy in the help
  (`--coverage str` listed twice); one level down the parent's copy is a flag of its own that leads
  nowhere (`--slurm` beside `--executor.slurm`). Both are removed; `--<dotted path>` stays.
- that flag's help says "Config file for ...", but draccus reads its value as the group in YAML
  (`--executor='{type: local, tasks: 8}'`, or `--executor='include file.yaml'`); the help says so, and a
  plain value (`--executor=local`) is refused with the group's flags named.
- a field comment with a percent sign ("6.2 % of the frames") broke `--help` (argparse formats help
  with %); it is escaped.
- a flag value YAML cannot read (`--source_options={bad`) ended in a yaml traceback; it is a ValueError
  naming the flag. A mapping that names one key twice (`--source_options='{"hands": {"left": ..., "left": ...}}'`)
  kept the last entry with no word; it is refused the same way, naming the key.
- a value draccus cannot read as its field's type (`--weights='[a, 1]'`) was named by its Python message alone;
  the flag (and the list item) is named.
- a ValueError raised by a config's `__post_init__` (a bad flag value) reaches the caller wrapped in
  `ParsingError("Couldn't instantiate class ...")`; it is raised as itself, with its own message.

One addition: `--config_path` takes a file or the name of a config shipped in the package (`train/small`,
`configs/`), so the documented commands work from any folder.

    @wrap()
    def train_cli(cfg: TrainConfig) -> None: ...

    cfg = parse_config(ExperimentConfig, args=["--train.steps=20"])
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import inspect
import re
import sys
import typing
from collections.abc import Callable, Sequence

import yaml
from draccus.argparsing import ArgumentParser
from draccus.utils import DecodingError, ParsingError

from lerobot_unidextok.configs import resolve_config_path
from lerobot_unidextok.errors import ConfigError, UserError


def config_parser[T](config_class: type[T], config_path: str | None = None) -> ArgumentParser:
    """draccus' parser for `config_class`, with one config-file flag per nested config (its dotted path)."""
    parser = ArgumentParser(config_class=config_class, config_path=config_path)
    _drop_stray_config_flags(parser.parser, set(_nested_paths(config_class)))
    for action in parser.parser._actions:
        if action.help:
            action.help = re.sub(r"%(?!\()", "%%", action.help)  # a literal %, not argparse's %(default)s
    return parser


def _nested_paths(config_class: type, prefix: str = "") -> list[str]:
    """Dotted paths of the nested dataclass fields of `config_class` (`executor`, `executor.slurm`)."""
    hints = typing.get_type_hints(config_class)
    paths = []
    for f in dataclasses.fields(config_class):
        kind = hints.get(f.name, f.type)
        if f.init and dataclasses.is_dataclass(kind):
            paths += [prefix + f.name, *_nested_paths(kind, f"{prefix}{f.name}.")]
    return paths


def _drop_stray_config_flags(parser: argparse.ArgumentParser, nested: set[str]) -> None:
    """Keep, of the whole-group flags draccus adds for nested configs, the live one named by the dotted path."""
    for action in list(parser._actions):
        if not (action.help or "").startswith("Config file for "):
            continue
        if action.dest not in nested:
            parser._remove_action(action)  # the parent's `--<field name>` copy of a deeper config
            for option in action.option_strings:
                parser._option_string_actions.pop(option, None)
        else:
            action.help = f"all of --{action.dest}.* as one YAML mapping ('{{field: value, ...}}' or 'include <file>')"
    live = {id(action) for action in parser._actions}
    for group in parser._action_groups:  # copies shadowed by a later flag of the same name
        group._group_actions[:] = [a for a in group._group_actions if id(a) in live]


def parse_config[T](config_class: type[T], args: Sequence[str] | None = None, config_path: str | None = None) -> T:
    """`draccus.parse` (`--config_path=...` and `--field=value` flags; `sys.argv[1:]` when `args` is None)."""
    args = _resolve_config_paths(sys.argv[1:] if args is None else list(args))
    if config_path is not None:
        config_path = resolve_config_path(config_path)
    nested = set(_nested_paths(config_class))
    for arg in args:
        name, _, value = arg.partition("=")
        try:  # draccus reads every value as YAML; a value YAML cannot read would end in a parser traceback
            load_flag_value(value)
        except DuplicateKeyError as exc:
            raise ConfigError(f"{name}: {value!r} {exc.problem}: give each key once (the later entry would silently "
                              "replace the earlier one)") from None  # fmt: skip
        except yaml.YAMLError as exc:
            problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
            raise ConfigError(
                f"{name}: {value!r} is not valid YAML/JSON ({problem}); check its brackets and quotes"
            ) from None
        if name.removeprefix("--") in nested and value and not _is_group_value(value):
            raise ConfigError(
                f"{arg}: {name} is a group of flags ({name}.<field>=..., --help lists them), or all of them as "
                f"one YAML mapping: {name}='{{field: value, ...}}'"
            )
    try:
        return config_parser(config_class, config_path).parse_args(args)
    except ParsingError as exc:
        cause = exc.__cause__
        nested = _user_error_in(exc)  # an optional nested config's own check, under draccus' union decoding
        if nested is not None:
            raise nested from None
        if isinstance(cause, UserError):
            raise cause from None
        if isinstance(exc, DecodingError) and exc.key_path and not exc.message.startswith("Couldn't instantiate"):
            raise ConfigError(_undecodable(exc)) from None  # `--weights='[a, 1]'`: name the flag and the item
        if isinstance(cause, ValueError):  # a __post_init__ check: its message names the flag
            raise ConfigError(str(cause)) from None
        if isinstance(cause, TypeError):  # a value of the wrong type for a field, or a key it does not have
            raise ConfigError(f"{cause}: check the config file's keys and value types against --help") from None
        raise ConfigError(str(exc)) from None


class DuplicateKeyError(yaml.constructor.ConstructorError):
    """A YAML mapping names one key twice."""


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a mapping that names one key twice (PyYAML keeps the last one silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise DuplicateKeyError(None, None, f"names the key {key!r} twice", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def load_flag_value(text: str):
    """A flag's value read as YAML (JSON is YAML), as draccus reads it, with a key given twice a `yaml.YAMLError`."""
    return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506  (a SafeLoader subclass)


def _undecodable(exc: DecodingError) -> str:
    """'--weights: item 0: Couldn't parse 'a' into a float; ...' for a value draccus cannot read as its type."""
    flag = ".".join(k for k in exc.key_path if not str(k).isdigit())
    items = "".join(f"item {k}: " for k in exc.key_path if str(k).isdigit())
    return f"--{flag}: {items}{' '.join(exc.message.split())}; check the value against --help"


def _user_error_in(exc: BaseException) -> UserError | None:
    """The first UserError (a config's own check) among the exceptions `exc` was raised from, if any."""
    seen: set[int] = set()
    todo = [exc.__cause__, exc.__context__]
    while todo:
        e = todo.pop(0)
        if e is None or id(e) in seen:
            continue
        if isinstance(e, UserError):
            return e
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return None


def _resolve_config_paths(args: list[str]) -> list[str]:
    """`--config_path=<file or shipped name>` with a shipped name (`train/small`) replaced by its file."""
    out = list(args)
    for i, arg in enumerate(out):
        if arg.startswith("--config_path="):
            out[i] = "--config_path=" + resolve_config_path(arg.partition("=")[2])
        elif arg == "--config_path" and i + 1 < len(out):
            out[i + 1] = resolve_config_path(out[i + 1])
    return out


def _is_group_value(value: str) -> bool:
    """What draccus reads for a whole group: a YAML mapping or `include <file>`."""
    if value.startswith("include "):
        return True
    try:
        return isinstance(yaml.safe_load(value), dict)
    except yaml.YAMLError:
        return False


def wrap(config_path: str | None = None) -> Callable:
    """Like `draccus.wrap()`: the decorated function's first parameter is parsed from the command line
    unless a config of that type is passed."""

    def decorate(fn: Callable) -> Callable:
        config_class = inspect.getfullargspec(fn).annotations[inspect.getfullargspec(fn).args[0]]

        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            if args and type(args[0]) is config_class:
                return fn(*args, **kwargs)
            return fn(parse_config(config_class, config_path=config_path), *args, **kwargs)

        return wrapper

    return decorate


__all__ = ["config_parser", "load_flag_value", "parse_config", "wrap"]
