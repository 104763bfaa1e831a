"""The MuJoCo scene: a table, a floating 6-DoF wrist (position-controlled, the same for every hand) carrying one
hand, and a task's objects. Built with `mujoco.MjSpec` (the hand's own MJCF attached under the wrist), once per
(hand, task) in a process.

Wrist frame: x along the fingers, y toward the thumb (a right hand, palm down), z out of the back of the hand.
Its six joints are, in order, slides along world x, y, z and hinges about z (yaw), y (pitch) and x (roll)
(orientation Rz(yaw) Ry(pitch) Rx(roll)); each has a position actuator, and the wrist and the hand are
gravity-compensated, so a constant target holds the hand still.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_env_unidextok.columns import WRIST_NAMES
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import SimHand

TIMESTEP_S = 0.004
WRIST_JOINTS = ("wrist_x", "wrist_y", "wrist_z", "wrist_yaw", "wrist_pitch", "wrist_roll")
__all__ = ["WRIST_NAMES", "Scene", "base_spec"]
WRIST_RANGE = {"wrist_x": (-0.35, 0.35), "wrist_y": (-0.35, 0.35), "wrist_z": (0.0, 0.45),
               "wrist_yaw": (-1.6, 1.6), "wrist_pitch": (-1.2, 1.2), "wrist_roll": (-1.6, 1.6)}  # fmt: skip
WRIST_KP = {"slide": 3000.0, "hinge": 60.0}
WRIST_KV = {"slide": 150.0, "hinge": 3.0}

SCENE_XML = """
<mujoco model="unidextok_sim">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep}" integrator="implicitfast" cone="elliptic" impratio="5"/>
  <visual>
    <headlight diffuse="0.6 0.6 0.6" ambient="0.35 0.35 0.35" specular="0 0 0"/>
    <global offwidth="640" offheight="480" azimuth="150" elevation="-30"/>
  </visual>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.55 0.5 0.45" rgb2="0.5 0.45 0.4" width="256" height="256"/>
    <material name="table" texture="grid" texrepeat="24 24" reflectance="0"/>
    <material name="hand" rgba="0.25 0.3 0.35 1"/>
  </asset>
  <default>
    <default class="wrist">
      <joint damping="0" armature="0.05" limited="true"/>
    </default>
  </default>
  <worldbody>
    <light pos="0 0 1.5" dir="0 0 -1" diffuse="0.7 0.7 0.7"/>
    <geom name="table" type="plane" size="2 2 0.02" material="table" friction="1 0.01 0.001"/>
    <camera name="front" pos="0.45 -0.35 0.38" mode="targetbody" target="wrist"/>
    <body name="wrist" gravcomp="1">
      <inertial pos="0 0 0" mass="0.2" diaginertia="2e-4 2e-4 2e-4"/>
      {joints}
      <site name="wrist" size="0.008" rgba="1 0.5 0 1"/>
    </body>
  </worldbody>
  <actuator>
    {actuators}
  </actuator>
</mujoco>
"""


def _wrist_xml() -> tuple[str, str]:
    axes = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
    joints, acts = [], []
    for name in WRIST_JOINTS:
        kind = "slide" if name in ("wrist_x", "wrist_y", "wrist_z") else "hinge"
        axis = axes[name[-1]] if kind == "slide" else axes[{"wrist_yaw": "z", "wrist_pitch": "y", "wrist_roll": "x"}[name]]
        lo, hi = WRIST_RANGE[name]
        joints.append(f'<joint name="{name}" class="wrist" type="{kind}" axis="{axis}" range="{lo} {hi}"/>')
        acts.append(f'<position name="{name}" joint="{name}" kp="{WRIST_KP[kind]}" kv="{WRIST_KV[kind]}" '
                    f'ctrlrange="{lo} {hi}"/>')  # fmt: skip
    return "\n      ".join(joints), "\n    ".join(acts)


def _matrix_to_quat(matrix: tuple[tuple[float, ...], ...]) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.asarray(matrix, dtype=np.float64).ravel())
    return quat


def hand_spec(hand: SimHand) -> mujoco.MjSpec:
    """The hand's own model as an MjSpec (before attaching)."""
    return mujoco.MjSpec.from_string(hand.model_xml)


def base_spec(hand: SimHand) -> mujoco.MjSpec:
    """Table, wrist and the hand attached to the wrist (no task objects yet)."""
    joints, acts = _wrist_xml()
    spec = mujoco.MjSpec.from_string(SCENE_XML.format(timestep=TIMESTEP_S, joints=joints, actuators=acts))
    child = hand_spec(hand)
    for attr in ("nuser_jnt", "nuser_site", "nuser_tendon", "nuser_actuator", "nuser_sensor", "nuser_geom",
                 "nuser_body", "nuser_cam"):  # fmt: skip
        setattr(spec, attr, max(getattr(spec, attr), getattr(child, attr)))
    child.njmax, child.nconmax = -1, -1  # MuJoCo sizes them; a conflict would be logged to MUJOCO_LOG.TXT in the cwd
    frame = spec.body("wrist").add_frame(pos=list(hand.mount_pos_m), quat=list(_matrix_to_quat(hand.mount_matrix)))
    root = child.body(hand.root)
    root.pos, root.quat = [0, 0, 0], [1, 0, 0, 0]  # the mount places the root's own frame
    frame.attach_body(root, "hand/", "")
    for body in spec.bodies:
        if body.name.startswith("hand/"):
            body.gravcomp = 1.0
    return spec


