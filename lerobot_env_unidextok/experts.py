"""Scripted experts: a wrist trajectory through key poses and the hand's postures, per hand and task, with noise.

The postures are UDHM slot angles (`SimHand.postures`: the shared `hand_model.POSTURES`, fitted by forward
kinematics for a hand built from its URDF, or a model file's own), turned into that hand's native command by its
spec (`SimHand.posture` -> `spec.from_udhm`); the grasp offsets (where the wrist goes relative to the object) are
`SimHand.grasp` (computed for a built hand, `urdf_hand.grasp_offsets`; a model file's `grasp:` entries). The
expert reads only what the observation holds (the object's pose and size, the panel's place, the goal finger),
plans its key poses once at the episode's start, and moves between them at most 3 cm per step; a sequence's
presses (`FingerSequence-v0`) follow the due finger and `presses_done`, each held until it counted
(`SequencePresses`), and a pinch's lift, carry and set-down (`PinchPlace-v0`) follow the object's place
(`PinchCarry`); a pinch and lift (`PinchLift-v0`) is planned open loop, as the grasp. Noise (its own
generator, seeded per episode): key poses +-4 mm (+-3 mm in height) and +-0.04 rad of yaw (a press turns the hand
about its fingertips over the buttons), postures +-0.05 rad per UDHM slot, phase lengths +-1 step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_env_unidextok.chord_press import ChordPress
from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.finger_sequence import SEQUENCE_LENGTH, FingerSequence
from lerobot_env_unidextok.hand_model import SimHand
from lerobot_env_unidextok.pinch_lift import PinchLift
from lerobot_env_unidextok.pinch_place import PINCH_FINGERS, PinchPlace, pinch_of
from lerobot_env_unidextok.tasks import PRESS_FINGERS, FingerPress, GraspLift

WRIST_SPEED_M = 0.03  # per step
POSE_NOISE = np.array([0.004, 0.004, 0.003, 0.0, 0.0, 0.04])
POSTURE_NOISE_RAD = 0.05


@dataclass
class Segment:
    """Move the wrist to `pose` and the hand to `hand` (linearly from the previous segment) over `steps`."""

    pose: np.ndarray  # (6,) x, y, z, roll, pitch, yaw
    hand: np.ndarray  # (J,) native
    steps: int


class Expert:
    """Scripted policy for one episode of `env` (plan at `reset`, then `act` once per step)."""

    def __init__(self, env: UniDexTokEnv, rng: np.random.Generator, noise: bool = True) -> None:
        self.env, self.rng, self.noise = env, rng, noise
        self.hand = env.hand
        self.plan: list[tuple[np.ndarray, np.ndarray]] = []
        self.segment_ends: list[int] = []  # per segment of the plan, its last step (pictures of each phase)
        self.t = 0
        self.presses: SequencePresses | None = None  # FingerSequence-v0's, set by `sequence_segments`
        self.done_column = env.state_names.index("presses_done") if "presses_done" in env.state_names else -1
        self.due_columns = [env.state_names.index(f"due_{f}") for f in PRESS_FINGERS if f"due_{f}" in env.state_names]
        self.carry: PinchCarry | None = None  # PinchPlace-v0's, set by `pinch_place_segments`
        self.object_columns = [env.state_names.index(c) for c in ("object_x", "object_y", "object_z")
                               if c in env.state_names]  # fmt: skip
        self.last_hand = self.hand.posture("open")

    # -- postures and noise -----------------------------------------------------------------------
    def posture(self, name: str) -> np.ndarray:
        """A named posture in native units, each UDHM slot of it jittered (noise)."""
        return self.jittered(self.hand.posture(name))

    def jittered(self, native: np.ndarray) -> np.ndarray:
        """A native command with each UDHM slot of it jittered (noise)."""
        hand = self.hand
        if not self.noise:
            return native.copy()
        base = np.asarray(hand.spec.to_udhm(native, hand.side), dtype=np.float64)
        mask = hand.spec.active_mask
        base[mask] += self.rng.uniform(-POSTURE_NOISE_RAD, POSTURE_NOISE_RAD, int(mask.sum()))
        raw = np.asarray(hand.spec.from_udhm(base, hand.side), dtype=np.float64)
        dropped = ~np.isin(np.arange(len(raw)), hand.spec.active_joint_indices)
        raw[dropped] = native[dropped]
        return raw

    def jitter(self, pose: np.ndarray) -> np.ndarray:
        return pose + (self.rng.uniform(-1, 1, 6) * POSE_NOISE if self.noise else 0)

    def steps(self, n: int) -> int:
        return max(1, n + (int(self.rng.integers(-1, 2)) if self.noise else 0))

    # -- plan -------------------------------------------------------------------------------------
    def reset(self, obs: dict[str, np.ndarray]) -> None:
        state = obs["agent_pos"].astype(np.float64)
        wrist, task_cols = state[:6], state[6 : 6 + len(self.env.task.state_names())]
        segments = self.segments(dict(zip(self.env.task.state_names(), task_cols, strict=True)), wrist)
        pose, hand = wrist.copy(), self.hand.posture("open")
        self.plan, self.segment_ends = [], []
        for seg in segments:
            n = max(seg.steps, int(np.ceil(np.abs(seg.pose[:3] - pose[:3]).max() / WRIST_SPEED_M)))
            for k in range(1, n + 1):
                a = k / n
                self.plan.append(((1 - a) * pose + a * seg.pose, (1 - a) * hand + a * seg.hand))
            pose, hand = seg.pose, seg.hand
            self.segment_ends.append(len(self.plan))  # the step at which this segment's target is sent
        self.t = 0

    def act(self, obs: dict[str, np.ndarray] | None = None) -> np.ndarray:
        pose, hand = self.plan[min(self.t, len(self.plan) - 1)]
        if self.presses is not None and self.t >= len(self.plan):  # a sequence's presses, on what it observes
            done = int(round(float(obs["agent_pos"][self.done_column])))
            due = PRESS_FINGERS[int(np.argmax(obs["agent_pos"][self.due_columns]))]
            pose, hand = self.presses.act(done, due, self.last_hand)
        if self.carry is not None and self.t >= len(self.plan):  # a pinch's carry and set-down, on what it observes
            state = obs["agent_pos"].astype(np.float64)
            pose, hand = self.carry.act(state[self.object_columns], state[-len(self.hand.native_names) :])
        self.t += 1
        self.last_hand = hand
        return np.concatenate([pose, hand]).astype(np.float32)

    def segments(self, task: dict[str, float], wrist: np.ndarray) -> list[Segment]:
        if isinstance(self.env.task, GraspLift):
            return self.grasp_segments(task)
        if isinstance(self.env.task, ChordPress):  # before FingerPress: its panel is FingerPress's
            return self.chord_segments(task)
        if isinstance(self.env.task, FingerSequence):  # before FingerPress: its panel is FingerPress's
            return self.sequence_segments(task)
        if isinstance(self.env.task, FingerPress):
            return self.press_segments(task)
        if isinstance(self.env.task, PinchLift):  # before PinchPlace: its cylinder is PinchPlace's
            return self.pinch_lift_segments(task)
        if isinstance(self.env.task, PinchPlace):
            return self.pinch_place_segments(task)
        raise TypeError(f"no expert for {type(self.env.task).__name__}")

    def grasp_segments(self, task: dict[str, float]) -> list[Segment]:
        half = np.array([task["object_half_x"], task["object_half_y"], task["object_half_z"]])
        width = 2 * min(half[0], half[1])
        kind = "power" if width >= GRASP_WIDTH_M else "pinch"
        g = self.hand.grasp[kind]
        yaw = task["object_yaw"]
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy, dz = g["offset_m"]
        centre = np.array([task["object_x"], task["object_y"], task["object_z"]])
        if kind == "power" and g.get("from") == "centre":  # the hand closes around the object's centre, the palm
            # no lower than on its top, the closed tips not into the table
            dz = max(dz, half[2] + g["palm_over_top_m"], g["over_table_m"] - task["object_z"])
        elif kind == "power":
            dz = half[2] + dz  # the wrist's height over the object's top
        at = centre + [c * dx - s * dy, s * dx + c * dy, dz]
        grasp_pose = self.jitter(np.array([*at, 0.0, float(g.get("pitch", 0.0)), yaw]))
        above = grasp_pose + [0, 0, 0.06, 0, 0, 0]
        lifted = grasp_pose + [0, 0, 0.12, 0, 0, 0]
        pre, closed = self.posture(g["preshape"]), self.posture(g["posture"])
        # no phase waits in place: a state-only policy cannot tell "wait" from "go on" at a state that does not
        # change, so the lift starts slowly while the fingers are still closing
        return [Segment(above, pre, self.steps(8)), Segment(grasp_pose, pre, self.steps(4)),
                Segment(grasp_pose, closed, self.steps(8)), Segment(grasp_pose + [0, 0, 0.01, 0, 0, 0], closed, 5),
                Segment(lifted, closed, self.steps(5)), Segment(lifted, closed, 10)]  # fmt: skip

    def hover_pose(self, task: dict[str, float]) -> np.ndarray:
        """The wrist over the panel, every button under its finger, with the pose noise."""
        panel = np.array([task["panel_x"], task["panel_y"], task["panel_z"]])
        hover = self.jitter(np.array([*(panel + FingerPress.HOVER_M), 0.0, 0.0, 0.0]))
        # the yaw noise turns the hand about its fingertips over the buttons, not about the wrist: a hand's tips
        # then miss their buttons by the position noise alone, whatever the hand's length
        reach = self.env.task.buttons_x_m - FingerPress.HOVER_M[0]
        hover[:2] += reach * np.array([1 - np.cos(hover[5]), -np.sin(hover[5])])
        return hover

    def press_segments(self, task: dict[str, float]) -> list[Segment]:
        goal = next(f for f in PRESS_FINGERS if task[f"goal_{f}"] > 0.5)
        hover = self.hover_pose(task)
        above = hover + [0, 0, 0.04, 0, 0, 0]
        open_ = self.posture("open")
        press = self.posture(f"press_{goal}")
        return [Segment(above, open_, self.steps(8)), Segment(hover, open_, self.steps(3)),
                Segment(hover, press, self.steps(5)), Segment(hover, press, 15)]  # fmt: skip

    def chord_segments(self, task: dict[str, float]) -> list[Segment]:
        """Over the panel as for one press; both named fingers to their press postures at once (each finger's UDHM
        slots from its own press posture, the others open), held."""
        chord = [f for f in PRESS_FINGERS if task[f"chord_{f}"] > 0.5]
        hover = self.hover_pose(task)
        open_ = self.posture("open")
        slots = {k: v for f in chord for k, v in self.hand.postures[f"press_{f}"].items()}
        press = self.jittered(self.hand.with_slots(slots))
        return [Segment(hover + [0, 0, 0.04, 0, 0, 0], open_, self.steps(8)), Segment(hover, open_, self.steps(3)),
                Segment(hover, press, self.steps(5)), Segment(hover, press, 15)]  # fmt: skip

    def sequence_segments(self, task: dict[str, float]) -> list[Segment]:
        """Over the panel as for one press; the presses follow from the observation (`act`, `SequencePresses`)."""
        hover = self.hover_pose(task)
        open_ = self.posture("open")
        presses = {f: self.posture(f"press_{f}") for f in self.env.task.fingers}
        self.presses = SequencePresses(hover, presses, open_, self.steps(SEQUENCE_PRESS_STEPS))
        return [Segment(hover + [0, 0, 0.04, 0, 0, 0], open_, self.steps(8)), Segment(hover, open_, self.steps(3))]

    def pinch_pose(self, task: dict[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The wrist at the pinch (level, its yaw 0: the point halfway between the fingers where they close to the
        cylinder's width, `pinch_place.Pinch.point_m`, on its centre), the pre-shape and the hold, with noise."""
        finger = next(f for f in PINCH_FINGERS if task[f"pinch_{f}"] > 0.5)
        pinch = pinch_of(self.hand, finger)
        width = 2 * task["object_radius"]
        centre = np.array([task["object_x"], task["object_y"], task["object_z"]])
        grasp = self.jitter(np.array([*(centre - pinch.point_m(width)), 0.0, 0.0, 0.0]))
        return grasp, self.jittered(pinch.pre), self.jittered(pinch.hold(width))

    def pinch_lift_segments(self, task: dict[str, float]) -> list[Segment]:
        """Over the cylinder, down, pinch, lift: open loop, as the grasp's (no phase waits in place, the lift starts
        slowly while the fingers are still closing)."""
        grasp, pre, hold = self.pinch_pose(task)
        up = np.array([0, 0, 1.0, 0, 0, 0])
        return [Segment(grasp + 0.05 * up, pre, self.steps(8)), Segment(grasp, pre, self.steps(4)),
                Segment(grasp, hold, self.steps(PINCH_CLOSE_STEPS)), Segment(grasp + 0.01 * up, hold, 6),
                Segment(grasp + 0.07 * up, hold, self.steps(6)), Segment(grasp + 0.07 * up, hold, 10)]  # fmt: skip

    def pinch_place_segments(self, task: dict[str, float]) -> list[Segment]:
        """Over the cylinder, down, pinch; the rest follows from the observation (`act`, `PinchCarry`). The wrist
        at the pinch (`pinch_pose`)."""
        grasp, pre, hold = self.pinch_pose(task)
        self.carry = PinchCarry(self.hand, np.array([task["target_x"], task["target_y"]]),
                                task["object_half_height"], grasp.copy(), hold, self.posture("open"))  # fmt: skip
        return [Segment(grasp + [0, 0, 0.05, 0, 0, 0], pre, self.steps(8)), Segment(grasp, pre, self.steps(4)),
                Segment(grasp, hold, self.steps(PINCH_CLOSE_STEPS))]  # fmt: skip


