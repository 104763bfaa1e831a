"""`FingerSequence-v0`: press three buttons in a given order, each with its own finger.

The panel of `FingerPress-v0` (one button under each finger but the thumb, at the hand's press postures), its
place drawn per episode; the goal is an order of three of the hand's pressing fingers (index, middle, ring,
little), drawn per episode. Columns: the panel's place, the finger whose button is due now (`due_<finger>`, one-hot: 1.0
for the due one, 0.0 for the others) and how many of the three are done (`presses_done`), the same for every hand.
The order is given one step at a time: what a policy needs at each step is the button due now (which finger comes
after it does not change what to do now, and the due column moves on the step the press counts), so it does not
have to decode an order and count along it (the earlier `order_<finger>` columns, 1, 2, 3 or 0, which left trained
policies picking the first finger at chance: docs/lerobot.md, issue 56). A press counts when the button goes down
4 mm while its finger touches it.

Success: the three buttons pressed in the order, each by its finger. The episode fails when a button is pressed
out of turn (one not in the sequence, or a later one before the one due; a done button pressed again does not
count), or when the due button goes down touched by other fingers and not its own. A hand with fewer than three
fingers besides the thumb (the Dex3-1's two) cannot take the task: refused when the env is made, in one line.
"""

from __future__ import annotations

import numpy as np

from lerobot_env_unidextok.columns import PRESS_FINGERS, TASK_TEXT
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import SimHand
from lerobot_env_unidextok.tasks import FingerPress

SEQUENCE_LENGTH = 3  # buttons per episode, each with another finger


class FingerSequence(FingerPress):
    name = "FingerSequence-v0"
    description = TASK_TEXT[name]

    def __init__(self, hand: SimHand) -> None:
        super().__init__(hand)
        if len(self.fingers) < SEQUENCE_LENGTH:
            raise SimInputError(
                f"hand {hand.name!r} has {len(self.fingers)} fingers besides the thumb ({', '.join(self.fingers)}), "
                f"and {self.name} presses {SEQUENCE_LENGTH} buttons with {SEQUENCE_LENGTH} different fingers: "
                f"choose a hand with an index, middle and ring finger, or FingerPress-v0 for this one"
            )
        self.order: tuple[str, ...] = self.fingers[:SEQUENCE_LENGTH]
        self.done = 0
        self.failure = ""

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        super().reset(data, rng)
        self.order = tuple(str(f) for f in rng.permutation(self.fingers)[:SEQUENCE_LENGTH])
        self.goal = self.order[0]
        self.done, self.failure = 0, ""

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        due = self.order[min(self.done, SEQUENCE_LENGTH - 1)]
        return np.array([*self.panel_pos(), *(float(f == due) for f in PRESS_FINGERS), float(self.done)])

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        if self.done == SEQUENCE_LENGTH or self.failure:
            return self.done == SEQUENCE_LENGTH, bool(self.failure)
        pressed = self.pressed(data)
        due = self.order[self.done]
        early = [f for f, p in pressed.items() if p and f not in self.order[: self.done + 1]]
        if early:
            self.failure = "wrong order"
        elif pressed[due]:
            by = self.scene.fingers_touching(data, self.buttons[due].geom)
            if due in by:
                self.done += 1
                self.goal = self.order[min(self.done, SEQUENCE_LENGTH - 1)]
            elif by:
                self.failure = "wrong finger"
        return self.done == SEQUENCE_LENGTH, bool(self.failure)

    def failure_reason(self, terminated: bool) -> str:
        return self.failure or f"timeout ({self.done} of {SEQUENCE_LENGTH} done)"


__all__ = ["SEQUENCE_LENGTH", "FingerSequence"]
