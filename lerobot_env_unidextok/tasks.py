"""The `Task` base and the first two tasks: what each adds to the scene, how an episode is drawn, what it observes,
when it succeeds. Each later task has a module of its own (`finger_sequence.py`, `pinch_place.py`, `chord_press.py`, `pinch_lift.py`); `task_classes.py`
lists them all.

- `GraspLift-v0`: one object on the table, drawn per episode: a box or an upright cylinder wide enough to need a
  power grasp, or a small cube or block that a power grasp's fingers close past (a pinch). Size, place and yaw
  vary. Success: the object's centre 6 cm above where it rested (`goal_z`).
- `FingerPress-v0`: a panel with one button under each finger but the thumb (index, middle, ring, little; the
  ones the hand has), its place drawn per episode; the goal names one finger. Success: that button pressed
  (4 mm) while that finger touches it; pressing any other button ends the episode as a failure.

Each task's columns of the observation (`state_names`) come after the wrist pose and before the hand's native
joints; they are the same for every hand, so datasets of different hands mix by name.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from lerobot_env_unidextok.columns import PRESS_FINGERS, TASK_COLUMNS, TASK_TEXT
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import SimHand
from lerobot_env_unidextok.objects import DENSITY, SHAPES, Shape
from lerobot_env_unidextok.scene import Scene, base_spec

TABLE_Z = 0.0


class Task(abc.ABC):
    """One task: scene objects, episode sampling, observation columns, success."""

    name: str  # the gym id's task part, e.g. "GraspLift-v0"
    description: str  # the episode's task text
    # whether the hand closes on an object: only then does a recording carry the hand's grasp centre (the wrist
    # frame of `grasp_centre.py`). Measured in closed loop: zero-shot presses with the grasp centre's frame
    # succeeded 0-35 % against 73-90 % without it (docs/pooling.md)
    grasps: bool = False

    def __init__(self, hand: SimHand) -> None:
        self.hand = hand

    @abc.abstractmethod
    def state_names(self) -> list[str]: ...

    @abc.abstractmethod
    def add_to_spec(self, spec: mujoco.MjSpec) -> None: ...

    @abc.abstractmethod
    def bind(self, scene: Scene) -> None: ...

    @abc.abstractmethod
    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None: ...

    @abc.abstractmethod
    def observe(self, data: mujoco.MjData) -> np.ndarray: ...

    @abc.abstractmethod
    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        """(success, failed) now."""

    def failure_reason(self, terminated: bool) -> str:
        """How an episode that did not succeed failed (`terminated`: the task ended it), for the benchmark."""
        return "failed" if terminated else "timeout"


# ---------------------------------------------------------------------------------------------
# grasp and lift
# ---------------------------------------------------------------------------------------------
PARK = np.array([2.0, 2.0, 0.5])  # where unused objects wait, far from everything


def half_extents(shape: Shape, size: np.ndarray) -> np.ndarray:
    """(3,) half extents x, y, z of a shape with size parameters `size`."""
    if shape.geom == "box":
        return np.resize(size, 3)
    if shape.geom == "cylinder":
        return np.array([size[0], size[0], size[1]])
    return np.array([size[0]] * 3)


def geom_size(shape: Shape, size: np.ndarray) -> list[float]:
    """MuJoCo's size triple of a shape with size parameters `size`."""
    if shape.geom == "box":
        return list(half_extents(shape, size))
    return [*size, *[0.0] * (3 - len(size))]