@dataclass
class Scene:
    """A compiled scene and the indices the env reads and writes every step."""

    model: mujoco.MjModel
    hand: SimHand
    wrist_qpos: np.ndarray  # (6,) qpos addresses, WRIST_JOINTS order
    wrist_act: np.ndarray  # (6,) actuator ids, WRIST_JOINTS order
    hand_act: dict[str, int]  # hand actuator name -> id
    measure_qpos: dict[str, int]  # MJCF joint name -> qpos address of each measuring joint
    tip_body: dict[str, int]  # finger -> body id
    tip_point: dict[str, np.ndarray]  # finger -> contact point in that body (m)
    finger_geoms: dict[str, frozenset[int]]  # finger -> its geoms

    @classmethod
    def compile(cls, spec: mujoco.MjSpec, hand: SimHand) -> Scene:
        return cls.bind(spec.compile(), hand)

    @classmethod
    def bind(cls, model: mujoco.MjModel, hand: SimHand) -> Scene:
        """The scene of a compiled `model` (its indices read by name)."""
        p = "hand/"
        finger_geoms = {}
        for finger, bodies in hand.finger_bodies.items():
            ids = {model.body(p + b).id for b in bodies}
            finger_geoms[finger] = frozenset(int(g) for g in np.flatnonzero(np.isin(model.geom_bodyid, list(ids))))
        names = {**{d.actuator: d for d in hand.drives if d.actuator}, **dict.fromkeys(hand.held)}
        return cls(
            model=model,
            hand=hand,
            wrist_qpos=np.array([model.jnt_qposadr[model.joint(j).id] for j in WRIST_JOINTS]),
            wrist_act=np.array([model.actuator(j).id for j in WRIST_JOINTS]),
            hand_act={a: model.actuator(p + a).id for a in names},
            measure_qpos={d.joint: int(model.jnt_qposadr[model.joint(p + d.joint).id]) for d in hand.measuring if d},
            tip_body={f: model.body(p + b).id for f, (b, _) in hand.fingertips.items()},
            tip_point={f: np.asarray(pt, dtype=np.float64) for f, (_, pt) in hand.fingertips.items()},
            finger_geoms=finger_geoms,
        )

    # -- wrist pose <-> joints ---------------------------------------------------------------------
    @staticmethod
    def wrist_pose_to_joints(pose: np.ndarray) -> np.ndarray:
        """(6,) x, y, z, roll, pitch, yaw -> (6,) in WRIST_JOINTS order."""
        x, y, z, roll, pitch, yaw = pose
        return np.array([x, y, z, yaw, pitch, roll])

    @staticmethod
    def wrist_joints_to_pose(q: np.ndarray) -> np.ndarray:
        x, y, z, yaw, pitch, roll = q
        return np.array([x, y, z, roll, pitch, yaw])

    def wrist_pose(self, data: mujoco.MjData) -> np.ndarray:
        return self.wrist_joints_to_pose(data.qpos[self.wrist_qpos])

    def native_state(self, data: mujoco.MjData) -> np.ndarray:
        return self.hand.native_state({j: data.qpos[a] for j, a in self.measure_qpos.items()})

    def place_hand(self, data: mujoco.MjData, native_raw: np.ndarray) -> None:
        """Put the hand's joints where `native_raw` drives them (clipped to the joints' ranges): a start pose."""
        hand, model = self.hand, self.model
        rad = hand.spec.to_radians(np.asarray(native_raw, dtype=np.float64), hand.side, "clip")
        index = {n: i for i, n in enumerate(hand.native_names)}
        for drive in hand.drives:
            joint = model.joint("hand/" + drive.joint).id
            lo, hi = model.jnt_range[joint]
            data.qpos[model.jnt_qposadr[joint]] = np.clip(drive.to_joint(rad[index[drive.native]]), lo, hi)
        for e in range(model.neq):  # mimic followers (a URDF's, built as joint equalities) where their leaders put them
            if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT):
                c, leader = model.eq_data[e], data.qpos[model.jnt_qposadr[model.eq_obj2id[e]]]
                data.qpos[model.jnt_qposadr[model.eq_obj1id[e]]] = c[0] + c[1] * leader

    def set_controls(self, data: mujoco.MjData, wrist_pose: np.ndarray, native_command: np.ndarray) -> None:
        data.ctrl[self.wrist_act] = self.wrist_pose_to_joints(wrist_pose)
        for name, target in self.hand.command(native_command).items():
            data.ctrl[self.hand_act[name]] = target
        np.clip(data.ctrl, self.model.actuator_ctrlrange[:, 0], self.model.actuator_ctrlrange[:, 1], out=data.ctrl)

    def fingertip(self, data: mujoco.MjData, finger: str) -> np.ndarray:
        b = self.tip_body[finger]
        return data.xpos[b] + data.xmat[b].reshape(3, 3) @ self.tip_point[finger]

    def fingers_touching(self, data: mujoco.MjData, geom: int) -> set[str]:
        """Fingers whose geoms touch `geom` now."""
        out = set()
        for c in data.contact[: data.ncon]:
            other = c.geom2 if c.geom1 == geom else c.geom1 if c.geom2 == geom else None
            if other is None:
                continue
            out |= {f for f, gs in self.finger_geoms.items() if other in gs}
        return out

