"""`UniDexTokEnv`: a gymnasium env of one hand (any hand spec with a model) on the floating wrist, doing one task.

Observation `{"agent_pos": (6 + T + J,) float32}`: the wrist pose (x, y, z in m; roll, pitch, yaw in rad), the
task's object and goal columns (`Task.state_names`), with `fingertips=True` each fingertip's position from the
hand's grasp centre (15, m, `columns.FINGERTIP_COLUMNS`), then the hand's native joint state in its spec's units (an
Inspire's six values in [0, 1] for `inspire_rh56_unitree`, as Unitree's datasets record them). LeRobot maps
`agent_pos` to `observation.state`; the names are `UniDexTokEnv.state_names` and `action_names`.
Action `(6 + J,)`: the wrist target pose, then the hand's native joint command, both absolute. Values outside
the ranges are clipped (the hand's to its native range, the wrist's to its workspace, and each step's wrist
target to within 4 cm and 0.3 rad of where the wrist is); an action of another width is refused, naming the hand
and the width it takes.

One step is 0.1 s (10 Hz, `FPS`): the controls are held for 25 physics steps of 4 ms. Episodes end when the task
succeeds or fails (`terminated`), or after `max_episode_steps` (a TimeLimit). `info["is_success"]` says whether
the task succeeded, as LeRobot's `lerobot-eval` reads it. Seeded episodes are reproducible: `reset(seed=s)` draws
the episode (object, place, goal, the wrist's start) from `s` alone.
"""

from __future__ import annotations

import copy
import functools
import logging
from typing import Any

import gymnasium as gym
import numpy as np

from lerobot_env_unidextok import sim_hands
from lerobot_env_unidextok.columns import FPS, STATE_IS_NATIVE_KEY, action_names, state_names, tip_sources
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.gl import mujoco, render_problem
from lerobot_env_unidextok.grasp_centre import grasp_centre_in_wrist_m, wrist_frame_of
from lerobot_env_unidextok.scene import WRIST_NAMES, WRIST_RANGE, Scene, base_spec
from lerobot_env_unidextok.task_classes import TASKS, Task
from lerobot_unidextok.data.wrist_frame import WristFrame

logger = logging.getLogger(__name__)

SUBSTEPS = 25  # physics steps of scene.TIMESTEP_S per env step
START_POSE = np.array([-0.10, 0.0, 0.20, 0.0, 0.0, 0.0])  # where the wrist starts (x, y, z, roll, pitch, yaw)
START_NOISE = np.array([0.02, 0.02, 0.01, 0.0, 0.0, 0.05])
MAX_WRIST_STEP = np.array([0.04, 0.04, 0.04, 0.3, 0.3, 0.3])  # per env step, from the current pose


@functools.cache
def _warn_once(problem: str) -> None:
    logger.warning("no frames: %s; the frames are black", problem)


def make_scene(hand: str, task: str) -> tuple[Scene, Task]:
    """A scene of its own for (hand, task): a copy of the model compiled once per process (episodes change the
    model's object sizes and places, so envs never share one)."""
    if task not in TASKS:
        raise SimInputError(f"unknown task {task!r}; tasks: {', '.join(TASKS)}")
    sim_hand = sim_hands.load(hand)
    t = TASKS[task](sim_hand)
    scene = Scene.bind(copy.deepcopy(_compiled(hand, task)), sim_hand)
    t.bind(scene)
    return scene, t


@functools.cache
def _compiled(hand: str, task: str) -> mujoco.MjModel:
    sim_hand = sim_hands.load(hand)
    spec = base_spec(sim_hand)
    TASKS[task](sim_hand).add_to_spec(spec)
    return spec.compile()


class UniDexTokEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": FPS}

    def __init__(self, hand: str = "inspire_rh56_unitree", task: str = "GraspLift-v0",
                 render_mode: str | None = "rgb_array", width: int = 320, height: int = 240,
                 fingertips: bool = False) -> None:  # fmt: skip
        self.hand_name, self.task_name = hand, task
        self.scene, self.task = make_scene(hand, task)
        self.model = self.scene.model
        self.data = mujoco.MjData(self.model)
        self.hand = self.scene.hand
        self.render_mode, self.width, self.height = render_mode, width, height
        self._renderer: Any = None
        self._render_failed = False
        self.state_names = state_names(task, self.hand.native_names, fingertips)
        # with fingertips: the grasp centre in the wrist frame (3,) and the finger filling each finger's columns (5,)
        self._tips = (grasp_centre_in_wrist_m(self.scene), tip_sources(self.hand.fingers)) if fingertips else None
        self._wrist_body = self.model.body("wrist").id
        self.action_names = action_names(self.hand.native_names)
        j = len(self.hand.native_names)
        raw_lo, raw_hi = np.asarray(self.hand.spec.raw_range(self.hand.side), dtype=np.float64).T
        wrist_lo = np.array([WRIST_RANGE[n][0] for n in WRIST_NAMES])
        wrist_hi = np.array([WRIST_RANGE[n][1] for n in WRIST_NAMES])
        self.action_low = np.concatenate([wrist_lo, raw_lo]).astype(np.float32)
        self.action_high = np.concatenate([wrist_hi, raw_hi]).astype(np.float32)
        self.action_space = gym.spaces.Box(self.action_low, self.action_high, shape=(6 + j,), dtype=np.float32)
        width_obs = len(self.state_names)
        self.observation_space = gym.spaces.Dict(
            {"agent_pos": gym.spaces.Box(-np.inf, np.inf, shape=(width_obs,), dtype=np.float32),
             STATE_IS_NATIVE_KEY: gym.spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32)}
        )  # fmt: skip
        self.task_description = self.task.description

    # -- episode ---------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        rng = self.np_random
        mujoco.mj_resetData(self.model, self.data)
        start = START_POSE + rng.uniform(-1, 1, 6) * START_NOISE
        self.data.qpos[self.scene.wrist_qpos] = Scene.wrist_pose_to_joints(start)
        open_raw = self.hand.posture("open")
        self.scene.place_hand(self.data, open_raw)
        self.task.reset(self.data, rng)
        self.scene.set_controls(self.data, start, open_raw)
        mujoco.mj_forward(self.model, self.data)
        return self._obs(), {"is_success": False}

    def step(self, action: np.ndarray):
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape[0] != self.action_space.shape[0]:
            raise SimInputError(
                f"the action has {action.shape[0]} values, but this env's hand {self.hand_name!r} takes "
                f"{self.action_space.shape[0]}: the wrist pose (6) and its {len(self.hand.native_names)} native "
                f"joints ({', '.join(self.hand.native_names)}). A policy trained on another hand must be bound to "
                f"this one first: unidextok-deploy --checkpoint=<policy> --robot=<a converted dataset of "
                f"{self.hand_name}> --zero_shot=true (docs/lerobot.md, 'Closed-loop evaluation')"
            )
        action = np.clip(action, self.action_low, self.action_high)
        pose = self.scene.wrist_pose(self.data)
        wrist = np.clip(action[:6], pose - MAX_WRIST_STEP, pose + MAX_WRIST_STEP)
        self.scene.set_controls(self.data, wrist, action[6:])
        for _ in range(SUBSTEPS):
            mujoco.mj_step(self.model, self.data)
        success, failed = self.task.evaluate(self.data)
        info = {"is_success": success}
        return self._obs(), float(success), bool(success or failed), False, info

    def _obs(self) -> dict[str, np.ndarray]:
        tips = () if self._tips is None else (self._fingertips_m(),)
        state = np.concatenate([self.scene.wrist_pose(self.data), self.task.observe(self.data), *tips,
                                self.scene.native_state(self.data)])  # fmt: skip
        return {"agent_pos": state.astype(np.float32), STATE_IS_NATIVE_KEY: np.ones(1, dtype=np.float32)}

    def _fingertips_m(self) -> np.ndarray:
        """(15,) the tip of each finger of `tip_sources` minus the grasp centre, world axes (m)."""
        centre_in_wrist_m, sources = self._tips
        b = self._wrist_body
        centre = self.data.xpos[b] + self.data.xmat[b].reshape(3, 3) @ centre_in_wrist_m  # (3,) world
        tips = {f: self.scene.fingertip(self.data, f) - centre for f in set(sources)}
        return np.concatenate([tips[f] for f in sources])

    def wrist_frame(self) -> WristFrame:
        """The wrist frame a recording of this hand carries: the wrist columns and the hand's grasp centre
        (`grasp_centre.py`)."""
        return wrist_frame_of(self.hand_name)

    # -- rendering -------------------------------------------------------------------------------
    def render(self) -> np.ndarray:
        """An RGB frame (H, W, 3) uint8 from the scene's camera; black where MuJoCo cannot render (`gl.py`: no
        display and no headless backend), with one warning per process, never a crash."""
        if self._renderer is None and not self._render_failed:
            problem = render_problem()
            if problem is None:
                try:
                    self._renderer = mujoco.Renderer(self.model, self.height, self.width)
                except Exception as err:  # noqa: BLE001 (no GL context: EGL/OSMesa present but not working)
                    problem = f"MuJoCo cannot open an OpenGL context here ({' '.join(str(err).split())})"
            if self._renderer is None:
                self._render_failed = True
                _warn_once(problem)
        if self._renderer is None:
            return np.zeros((self.height, self.width, 3), dtype=np.uint8)
        self._renderer.update_scene(self.data, camera="front")
        return self._renderer.render()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
