"""Console output of the command-line tools: one-line errors for user mistakes, quiet optional backends,
progress bars that do not flood logs.

    def main() -> None:
        run_cli(my_draccus_cli)      # configure_output(), then the CLI body with one-line user errors

    for item in progress_bar(items, desc="convert", unit="ep"):   # every bar of this package
        ...

Nothing here runs on import: a CLI calls `configure_output()` (through `run_cli`) when it starts.
"""

from __future__ import annotations

import functools
import logging
import os
import sys
from collections.abc import Callable, Iterable
from typing import Any


class UserError(RuntimeError):
    """A mistake the user can fix from the message (e.g. a push while HF_HUB_OFFLINE is set, a missing licensed
    model), where no builtin type such as ValueError or FileNotFoundError says it: one `error:` line in a CLI.
    A RuntimeError, so callers that caught these as RuntimeError still do; a plain RuntimeError is a bug."""


# Mistakes a person can fix from the message (bad paths, values, missing downloads); anything else is a bug
# and keeps its traceback. UNIDEXTOK_TRACEBACK=1 shows the traceback for these too.
USER_ERRORS: tuple[type[BaseException], ...] = (
    UserError,
    ValueError,
    FileNotFoundError,
    FileExistsError,
    NotADirectoryError,
    PermissionError,
    KeyError,
)
TORCHCODEC_NOTE = (
    "note: torchcodec cannot load FFmpeg on this machine, so LeRobot will decode videos with pyav. "
    "State-only datasets need neither; for video datasets install FFmpeg (LeRobot's system dependency, see "
    "README). `python -c 'import torchcodec'` shows the details."
)
_TORCHCODEC_WARNING = "'torchcodec' is installed but cannot be loaded"
NON_TTY_PROGRESS_INTERVAL_S = 30.0  # seconds between progress-bar refreshes when stderr is a file or pipe
TTY_PROGRESS_INTERVAL_S = 0.1  # ... on a terminal (tqdm's default)


class _TorchcodecNote(logging.Filter):
    """Turn LeRobot's ~100-line torchcodec/FFmpeg warning into one note, once per process."""

    shown = False

    def filter(self, record: logging.LogRecord) -> bool:
        if _TORCHCODEC_WARNING not in str(record.msg):
            return True
        if _TorchcodecNote.shown:
            return False
        _TorchcodecNote.shown = True
        record.msg, record.args, record.levelno, record.levelname = TORCHCODEC_NOTE, (), logging.INFO, "INFO"
        return True


def quiet_torchcodec_warning() -> None:
    """Install the one-line torchcodec note on LeRobot's import_utils logger (idempotent)."""
    logger = logging.getLogger("lerobot.utils.import_utils")
    if not any(isinstance(f, _TorchcodecNote) for f in logger.filters):
        logger.addFilter(_TorchcodecNote())


def progress_interval_s(stream: Any = None) -> float:
    """Seconds between progress-bar refreshes on `stream` (default stderr): TQDM_MININTERVAL when set, else
    30 when the stream is a file or pipe, 0.1 on a terminal."""
    explicit = os.environ.get("TQDM_MININTERVAL", "").strip()
    if explicit:
        return float(explicit)
    stream = sys.stderr if stream is None else stream
    on_terminal = getattr(stream, "isatty", lambda: False)()
    return TTY_PROGRESS_INTERVAL_S if on_terminal else NON_TTY_PROGRESS_INTERVAL_S


@functools.cache
def _progress_bar_class() -> type:
    from tqdm.auto import tqdm  # ~0.1-0.4 s (asyncio): imported with the first bar, not with this module

    class ProgressBar(tqdm):
        """tqdm whose `set_postfix` waits for the next refresh, so the counter and the postfix are written
        together, at most every `mininterval` seconds (tqdm's own `set_postfix` refreshes on every call)."""

        monitor_interval = 0  # no monitor thread: between updates it re-writes the last counter

        def set_postfix(self, ordered_dict=None, refresh: bool = False, **kwargs) -> None:
            super().set_postfix(ordered_dict, refresh=refresh, **kwargs)

    return ProgressBar


def progress_bar(iterable: Iterable | None = None, **kwargs: Any):
    """The progress bar of every tool of this package (tqdm arguments): it refreshes every
    `progress_interval_s()` seconds (30 s when stderr is a log file or pipe, so logs hold a line per 30 s,
    not one per update) and writes its counter and postfix in the same refresh."""
    kwargs.setdefault("mininterval", progress_interval_s(kwargs.get("file")))
    kwargs.setdefault("miniters", 1)  # check the clock on every update, so a slowing loop still refreshes on time
    return _progress_bar_class()(iterable, **kwargs)


def throttle_progress_bars() -> None:
    """When stderr is not a terminal, also make other libraries' tqdm bars (LeRobot's, datasets') and child
    processes refresh every 30 s, through tqdm's TQDM_MININTERVAL default (an explicit value wins). tqdm reads
    it when it is first imported, so this only reaches bars of modules imported afterwards."""
    if not sys.stderr.isatty():
        os.environ.setdefault("TQDM_MININTERVAL", str(NON_TTY_PROGRESS_INTERVAL_S))


def configure_output() -> None:
    """What a CLI does when it starts: the torchcodec note and throttled progress bars."""
    quiet_torchcodec_warning()
    throttle_progress_bars()


def run_cli(fn: Callable[[], object]) -> None:
    """Run a CLI body after `configure_output()`; a user mistake prints `error: <message>` on stderr and exits
    with status 2."""
    configure_output()
    try:
        fn()
    except USER_ERRORS as err:
        if os.environ.get("UNIDEXTOK_TRACEBACK", "0") not in ("", "0"):
            raise
        message = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"error: {message}", file=sys.stderr)
        print("(set UNIDEXTOK_TRACEBACK=1 to see the traceback)", file=sys.stderr)
        raise SystemExit(2) from None