class GraspLift(Task):
    name = "GraspLift-v0"
    grasps = True
    description = TASK_TEXT[name]
    LIFT_M = 0.06
    AREA = ((0.02, 0.12), (-0.08, 0.08))  # x, y ranges of the object's centre (m)
    YAW = 0.5  # boxes: yaw drawn in [-YAW, YAW] rad

    def __init__(self, hand: SimHand) -> None:
        super().__init__(hand)
        self.shape: Shape = SHAPES[0]
        self.half = np.zeros(3)
        self.rest_z = 0.0

    def state_names(self) -> list[str]:
        return list(TASK_COLUMNS[self.name])

    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        colours = {"box": [0.85, 0.3, 0.2, 1], "cylinder": [0.2, 0.5, 0.85, 1], "block": [0.2, 0.7, 0.3, 1],
                   "cube": [0.9, 0.7, 0.1, 1]}  # fmt: skip
        for i, shape in enumerate(SHAPES):
            body = spec.worldbody.add_body(name=f"object_{shape.name}", pos=list(PARK + [0.2 * i, 0, 0]))
            body.add_freejoint(name=f"object_{shape.name}")
            size = geom_size(shape, np.array([hi for _, hi in shape.half_m]))
            body.add_geom(name=f"object_{shape.name}", type=getattr(mujoco.mjtGeom, f"mjGEOM_{shape.geom.upper()}"),
                          size=size, rgba=colours[shape.name], friction=[2.0, 0.05, 0.01], condim=6,
                          density=DENSITY)  # fmt: skip

    def bind(self, scene: Scene) -> None:
        m = scene.model
        self.scene = scene
        self.body = {s.name: m.body(f"object_{s.name}").id for s in SHAPES}
        self.geom = {s.name: m.geom(f"object_{s.name}").id for s in SHAPES}
        self.qpos = {s.name: int(m.jnt_qposadr[m.joint(f"object_{s.name}").id]) for s in SHAPES}
        self.qvel = {s.name: int(m.jnt_dofadr[m.joint(f"object_{s.name}").id]) for s in SHAPES}

    def _resize(self, shape: Shape, size: np.ndarray) -> None:
        """Set a shape's size, mass and inertia (solid, DENSITY) and its bounding volumes."""
        m, g, b = self.scene.model, self.geom[shape.name], self.body[shape.name]
        half = half_extents(shape, size)
        m.geom_size[g] = geom_size(shape, size)
        if shape.geom == "box":
            volume = 8 * np.prod(half)
            inertia = volume * DENSITY / 3 * np.array([half[1] ** 2 + half[2] ** 2, half[0] ** 2 + half[2] ** 2,
                                                       half[0] ** 2 + half[1] ** 2])  # fmt: skip
        elif shape.geom == "cylinder":
            r, h = size
            volume = np.pi * r**2 * 2 * h
            mass = volume * DENSITY
            inertia = np.array([mass * (3 * r**2 + (2 * h) ** 2) / 12] * 2 + [mass * r**2 / 2])
        else:
            volume = 4 / 3 * np.pi * size[0] ** 3
            inertia = np.full(3, 2 / 5 * volume * DENSITY * size[0] ** 2)
        m.body_mass[b] = volume * DENSITY
        m.body_inertia[b] = inertia
        m.geom_rbound[g] = float(np.linalg.norm(half))
        m.geom_aabb[g] = np.concatenate([np.zeros(3), half])

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        self.shape = SHAPES[rng.integers(len(SHAPES))]
        size = np.array([rng.uniform(lo, hi) for lo, hi in self.shape.half_m])
        if len(size) == 3:
            size[1] = size[0] + rng.uniform(-0.002, 0.002)  # near-square footprint: any side is a grasp
        self._resize(self.shape, size)
        self.half = half_extents(self.shape, size)
        xy = np.array([rng.uniform(*self.AREA[0]), rng.uniform(*self.AREA[1])])
        yaw = rng.uniform(-self.YAW, self.YAW) if self.shape.yaw else 0.0
        self.rest_z = TABLE_Z + self.half[2]
        for i, s in enumerate(SHAPES):
            q, v = self.qpos[s.name], self.qvel[s.name]
            pos = np.array([*xy, self.rest_z]) if s is self.shape else PARK + [0.2 * i, 0, 0]
            data.qpos[q : q + 3] = pos
            data.qpos[q + 3 : q + 7] = [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)] if s is self.shape else [1, 0, 0, 0]
            data.qvel[v : v + 6] = 0

    def object_pose(self, data: mujoco.MjData) -> tuple[np.ndarray, float]:
        """(position (3,), yaw folded into [-pi/4, pi/4] for boxes, 0 for round shapes)."""
        q = self.qpos[self.shape.name]
        w, x, y, z = data.qpos[q + 3 : q + 7]
        yaw = float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
        if not self.shape.yaw:
            yaw = 0.0
        else:
            yaw = (yaw + np.pi / 4) % (np.pi / 2) - np.pi / 4
        return data.qpos[q : q + 3].copy(), yaw

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        pos, yaw = self.object_pose(data)
        return np.array([*pos, yaw, *self.half, self.rest_z + self.LIFT_M])

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        z = data.qpos[self.qpos[self.shape.name] + 2]
        return bool(z >= self.rest_z + self.LIFT_M), False

    def failure_reason(self, terminated: bool) -> str:
        return self.shape.grasp  # the kind of grasp the object needed


