"""Where a simulated hand's fingers close, in the wrist frame of the wrist pose its state and action hold.

The grasp centre of a hand depends on the grip its task asks for (`Task.grip`):

- `power` (GraspLift-v0): the centroid of its fingertips (`SimHand.fingertips`: every finger a joint moves, the
  thumb included) at its `power` grasp posture;
- `pinch` (PinchPlace-v0, PinchLift-v0): where a thumb-finger pinch holds an object, the mean of its thumb-index
  and thumb-middle pinch points (`pinch_place.Pinch.point_m`, halfway between the two fingers where they close to
  the middle of the tasks' cylinder widths). The fingertip centroid at the power posture lies 4-8 cm from the
  object a hand pinches, where the experts hold it 1.5-3.2 cm from the other hands' mean; the pinch point lies
  on it, 0.1-1.2 cm from theirs (`experiments/grasp_points.py --task=PinchLift-v0`, docs/tasks.md).

Both with the wrist at the zero pose, expressed in the wrist body's frame (x along the fingers, y toward the thumb,
z out of the back of the hand; `scene.py`). It is a property of the hand and the grip alone, the same for every
hand built from a URDF and every hand with a model file, by forward kinematics in the scene the env steps. (The
experts' power-grasp offsets are not used: a model file's measure the wrist from the object's top, which depends on
the object.) The recorder writes it into every dataset it records (`record.py`,
`lerobot_unidextok/data/wrist_frame.py`).
"""

from __future__ import annotations

import numpy as np

from lerobot_env_unidextok import sim_hands
from lerobot_env_unidextok.columns import WRIST_NAMES
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.pinch_place import PINCH_FINGERS, RADIUS_M, pinch_of
from lerobot_env_unidextok.scene import Scene, base_spec
from lerobot_unidextok.data.wrist_frame import ROTATION, WristFrame

GRIPS = ("power", "pinch")  # Task.grip


def grasp_centre_in_wrist_m(scene: Scene, grip: str = "power") -> np.ndarray:
    """(3,) where `scene`'s hand closes for `grip`, in its wrist frame (module docstring)."""
    if grip == "pinch":
        width_m = float(np.mean(RADIUS_M)) * 2
        return np.mean([pinch_of(scene.hand, f).point_m(width_m) for f in PINCH_FINGERS], axis=0)
    if grip != "power":
        raise ValueError(f"grip must be one of {GRIPS}, got {grip!r}")
    data = mujoco.MjData(scene.model)
    data.qpos[scene.wrist_qpos] = Scene.wrist_pose_to_joints(np.zeros(6))
    scene.place_hand(data, scene.hand.posture("power"))
    mujoco.mj_kinematics(scene.model, data)
    tips = np.stack([scene.fingertip(data, f) for f in scene.hand.fingers])
    wrist = scene.model.body("wrist").id
    rotation = data.xmat[wrist].reshape(3, 3)
    return rotation.T @ (tips.mean(0) - data.xpos[wrist])


def wrist_frame_of(hand: str, grip: str = "power") -> WristFrame:
    """The wrist frame a recording of the registered hand `hand` carries for a task of `grip` (its grasp centre,
    the wrist columns)."""
    sim_hand = sim_hands.load(hand)
    scene = Scene.compile(base_spec(sim_hand), sim_hand)
    centre = grasp_centre_in_wrist_m(scene, grip)
    return WristFrame(list(WRIST_NAMES), ROTATION, {hand: [round(float(x), 6) for x in centre]})


__all__ = ["GRIPS", "grasp_centre_in_wrist_m", "wrist_frame_of"]
