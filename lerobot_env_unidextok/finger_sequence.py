"""`FingerSequence-v0`: press three buttons in a given order, each with its own finger.

The panel of `FingerPress-v0` (one button under each finger but the thumb, at the hand's press postures), its
place drawn per episode; the goal is an order of three of the hand's pressing fingers (index, middle, ring,
little), drawn per episode. Columns: the panel's place, the presses still to do in their order, each place a
one-hot over the four fingers (`due_<finger>`: the button due now; `next_<finger>`: the one after it;
`then_<finger>`: the one after that; all 0 where no press is left), and how many of the three are done
(`presses_done`), the same for every hand. A press counts when the button goes down 4 mm while its finger touches
it.

The order is given from now on, place by place, as a policy acts on it: what to press now is one column, and what
comes after it is in the state too, as a chunked policy needs it (act_udt runs 10 actions per prediction and the
Shadow's expert presses about 5 steps apart: one chunk spans up to two switches). Two earlier encodings left
trained policies at the floor (docs/lerobot.md, issue 56): each finger's place in the order (`order_<finger>`: 1,
2, 3, or 0) with `presses_done`, to be decoded and counted along, and the due finger alone.

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
        ahead = [*self.order[self.done + 1 :], "", ""][:2]  # the next press and the one after it ("": none)
        places = [float(f == g) for g in (due, *ahead) for f in PRESS_FINGERS]
        return np.array([*self.panel_pos(), *places, float(self.done)])

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