# ---------------------------------------------------------------------------------------------
# press the button under the named finger
# ---------------------------------------------------------------------------------------------

@dataclass
class Button:
    finger: str
    body: int = -1
    geom: int = -1
    qpos: int = -1


class FingerPress(Task):
    name = "FingerPress-v0"
    description = TASK_TEXT[name]
    PRESSED_M = 0.004
    TRAVEL_M = 0.012
    AREA = ((0.07, 0.11), (-0.025, 0.025))  # x, y ranges of the panel's origin (m)
    # the wrist over the panel when pressing, relative to the panel's origin: the same for every hand
    HOVER_M = np.array([-0.11, 0.0, 0.16])

    def __init__(self, hand: SimHand) -> None:
        super().__init__(hand)
        self.fingers = tuple(f for f in PRESS_FINGERS if f in hand.fingers)
        self.goal = self.fingers[0]
        self.buttons: dict[str, Button] = {}
        self.ended_wrong = False

    def state_names(self) -> list[str]:
        return list(TASK_COLUMNS[self.name])

    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        geometry = press_geometry(self.hand, self.HOVER_M)
        layout = {f: top for f, (top, _) in geometry.items()}
        panel = spec.worldbody.add_body(name="panel", pos=[0.1, 0, 0])
        panel.add_geom(name="panel", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.1, 0.005], pos=[0.0, 0, 0.005],
                       rgba=[0.3, 0.3, 0.3, 1], contype=0, conaffinity=0)  # fmt: skip
        colours = {"index": [0.9, 0.2, 0.2, 1], "middle": [0.2, 0.7, 0.2, 1], "ring": [0.2, 0.3, 0.9, 1],
                   "little": [0.9, 0.8, 0.1, 1]}  # fmt: skip
        for f in self.fingers:
            top = layout[f]
            post = panel.add_body(name=f"button_{f}", pos=[top[0], top[1], 0])
            post.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.004, top[2] / 2 - 0.004, 0],
                          pos=[0, 0, top[2] / 2 - 0.004], rgba=[0.5, 0.5, 0.5, 1], contype=0, conaffinity=0)  # fmt: skip
            cap = post.add_body(name=f"cap_{f}", pos=[0, 0, top[2] - 0.004], gravcomp=1.0)
            cap.add_joint(name=f"button_{f}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1],
                          range=[-self.TRAVEL_M, 0], stiffness=20.0, damping=0.5, springref=0.0)  # fmt: skip
            # long along the finger: its tip comes down on the cap along an arc that ends over the cap's back end;
            # the cap reaches as far forward as the arc comes down to it (`press_geometry`), at least CAP_HALF_M
            half = max(CAP_HALF_M[0], (geometry[f][1] + CAP_BACK_M) / 2)
            # as wide as CAP_HALF_M, narrower where the buttons sit closer: CAP_GAP_M between neighbours' caps
            spacing = min([abs(top[1] - layout[g][1]) for g in self.fingers if g != f], default=1.0)
            width = min(CAP_HALF_M[1], (spacing - CAP_GAP_M) / 2)
            cap.add_geom(name=f"cap_{f}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[half, width, 0.004],
                         pos=[half - CAP_BACK_M, 0, 0], rgba=colours[f], mass=0.005, friction=[1, 0.01, 0.001])  # fmt: skip

    def bind(self, scene: Scene) -> None:
        m = scene.model
        self.scene = scene
        self.panel = m.body("panel").id
        # where the buttons are along the fingers, relative to the panel's origin (their posts' places)
        self.buttons_x_m = float(np.mean([m.body_pos[m.body(f"button_{f}").id][0] for f in self.fingers]))
        for f in self.fingers:
            self.buttons[f] = Button(f, m.body(f"cap_{f}").id, m.geom(f"cap_{f}").id,
                                     int(m.jnt_qposadr[m.joint(f"button_{f}").id]))  # fmt: skip

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        m = self.scene.model
        m.body_pos[self.panel] = [rng.uniform(*self.AREA[0]), rng.uniform(*self.AREA[1]), TABLE_Z]
        self.goal = self.fingers[rng.integers(len(self.fingers))]
        for b in self.buttons.values():
            data.qpos[b.qpos] = 0.0
        self.ended_wrong = False

    def panel_pos(self) -> np.ndarray:
        return self.scene.model.body_pos[self.panel].copy()

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        goal = [float(f == self.goal) for f in PRESS_FINGERS]
        return np.array([*self.panel_pos(), *goal])

    def pressed(self, data: mujoco.MjData) -> dict[str, bool]:
        return {f: bool(data.qpos[b.qpos] <= -self.PRESSED_M) for f, b in self.buttons.items()}

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        pressed = self.pressed(data)
        wrong = any(p for f, p in pressed.items() if f != self.goal)
        goal_button = self.buttons[self.goal]
        by = self.scene.fingers_touching(data, goal_button.geom) if pressed[self.goal] else set()
        success = pressed[self.goal] and self.goal in by and not wrong
        failed = wrong or (pressed[self.goal] and bool(by) and self.goal not in by)
        return success, failed

    def failure_reason(self, terminated: bool) -> str:
        return "wrong" if terminated else "timeout"  # another button pressed, or the goal's not in time


