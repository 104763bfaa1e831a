"""Console output of the command-line tools: one-line errors for user mistakes, quiet optional backends,
progress bars that do not flood logs.

    def main() -> None:
        run_cli(my_draccus_cli)      # `import lerobot_unidextok` already called configure_output()
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable

# Mistakes a person can fix from the message (bad paths, values, missing downloads); anything else is a bug
# and keeps its traceback. UNIDEXTOK_TRACEBACK=1 shows the traceback for these too.
USER_ERRORS: tuple[type[BaseException], ...] = (
    ValueError,
    FileNotFoundError,
    FileExistsError,
    NotADirectoryError,
    PermissionError,
    KeyError,
    RuntimeError,
)
TORCHCODEC_NOTE = (
    "note: torchcodec cannot load FFmpeg on this machine, so LeRobot will decode videos with pyav. "
    "State-only datasets need neither; for video datasets install FFmpeg (LeRobot's system dependency, see "
    "README). `python -c 'import torchcodec'` shows the details."
)
_TORCHCODEC_WARNING = "'torchcodec' is installed but cannot be loaded"
NON_TTY_PROGRESS_INTERVAL_S = 30  # tqdm refresh interval when stderr is a file or pipe


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


def throttle_progress_bars() -> None:
    """When stderr is not a terminal, make every tqdm bar (ours, LeRobot's, datasets') refresh at most every
    30 s instead of on every update, through tqdm's TQDM_MININTERVAL default (an explicit value wins).

    tqdm reads TQDM_* when it is first imported, so this runs at the top of `import lerobot_unidextok`;
    child processes (lerobot-train, converter workers) inherit it."""
    if not sys.stderr.isatty():
        os.environ.setdefault("TQDM_MININTERVAL", str(NON_TTY_PROGRESS_INTERVAL_S))


def configure_output() -> None:
    """What `import lerobot_unidextok` does first: the torchcodec note and throttled progress bars."""
    quiet_torchcodec_warning()
    throttle_progress_bars()


def run_cli(fn: Callable[[], object]) -> None:
    """Run a CLI body; a user mistake prints `error: <message>` on stderr and exits with status 2."""
    try:
        fn()
    except USER_ERRORS as err:
        if os.environ.get("UNIDEXTOK_TRACEBACK", "0") not in ("", "0"):
            raise
        message = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"error: {message}", file=sys.stderr)
        print("(set UNIDEXTOK_TRACEBACK=1 to see the traceback)", file=sys.stderr)
        raise SystemExit(2) from None
