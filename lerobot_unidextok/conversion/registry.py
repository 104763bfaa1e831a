"""Source registry: converters register a reader class under a source name.

A source reader lives in the checkout's `converters/<source>.py`, imported as `lerobot_unidextok.converters.<source>`
(or in any module of yours that imports `register_source` and is imported before the conversion)::

    @register_source("dexycb")
    class DexYCBSource:
        license = "CC BY-NC 4.0"
        description = "DexYCB hand-object grasps, MANO-21 keypoints (human)"
        synthetic = False                      # optional; True for generated samples

        def __init__(self, **options): ...     # optional source options (e.g. --source_options)
        def list_episodes(self, input_path: Path) -> list: ...   # picklable refs, in a stable order
        def read_episode(self, ref) -> RawEpisode: ...            # one ref -> one episode
        def robot_type(self, refs) -> str | None: ...              # optional: the source's robot type

`list_episodes` must be cheap and deterministic; `read_episode` runs in worker processes. Options named
`fps` and `keep` are filled from the `--fps` / `--keep` flags.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import importlib
import inspect
import logging

from lerobot_unidextok.errors import InvalidInputError

logger = logging.getLogger(__name__)

_SOURCES: dict[str, type] = {}
CONVERTERS_PACKAGE = "lerobot_unidextok.converters"


def register_source(name: str):
    """Class decorator: register a source reader under `name` (lowercase, no spaces)."""
    if not name or name != name.strip().lower() or " " in name:
        raise ValueError(f"source name must be lowercase without spaces, got {name!r}")

    def _register(cls: type) -> type:
        for attr in ("list_episodes", "read_episode"):
            if not callable(getattr(cls, attr, None)):
                raise TypeError(f"source {name!r} ({cls.__qualname__}) must define {attr}()")
        if name in _SOURCES and _SOURCES[name] is not cls:
            raise ValueError(
                f"source {name!r} is already registered by {_SOURCES[name].__module__}."
                f"{_SOURCES[name].__qualname__}; pick another name"
            )
        _SOURCES[name] = cls
        return cls

    return _register


def unregister_source(name: str) -> None:
    """Remove a source (tests)."""
    _SOURCES.pop(name, None)


def import_sources() -> None:
    """Import `lerobot_unidextok.converters` (the checkout's `converters/` folder) and its submodules so their
    decorators run."""
    import pkgutil

    pkg = importlib.import_module(CONVERTERS_PACKAGE)

    for info in pkgutil.iter_modules(getattr(pkg, "__path__", [])):
        if info.name.startswith("_"):
            continue
        try:
            importlib.import_module(f"{CONVERTERS_PACKAGE}.{info.name}")
        except ImportError as exc:  # an optional extra is missing: the source stays unavailable
            logger.warning("source module %s not importable: %s", info.name, exc)


def available_sources() -> list[str]:
    """Names of all registered sources (after importing the converters package)."""
    import_sources()
    return sorted(_SOURCES)


def get_source(name: str) -> type:
    """The registered reader class for `name`; raises ValueError listing the known names."""
    if name not in _SOURCES:
        import_sources()
    if name not in _SOURCES:
        raise ValueError(
            f"unknown source {name!r}; available sources: {sorted(_SOURCES) or 'none registered'}. "
            f"Register one with @register_source({name!r}) in converters/{name}.py"
        )
    return _SOURCES[name]


class SetupError(InvalidInputError):
    """The conversion cannot start (bad source options, unknown hand, nothing to read): raised once,
    before any episode is read, with the fix in the message."""


def source_options_help(cls: type) -> str:
    """`name=default` of every option (keyword argument) of a source reader class."""
    params = [p for p in inspect.signature(cls).parameters.values() if p.kind is not p.VAR_KEYWORD]
    return ", ".join(f"{p.name}={p.default!r}" if p.default is not p.empty else p.name for p in params) or "none"


def resamples(name: str) -> bool:
    """Whether source `name` resamples time-stamped streams onto a frame grid (it takes `--fps`); the others
    keep the rate their files record."""
    return "fps" in inspect.signature(get_source(name)).parameters


def make_reader(name: str, options: dict | None = None):
    """An instance of source `name` with `options`; bad options raise `SetupError` naming the fix."""
    cls = get_source(name)
    options = dict(options or {})
    params = inspect.signature(cls).parameters
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        unknown = sorted(set(options) - set(params))
        if unknown:
            raise SetupError(
                f"source {name!r} has no option(s) {unknown}; its options are: {source_options_help(cls)}. "
                "Pass them as --source_options='{\"option\": value}'"
            )
    try:
        return cls(**options)
    except (ValueError, TypeError, KeyError) as exc:
        raise SetupError(f"source {name!r} options {options}: {exc}") from exc


def check_hand(name: str, where: str) -> str:
    """`name` if it is a registered hand spec, else `SetupError` listing the known ones (no per-episode errors)."""
    from lerobot_unidextok import hands

    if name not in hands.names():
        raise SetupError(f"{where}: unknown hand {name!r}; known hand specs: {', '.join(hands.names())}")
    return name