def press_geometry(hand: SimHand, hover_m: np.ndarray) -> dict[str, tuple[np.ndarray, float]]:
    """Per finger, with the wrist at `hover_m` (level, fingers along +x): the cap-top centre of its button
    relative to the panel origin (the finger's tip at its press posture, the cap top `PRESS_DEPTH_M` above it),
    and how far forward of that (m, along x) the tip comes down to the cap's height on its way from the open pose
    to the press posture (the commands in between, as the expert sends them)."""
    scene = Scene.compile(base_spec(hand), hand)
    m, d = scene.model, mujoco.MjData(scene.model)

    def tip_at(finger: str, native: np.ndarray) -> np.ndarray:
        d.qpos[:] = m.qpos0
        d.qpos[scene.wrist_qpos] = Scene.wrist_pose_to_joints(np.array([*hover_m, 0, 0, 0]))
        scene.place_hand(d, native)
        mujoco.mj_kinematics(m, d)
        return scene.fingertip(d, finger)

    out = {}
    open_ = hand.posture("open")
    for f in (f for f in PRESS_FINGERS if f in hand.fingers):
        press = hand.posture(f"press_{f}")
        tip = tip_at(f, press)
        top = tip + np.array([0, 0, PRESS_DEPTH_M])
        path = [tip_at(f, (1 - a) * open_ + a * press) for a in np.linspace(0, 1, 41)]
        reach = max([p[0] - tip[0] for p in path if p[2] <= top[2] + CAP_CLEAR_M], default=0.0)
        out[f] = (top, float(reach) + CAP_CLEAR_M)
    return out


PRESS_DEPTH_M = 0.008  # the press posture puts the tip this far below the cap's resting top
CAP_HALF_M = (0.02, 0.0065)  # a button cap's half length (along the fingers, at least) and half width
CAP_BACK_M = 0.008  # the cap reaches this far behind the press posture's tip
CAP_GAP_M = 0.0065  # at least this far between two buttons' caps (fingertips that meet when pressing, the BrainCo's)
CAP_CLEAR_M = 0.01  # the cap reaches this far past where the tip comes down to this height over it
