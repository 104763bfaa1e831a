"""Console output of the command-line tools: one-line errors for user mistakes, quiet optional backends,
progress bars that do not flood logs.

    def main() -> None:
        run_cli(my_draccus_cli)      # configure_output(), then the CLI body with one-line user errors

    for item in progress_bar(items, desc="convert", unit="ep"):   # every bar of this package
        ...

Nothing here runs on import: a CLI calls `configure_output()` (through `run_cli`) when it starts.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import functools
import logging
import os
import signal
import sys
from collections.abc import Callable, Iterable
from typing import Any

from lerobot_unidextok.errors import UserError  # layer 0: errors imports nothing of the package


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's KeyboardInterrupt so that the same clean-up runs (temporary folders
    removed, worker processes ended) before the tool exits with status 143."""


EXIT_USER_ERROR = 2  # a mistake the message says how to fix (docs/lerobot.md §6)
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT)
EXIT_TERMINATED = 143  # SIGTERM (128 + SIGTERM)
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


def _terminate(signum, frame) -> None:
    raise Terminated()


def _print_user_error(err: BaseException) -> None:
    message = err.args[0] if isinstance(err, KeyError) and err.args else err
    print(f"error: {message}", file=sys.stderr)
    print("(set UNIDEXTOK_TRACEBACK=1 to see the traceback)", file=sys.stderr)


def _show_tracebacks() -> bool:
    return os.environ.get("UNIDEXTOK_TRACEBACK", "0") not in ("", "0")


def _user_error_in(err: BaseException | None, kind: type) -> BaseException | None:
    """`err` if it is a `kind`, else the first `kind` it was raised from: draccus raises a config's refusal of a
    flag (`--env.hand=leap`, raised in its `__post_init__`) as the cause of its own `ParsingError`."""
    seen: set[int] = set()
    while err is not None and id(err) not in seen:  # explicit causes only: a bug raised while handling a
        if isinstance(err, kind):  # user error (its __context__) is still a bug
            return err
        seen.add(id(err))
        err = err.__cause__
    return None


def user_errors_in_lerobot_clis(
    translate: Callable[[BaseException, list[str]], BaseException | None] | None = None,
) -> None:
    """In a LeRobot CLI (lerobot-train, -eval, ...: the plugin's import), a `UserError` of this package that
    reaches the top of the process (a `<type>_udt` config refusing a dataset that was never converted, say)
    prints the same one `error:` line as this package's own tools and exits with status 2, after the
    process's exit handlers, instead of a traceback with status 1. `translate(err, sys.argv)` may give a
    `UserError` for an exception LeRobot raised itself (the plugin's `lerobot_errors.user_error_for`); a
    translator that fails leaves the exception as it was. Other exceptions keep the hook they had.
    Nothing changes in other programs (a script or notebook that imports the plugin) or with
    UNIDEXTOK_TRACEBACK=1."""
    import atexit
    from pathlib import Path

    if not Path(sys.argv[0] if sys.argv else "").name.startswith(("lerobot-", "lerobot_")):
        return
    previous = sys.excepthook

    def hook(kind, err, tb) -> None:
        user = _user_error_in(err, UserError) or _translated(err)
        if user is None or _show_tracebacks():
            previous(kind, err, tb)
            return
        _print_user_error(user)
        atexit._run_exitfuncs()  # noqa: SLF001  what a normal exit runs (logging, multiprocessing), then the status
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_USER_ERROR)

    def _translated(err: BaseException) -> BaseException | None:
        if translate is None:
            return None
        try:
            user = translate(err, list(sys.argv))
        except Exception:  # noqa: BLE001  a translator's own bug must not hide the error it was reading
            return None
        return user if isinstance(user, UserError) else None

    sys.excepthook = hook


def run_cli(fn: Callable[[], object]) -> None:
    """The one way every command-line tool ends. Runs the CLI body after `configure_output()`, with SIGTERM
    handled as Ctrl-C. A `UserError` (`lerobot_unidextok.errors`) prints one `error: <message>` line on stderr
    and exits with status 2; Ctrl-C / SIGTERM print one line and exit with 130 / 143 after the body's clean-up;
    anything else is a bug and keeps its traceback. `UNIDEXTOK_TRACEBACK=1` shows the traceback of user errors.
    The body may return an exit status (an int) for outcomes that are not errors (an INVALID dataset)."""
    configure_output()
    signal.signal(signal.SIGTERM, _terminate)
    try:
        status = fn()
    except UserError as err:
        if _show_tracebacks():
            raise
        _print_user_error(err)
        raise SystemExit(EXIT_USER_ERROR) from None
    except KeyboardInterrupt as stop:
        terminated = isinstance(stop, Terminated)
        print(f"{'terminated (SIGTERM)' if terminated else 'interrupted'}: stopped; nothing half-written was "
              "left behind", file=sys.stderr)  # fmt: skip
        raise SystemExit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED) from None
    if isinstance(status, int) and status:
        raise SystemExit(status)
