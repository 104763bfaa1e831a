"""Where a simulated hand's fingers close, in the wrist frame of the wrist pose its state and action hold.

The grasp centre of a hand: the centroid of its fingertips (`SimHand.fingertips`: every finger a joint moves,
the thumb included) at its `power` grasp posture, with the wrist at the zero pose, expressed in the wrist body's
frame (x along the fingers, y toward the thumb, z out of the back of the hand; `scene.py`). It is a property of
the hand alone, the same for every hand built from a URDF and every hand with a model file, by forward
kinematics in the scene the env steps. (The experts' power-grasp offsets are not used: a model file's measure the
wrist from the object's top, which depends on the object.) The recorder writes it into every dataset it records
(`record.py`, `lerobot_unidextok/data/wrist_frame.py`).
"""

from __future__ import annotations

import numpy as np

from lerobot_env_unidextok import sim_hands
from lerobot_env_unidextok.columns import WRIST_NAMES
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.scene import Scene, base_spec
from lerobot_unidextok.data.wrist_frame import ROTATION, WristFrame

GRASP_POSTURE = "power"


def grasp_centre_in_wrist_m(scene: Scene, posture: str = GRASP_POSTURE) -> np.ndarray:
    """(3,) the fingertips' centroid at `posture` in the wrist frame of `scene`'s hand (module docstring)."""
    data = mujoco.MjData(scene.model)
    data.qpos[scene.wrist_qpos] = Scene.wrist_pose_to_joints(np.zeros(6))
    scene.place_hand(data, scene.hand.posture(posture))
    mujoco.mj_kinematics(scene.model, data)
    tips = np.stack([scene.fingertip(data, f) for f in scene.hand.fingers])
    wrist = scene.model.body("wrist").id
    rotation = data.xmat[wrist].reshape(3, 3)
    return rotation.T @ (tips.mean(0) - data.xpos[wrist])


def wrist_frame_of(hand: str) -> WristFrame:
    """The wrist frame a recording of the registered hand `hand` carries (its grasp centre, the wrist columns)."""
    sim_hand = sim_hands.load(hand)
    scene = Scene.compile(base_spec(sim_hand), sim_hand)
    centre = grasp_centre_in_wrist_m(scene)
    return WristFrame(list(WRIST_NAMES), ROTATION, {hand: [round(float(x), 6) for x in centre]})


__all__ = ["GRASP_POSTURE", "grasp_centre_in_wrist_m", "wrist_frame_of"]
