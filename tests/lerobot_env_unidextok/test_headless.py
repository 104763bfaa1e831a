"""Rendering on a machine without a display, with `MUJOCO_GL` unset, as LeRobot's CLIs run the simulator: the
OpenGL backend is chosen before any MuJoCo import the plugin makes (`lerobot_env_unidextok/gl.py`).

Before: `lerobot-eval --env.type=unidextok --env.hand=unitree_dex3_1` aborted (SIGABRT in GLFW, "DISPLAY environment
variable is missing") because building the hand's model imported MuJoCo before the env chose EGL. Each case runs
in a fresh interpreter, the way LeRobot's config and gym.make reach the env."""

import os
import subprocess
import sys

import pytest
from linkerhand_udhm import subprocess_env

FRAME = """
import os
{first}
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
import gymnasium as gym
cfg = UniDexTokEnvConfig(hand={hand!r})
env = gym.make(cfg.gym_id, disable_env_checker=True, **cfg.gym_kwargs)
env.reset(seed=0)
frames = [env.render() for _ in range(2)]
print("RESULT", os.environ.get("MUJOCO_GL"), frames[0].shape, int(frames[0].max()))
"""


def _run(code: str, tmp_path) -> tuple[list[str], list[str]]:
    """(the RESULT line's fields, the warning lines) of `code` with no display and MUJOCO_GL unset."""
    env = {k: v for k, v in subprocess_env(OMP_NUM_THREADS="1").items()
           if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY", "PYOPENGL_PLATFORM")}  # fmt: skip
    r = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    (result,) = [line.split()[1:] for line in r.stdout.splitlines() if line.startswith("RESULT")]
    return result, [line for line in r.stderr.splitlines() if "no frames:" in line]


@pytest.mark.skipif(sys.platform != "linux", reason="the headless backends (EGL, OSMesa) are Linux's")
@pytest.mark.parametrize("hand", ["unitree_dex3_1"])
def test_a_hand_renders_headless_with_mujoco_gl_unset(hand, tmp_path):
    """A built hand (its model loads MuJoCo while LeRobot's config is parsed) and a model-file hand: the process
    lives, and draws frames with the backend chosen for it, or, where none works, says so in one warning line."""
    (backend, *shape, brightest), warnings = _run(FRAME.format(first="", hand=hand), tmp_path)
    assert "".join(shape) == "(240,320,3)"
    if backend == "disable":  # no libEGL nor libOSMesa here: black frames, one warning
        assert int(brightest) == 0 and len(warnings) == 1, warnings
    else:
        assert backend in ("egl", "osmesa") and int(brightest) > 0 and warnings == [], (backend, warnings)


@pytest.mark.skipif(sys.platform != "linux", reason="GLFW without a display is the Linux case")
def test_mujoco_loaded_by_someone_else_first_gives_black_frames_and_one_warning_not_an_abort(tmp_path):
    """A program that imported MuJoCo itself with MUJOCO_GL unset has GLFW and no display: the env draws no frame
    (GLFW would abort the process) and says why once, naming the fix."""
    (backend, *_, brightest), warnings = _run(FRAME.format(first="import mujoco", hand="unitree_dex3_1"), tmp_path)
    assert int(brightest) == 0 and len(warnings) == 1, warnings
    assert "GLFW" in warnings[0] and "MUJOCO_GL=egl" in warnings[0]


def test_the_choice_keeps_a_backend_the_user_set(monkeypatch):
    from lerobot_env_unidextok import gl

    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.delenv("DISPLAY", raising=False)
    assert gl.choose_gl_backend() is None and os.environ["MUJOCO_GL"] == "osmesa"
