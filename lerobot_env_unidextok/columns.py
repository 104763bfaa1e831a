"""The simulator's vectors by name, without MuJoCo: what LeRobot's config needs to size features and register ids.

observation.state (`agent_pos`) = WRIST_NAMES + TASK_COLUMNS[task] [+ FINGERTIP_COLUMNS] + the hand's native
joints, each named `right_<native joint>` (`right_little`, `right_FFJ4`, `right_joint_0.0`); action = WRIST_NAMES +
the same hand columns. The fingertip columns (the env's `fingertips=True`) are each fingertip's position relative
to the hand's grasp centre, in the world's axes (m): forward kinematics of the state, the same space for every
hand (a closed hand's tips near 0); a finger the hand lacks takes its nearest finger's tip (`tip_sources`). The
task columns are the same for every hand, so datasets of different hands mix by name (`unidextok-mix --keep=all`);
the hand's columns are found by their prefix (`unidextok-convert --source=lerobot --source_options='{"hands":
{"right": "<hand>:right_"}}'`).
"""

from __future__ import annotations

FPS = 10  # env steps per second
EPISODE_STEPS = 50  # default episode length (steps)
# the wrist pose as the observation and the action give it: position (m), then roll, pitch, yaw (rad)
WRIST_NAMES = ("wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw")
PRESS_FINGERS = ("index", "middle", "ring", "little")
TASK_COLUMNS: dict[str, tuple[str, ...]] = {
    "GraspLift-v0": ("object_x", "object_y", "object_z", "object_yaw", "object_half_x", "object_half_y",
                     "object_half_z", "goal_z"),
    "FingerPress-v0": ("panel_x", "panel_y", "panel_z", *(f"goal_{f}" for f in PRESS_FINGERS)),
    # the finger whose button is due now, the next one's and the one's after it (each one-hot; all 0: none), and
    # how many of the three are done
    "FingerSequence-v0": ("panel_x", "panel_y", "panel_z", *(f"{k}_{f}" for k in ("due", "next", "then")
                                                             for f in PRESS_FINGERS), "presses_done"),
    # the cylinder (centre, radius, half height), the target's centre, and the finger that pinches with the thumb
    "PinchPlace-v0": ("object_x", "object_y", "object_z", "object_radius", "object_half_height", "target_x",
                      "target_y", "pinch_index", "pinch_middle"),
    # the two fingers whose buttons go down together (two-hot)
    "ChordPress-v0": ("panel_x", "panel_y", "panel_z", *(f"chord_{f}" for f in PRESS_FINGERS)),
    # the cylinder (centre, radius, half height) and the finger that pinches with the thumb
    "PinchLift-v0": ("object_x", "object_y", "object_z", "object_radius", "object_half_height", "pinch_index",
                     "pinch_middle"),
}  # fmt: skip
TASK_TEXT = {
    "GraspLift-v0": "grasp the object and lift it",
    "FingerPress-v0": "press the button under the named finger",
    "FingerSequence-v0": "press the three buttons in the given order, each with its own finger",
    "PinchPlace-v0": "pinch the cylinder with the thumb and the named finger and stand it in the target",
    "ChordPress-v0": "press the buttons under the two named fingers together, each with its own finger",
    "PinchLift-v0": "pinch the cylinder with the thumb and the named finger and lift it",
}
TASKS = tuple(TASK_COLUMNS)
FINGERS = ("thumb", "index", "middle", "ring", "little")  # every finger a simulated hand may have, in order
FINGERTIP_COLUMNS = tuple(f"tip_{f}_{axis}" for f in FINGERS for axis in "xyz")  # (15,) m, module docstring
# what `observation.state_is_native` carries: 1.0, the state is the hand's native layout (processor/native.py)
STATE_IS_NATIVE_KEY = "state_is_native"


HAND_PREFIX = "right_"  # every simulated hand is a right hand


def hand_columns(native_names: tuple[str, ...] | list[str]) -> list[str]:
    return [f"{HAND_PREFIX}{n}" for n in native_names]


def tip_sources(fingers: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The finger whose tip fills each of `FINGERS`' columns on a hand with `fingers`: its own, or for a finger the
    hand lacks its nearest neighbour toward the index, else toward the little finger (a four-finger hand's little
    columns hold its ring's tip), so the columns never hold a value no hand has (a 0 would put a tip at the grasp
    centre)."""
    if not set(fingers) & set(FINGERS[1:]):
        raise ValueError(f"a hand needs a finger besides the thumb for its fingertip columns, got {list(fingers)}")
    # per finger: itself, its neighbours toward the index, then toward the little finger
    nearest = ([f, *(FINGERS[i - 1 : 0 : -1] if i else ()), *FINGERS[i + 1 :]] for i, f in enumerate(FINGERS))
    return tuple(next(f for f in order if f in fingers) for order in nearest)


def state_names(task: str, native_names: tuple[str, ...] | list[str], fingertips: bool = False) -> list[str]:
    return [*WRIST_NAMES, *TASK_COLUMNS[task], *(FINGERTIP_COLUMNS if fingertips else ()), *hand_columns(native_names)]


def action_names(native_names: tuple[str, ...] | list[str]) -> list[str]:
    return [*WRIST_NAMES, *hand_columns(native_names)]