@dataclass
class PinchCarry:
    """A pinch-and-place after the fingers were sent to the pinch, closed loop on the observation: the wrist waits
    until the fingers stop moving (each UDHM slot under `SETTLED_RAD` a step, at most `SETTLE_STEPS`: the hand's
    own speed, the Inspire's slow drives), lifts `LIFT_M`, carries the object level toward the target, correcting
    for where it sits in the fingers (at most `CARRY_M` a step, reached over `RAMP_STEPS`); over the target (within
    `OVER_M`) it goes down `LOWER_M` a step until the object stands on the table (within 2 mm), then the hand opens
    to its open pose over `OPEN_STEPS` and the wrist rises. The object not in the fingers after the lift: the hand
    stays where it is (the episode runs out)."""

    hand: SimHand
    target_xy: np.ndarray  # (2,)
    half_height_m: float
    pose: np.ndarray  # (6,) the wrist, at the pinch
    hold: np.ndarray  # (J,) the pinch
    release: np.ndarray  # (J,) the open hand
    phase: str = "settle"
    k: int = 0
    last_udhm: np.ndarray | None = None
    LIFT_M = 0.04
    LIFT_STEPS = 5
    SETTLED_RAD = 0.005
    SETTLE_STEPS = 12  # at most
    CARRY_M = 0.015
    RAMP_STEPS = 3
    OVER_M = 0.003
    LOWER_M = 0.01
    OPEN_STEPS = 4

    def act(self, object_xyz: np.ndarray, native: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.k += 1
        if self.phase == "settle":
            udhm = np.asarray(self.hand.spec.to_udhm(native, self.hand.side), dtype=np.float64)
            still = self.last_udhm is not None and np.abs(udhm - self.last_udhm).max() < self.SETTLED_RAD
            self.last_udhm = udhm
            if not still and self.k < self.SETTLE_STEPS:
                return self.pose.copy(), self.hold
            self.phase, self.k = "lift", 1
        if self.phase == "lift":
            self.pose[2] += self.LIFT_M / self.LIFT_STEPS
            if self.k == self.LIFT_STEPS:
                self.phase, self.k = "carry", 0
            return self.pose.copy(), self.hold
        miss = self.target_xy - object_xyz[:2]
        if self.phase == "carry" and object_xyz[2] - self.half_height_m < 0.01:  # not in the fingers: stay
            return self.pose.copy(), self.hold
        if self.phase in ("carry", "lower"):  # from rest up to CARRY_M a step over RAMP_STEPS: no jerk to drop it
            limit = self.CARRY_M * min(1.0, self.k / self.RAMP_STEPS)
            self.pose[:2] += miss * min(1.0, limit / max(float(np.linalg.norm(miss)), 1e-9))
        if self.phase == "carry" and np.linalg.norm(miss) <= self.OVER_M:
            self.phase = "lower"
        if self.phase == "lower":
            if object_xyz[2] - self.half_height_m <= 0.002:
                self.phase, self.k = "open", 1
            else:
                self.pose[2] -= min(self.LOWER_M, object_xyz[2] - self.half_height_m)
        if self.phase == "open":
            a = min(1.0, self.k / self.OPEN_STEPS)
            if a == 1.0:
                self.phase = "up"
            return self.pose.copy(), (1 - a) * self.hold + a * self.release
        if self.phase == "up":
            self.pose[2] += self.LOWER_M
            return self.pose.copy(), self.release
        return self.pose.copy(), self.hold


@dataclass
class SequencePresses:
    """A sequence's presses, closed loop on the due finger and `presses_done`: the hand moves from where it is to
    the posture of the press due (that finger's press posture, the others open; after the last, open) over `steps`,
    and holds it until the observation says the press counted. A slow hand (the Inspire's drives take about 0.5 s
    per e-fold) then presses as long as it needs and a fast one moves on at once, within the 50 steps."""

    hover: np.ndarray  # (6,) the wrist, held
    postures: dict[str, np.ndarray]  # finger -> (J,) its press posture
    open_: np.ndarray  # (J,) after the last press
    steps: int
    done: int = -1
    start: np.ndarray | None = None
    k: int = 0

    def act(self, done: int, due: str, hand_now: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if done != self.done:
            self.done, self.start, self.k = done, hand_now, 0
        self.k += 1
        a = min(1.0, self.k / self.steps)
        target = self.postures[due] if done < SEQUENCE_LENGTH else self.open_
        return self.hover, (1 - a) * self.start + a * target


PINCH_CLOSE_STEPS = 6  # a pinch-and-place's pre-shape to closed
SEQUENCE_PRESS_STEPS = 5  # a sequence's move from one press posture to the next (or to open after the last)
GRASP_WIDTH_M = 0.04  # objects at least this wide get a power grasp, narrower ones a pinch
