"""`ChordPress-v0`: press two named buttons at once, each with its own finger, while the others stay up.

The panel of `FingerPress-v0` (one button under each finger but the thumb, at the hand's press postures), its
place drawn per episode; the goal is a pair of the hand's pressing fingers (index, middle, ring, little), drawn per
episode from every pair, neighbours (index and middle) or not (index and ring, the middle between them staying
up). Columns: the panel's place and the pair as a two-hot (`chord_<finger>`: 1.0 for the two named fingers, 0.0
for the others), the same for every hand. A button counts as down when it is 4 mm down while its finger touches it.

Success: both named buttons down together, each touched by its own finger, with no other button down, for
`HOLD_STEPS` env steps in a row (0.3 s). Failures end the episode: a button not in the chord pressed ("wrong
button"), or a named button pressed while other fingers and not its own touch it ("wrong finger"). A hand with
fewer than three fingers besides the thumb (the Dex3-1's two) has no button that must stay up: refused when the env
is made, in one line.
"""

from __future__ import annotations

import itertools

import numpy as np

from lerobot_env_unidextok.columns import PRESS_FINGERS, TASK_TEXT
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import SimHand
from lerobot_env_unidextok.tasks import FingerPress

CHORD_SIZE = 2  # buttons pressed together, each by its own finger
MIN_FINGERS = CHORD_SIZE + 1  # and at least one button that must stay up
HOLD_STEPS = 3  # env steps (0.1 s each) the chord is held for success


class ChordPress(FingerPress):
    name = "ChordPress-v0"
    description = TASK_TEXT[name]

    def __init__(self, hand: SimHand) -> None:
        super().__init__(hand)
        if len(self.fingers) < MIN_FINGERS:
            raise SimInputError(
                f"hand {hand.name!r} has {len(self.fingers)} fingers besides the thumb ({', '.join(self.fingers)}), "
                f"and {self.name} presses {CHORD_SIZE} buttons together while another finger's stays up: choose a "
                f"hand with an index, middle and ring finger, or FingerPress-v0 for this one"
            )
        self.chords: tuple[tuple[str, ...], ...] = tuple(itertools.combinations(self.fingers, CHORD_SIZE))
        self.chord: tuple[str, ...] = self.chords[0]
        self.held = 0  # env steps the chord has been held so far
        self.most_down = 0  # the most named buttons down together (by their fingers) in this episode
        self.failure = ""

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        super().reset(data, rng)
        self.chord = self.chords[rng.integers(len(self.chords))]
        self.goal = self.chord[0]
        self.held, self.most_down, self.failure = 0, 0, ""

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        return np.array([*self.panel_pos(), *(float(f in self.chord) for f in PRESS_FINGERS)])

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        if self.held >= HOLD_STEPS or self.failure:
            return self.held >= HOLD_STEPS, bool(self.failure)
        pressed = self.pressed(data)
        down = 0
        if any(p for f, p in pressed.items() if f not in self.chord):
            self.failure = "wrong button"
        for f in self.chord:
            if self.failure or not pressed[f]:
                continue
            by = self.scene.fingers_touching(data, self.buttons[f].geom)
            if f in by:
                down += 1
            elif by:
                self.failure = "wrong finger"
        self.most_down = max(self.most_down, down)
        self.held = self.held + 1 if down == CHORD_SIZE and not self.failure else 0
        return self.held >= HOLD_STEPS, bool(self.failure)

    def failure_reason(self, terminated: bool) -> str:
        return self.failure or f"timeout ({self.most_down} of {CHORD_SIZE} down together)"


__all__ = ["CHORD_SIZE", "HOLD_STEPS", "ChordPress"]
