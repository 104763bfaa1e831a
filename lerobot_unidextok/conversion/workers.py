"""Worker processes that end with the conversion that started them, however it ends.

`unidextok-convert --num_workers=N` reads episodes in a process pool started through a forkserver. A pool
shuts down with its `with` block, but a conversion killed with SIGKILL runs no code, and before this module a
SIGTERM left the forkserver and every worker alive (about 0.7 GB each). So each of them watches the process it
must not outlive: the forkserver its starter (the conversion, whose pid it reads from `PARENT_ENV`), each
worker the forkserver and the conversion. On Linux the kernel delivers SIGKILL when the parent dies
(`prctl(PR_SET_PDEATHSIG)`); everywhere a daemon thread also polls the watched pid once a second and exits.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

from lerobot_unidextok.utils.files import process_alive

PARENT_ENV = "UNIDEXTOK_CONVERT_PARENT"  # pid of the conversion, for the forkserver it starts
POLL_S = 1.0
_PR_SET_PDEATHSIG = 1


def die_with(*pids: int) -> None:
    """End this process when its parent dies (Linux: the kernel's SIGKILL) or when any of `pids` is gone."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        except (OSError, AttributeError):
            pass
    watched = [os.getppid(), *pids]

    def watch() -> None:
        while all(process_alive(pid) for pid in watched):
            time.sleep(POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="unidextok-die-with-parent", daemon=True).start()


# The forkserver imports this module (set_forkserver_preload) right after the conversion started it: there, and
# only there, the parent's pid is the one the conversion left in PARENT_ENV. Anywhere else this does nothing.
if os.environ.get(PARENT_ENV) == str(os.getppid()):
    die_with()


__all__ = ["PARENT_ENV", "die_with"]
