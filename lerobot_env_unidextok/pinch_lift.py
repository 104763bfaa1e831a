"""`PinchLift-v0`: pick a small upright cylinder with the thumb and the named finger (index or middle) and hold it
up, pinched by those two alone.

The cylinder, its draw and the refusal are `PinchPlace-v0`'s (`pinch_place.py`: radius 12-15 mm, half height
14-18 mm, each hand's pinch by forward kinematics, no number set per hand); there is no target. Columns (the same
for every hand): the object's centre, radius and half height, and the finger as a one-hot (`pinch_index`,
`pinch_middle`).

Success: the cylinder's centre `GOAL_M` (4 cm) over where it stood while the thumb and the named finger both touch
it and no other finger does. Failures end the episode: another finger than the thumb and the named one touches it
("other finger"), it lies tilted past 30 degrees with no finger on it ("knocked over"), or the hand lets it go more
than 10 mm above the table ("dropped").

What it asks that GraspLift does not: the pinch point between two named fingers (where a precision grasp holds a
small object differs per hand by several centimetres), and which finger, held to the end.
"""

from __future__ import annotations

import numpy as np

from lerobot_env_unidextok.columns import TASK_COLUMNS, TASK_TEXT
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.pinch_place import PINCH_FINGERS, PinchPlace
from lerobot_env_unidextok.scene import Scene


class PinchLift(PinchPlace):
    name = "PinchLift-v0"
    description = TASK_TEXT[name]
    GOAL_M = 0.04  # the cylinder's centre this far over its rest, pinched, for success

    def state_names(self) -> list[str]:
        return list(TASK_COLUMNS[self.name])

    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        self.add_cylinder(spec)

    def bind(self, scene: Scene) -> None:
        self.bind_cylinder(scene)

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        self.place_cylinder(data, self.draw_cylinder(rng), rng)

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        pos = data.qpos[self.qpos : self.qpos + 3]
        return np.array([*pos, self.radius, self.half_height, *(float(f == self.finger) for f in PINCH_FINGERS)])

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        if self.failure:
            return False, True
        z = float(data.qpos[self.qpos + 2])
        by = self.scene.fingers_touching(data, self.geom)
        self.lifted |= z >= self.rest_z + self.LIFTED_M
        self.failure = self.pinch_failure(data, z, by)
        self.touched = bool(by)
        if self.failure:
            return False, True
        return bool(by == {"thumb", self.finger} and z >= self.rest_z + self.GOAL_M), False


__all__ = ["PinchLift"]
