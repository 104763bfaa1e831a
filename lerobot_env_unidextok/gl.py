"""MuJoCo, its OpenGL backend chosen before it loads: the simulator's one `import mujoco` (`from
lerobot_env_unidextok.gl import mujoco` everywhere else; tests/test_import_cycles.py holds every module to it).

MuJoCo picks its backend once, when it is imported, from `MUJOCO_GL`. Left unset on a Linux machine without a
display it picks GLFW, and the first frame aborted the process (SIGABRT after GLFW's "DISPLAY environment variable
is missing"); a built hand's model imported MuJoCo before the env could choose. So this module chooses first: a
`MUJOCO_GL` already set is kept, a display (or another system than Linux) leaves MuJoCo its own choice, else EGL
when libEGL is installed (software rendering: no GPU needed), OSMesa when libOSMesa is, else rendering is off.
`render_problem()` says why no frame can be drawn here, if so; the env then draws none (`env.py`).
"""

from __future__ import annotations

import ctypes.util
import os
import sys

HEADLESS_BACKENDS = (("egl", "EGL"), ("osmesa", "OSMesa"))  # (MUJOCO_GL, the library it needs), in preference


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def choose_gl_backend() -> str | None:
    """Set `MUJOCO_GL` for a headless Linux process (module docstring) and return what this module chose; None:
    left as it was (set by the user, or MuJoCo's own choice)."""
    if "MUJOCO_GL" in os.environ or sys.platform != "linux" or has_display():
        return None
    chosen = next((gl for gl, lib in HEADLESS_BACKENDS if ctypes.util.find_library(lib)), "disable")
    os.environ["MUJOCO_GL"] = chosen
    return chosen


CHOSEN = choose_gl_backend()

import mujoco  # noqa: E402  (after the choice: MuJoCo reads MUJOCO_GL when it loads)


def render_problem() -> str | None:
    """Why MuJoCo cannot draw a frame in this process (one phrase naming the fix), or None when it can try."""
    backend = os.environ.get("MUJOCO_GL", "")
    context = getattr(mujoco, "GLContext", None)
    if context is None and CHOSEN == "disable":
        return ("MuJoCo has no OpenGL backend here: no display, and neither libEGL nor libOSMesa is installed "
                "(install one, e.g. apt install libegl1)")  # fmt: skip
    if context is None:
        return f"MuJoCo's rendering is off (MUJOCO_GL={backend}): set MUJOCO_GL=egl to render without a display"
    if context.__module__ == "mujoco.glfw" and sys.platform == "linux" and not has_display():
        return ("MuJoCo was loaded with GLFW and there is no display (something imported mujoco before "
                "lerobot_env_unidextok with MUJOCO_GL unset): set MUJOCO_GL=egl")  # fmt: skip
    return None


__all__ = ["choose_gl_backend", "mujoco", "render_problem"]
