"""LET (Leju Kuavo 4 Pro) reader: the published ROS 1 bags, hands 0-100 per joint, arms in radians.

Follows LejuRobotics/kuavo_data_challenge `kuavo_data/common/kuavo_dataset.py` (`KuavoRosbagReader`,
`KuavoMsgProcesser`) and `kuavo_data/CvtRosbag2Lerobot.py`:

- `/control_robot_hand_position` (`kuavo_msgs/robotHandPosition`: `uint8[] left_hand_position,
  right_hand_position`, 6 each, 0 = open, 100 = closed) -> hand action;
- `/dexhand/state` (`sensor_msgs/JointState`, names `l_thumb, l_thumb_aux, l_index, l_middle, l_ring,
  l_pinky, r_...`, same 0-100 scale) -> hand state (without it the commands are the state);
- `/sensors_data_raw` (`kuavo_msgs/sensorsData`) `joint_data.joint_q[12:26]` -> the 14 arm joints (rad),
  `/kuavo_arm_traj` (`sensor_msgs/JointState`, degrees, converted with deg2rad as upstream) -> arm action:
  kept as passthrough columns next to the hands (`zarm_l1_link ... zarm_r7_link`, upstream names).
- Stamps are bag log times (upstream overrides header stamps with them); every topic is resampled onto a
  fixed `fps` grid (default 30, the head camera timeline upstream aligns to): nearest command, linear
  (or nearest) state, see `_rosbag`.
- Episodes live in `<task>-P4-dex_hand/` (BrainCo Revo1 hands), `<task>-P4-Linker_Hand_L6/` (LET-Dex:
  LinkerHand L6 hands) or `<task>-P4-leju_claw/` (grippers, not dexterous: skipped with a note). The
  0-100 Kuavo scale of an L6 is mapped to its SDK scale as `255 * (1 - v / 100)` (0 = open on Kuavo,
  255 = open in the SDK) [unconfirmed: the LET-Dex hand units are not documented].
- Task: `enSkillDetail` of the annotation sidecar `<bag stem>.json` (`marks`), else the task folder name.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, Passthrough, RawEpisode
from lerobot_unidextok.conversion.registry import check_hand, register_source
from lerobot_unidextok.converters import _rosbag as rb
from lerobot_unidextok.errors import SourceFormatError

logger = logging.getLogger(__name__)

COMMAND_TOPIC = "/control_robot_hand_position"
STATE_TOPIC = "/dexhand/state"
ARM_STATE_TOPIC = "/sensors_data_raw"
ARM_COMMAND_TOPIC = "/kuavo_arm_traj"
HAND_JOINTS = ("thumb", "thumb_aux", "index", "middle", "ring", "pinky")
STATE_NAMES = {"left": tuple(f"l_{j}" for j in HAND_JOINTS), "right": tuple(f"r_{j}" for j in HAND_JOINTS)}
ARM_NAMES = tuple(f"zarm_{s}{i}_link" for s in "lr" for i in range(1, 8))  # kuavo_dataset.DEFAULT_ARM_JOINT_NAMES
ARM_SLICE = slice(12, 26)  # joint_q: 12 legs, 14 arms, 2 head
FOLDER_HANDS = {"dex_hand": "brainco_revo1", "linker_hand_l6": "linkerhand_l6"}  # folder marker -> hand spec
CLAW_MARKER = "leju_claw"
KUAVO_FULL_SCALE = 100.0


class LETFormatError(SourceFormatError):
    """A LET bag or sidecar is missing, truncated or lacks a topic; the message names both."""


def folder_hand(path: Path) -> str | None:
    """The hand spec a LET folder name implies ("...-P4-dex_hand" -> brainco_revo1, ...), or None."""
    for part in reversed(path.parts):
        low = part.lower()
        if CLAW_MARKER in low:
            return CLAW_MARKER
        for marker, hand in FOLDER_HANDS.items():
            if low.endswith(marker) or f"-{marker}" in low:
                return hand
    return None


def _command(msg) -> tuple[np.ndarray, None]:
    left, right = np.asarray(msg.left_hand_position), np.asarray(msg.right_hand_position)
    if left.shape != (6,) or right.shape != (6,):
        raise ValueError(f"left/right_hand_position have {left.shape}/{right.shape} values, expected 6 each")
    return np.concatenate([left, right]), None


def _arm_state(msg) -> tuple[np.ndarray, None]:
    q = np.asarray(msg.joint_data.joint_q)
    if q.shape[0] < ARM_SLICE.stop:
        raise ValueError(f"joint_data.joint_q has {q.shape[0]} joints, expected >= {ARM_SLICE.stop}")
    return q[ARM_SLICE], None


def _arm_command(msg) -> tuple[np.ndarray, None]:
    position = np.asarray(msg.position)
    if position.shape[0] != len(ARM_NAMES):
        raise ValueError(f"position has {position.shape[0]} values, expected {len(ARM_NAMES)} arm joints")
    return np.deg2rad(position), None


@register_source("let")
class LETSource:
    license = "CC BY-NC-SA 4.0 (LET dataset, LejuRobotics/let_dataset); check before redistribution"
    description = "LET: Kuavo 4 Pro humanoid ROS 1 bags, BrainCo or LinkerHand L6 hands 0-100 per joint + arms (robot)"

    def __init__(
        self,
        hand: str = "auto",
        fps: int = 30,
        interpolation: str = "linear",
        use_state_topic: bool = True,
        arms: bool = True,
    ) -> None:
        self.hand = hand if hand == "auto" else check_hand(hand, "let option hand")
        self.fps, self.interpolation = rb.resampling_options(fps, interpolation)
        self.use_state_topic, self.arms = use_state_topic, arms

    def _hand_of(self, path: Path) -> str | None:
        return self.hand if self.hand != "auto" else folder_hand(path)

    def list_episodes(self, input_path: str | Path) -> list[str]:
        rb.require_rosbags()
        root = Path(input_path)
        bags = rb.list_bags(root)
        if not bags:
            raise LETFormatError(f"{root}: no ROS bags (*.bag, rosbag2 folders, *.mcap) found")
        claws = [b for b in bags if self._hand_of(b) == CLAW_MARKER]
        unknown = [b for b in bags if self._hand_of(b) is None]
        if unknown:
            raise LETFormatError(
                f"cannot tell the hand of {unknown[0]} (and {len(unknown) - 1} more) from its folder: LET folders "
                "end in -P4-dex_hand (BrainCo) or -P4-Linker_Hand_L6; pass hand=brainco_revo1 or hand=linkerhand_l6"
            )
        if claws:
            logger.warning("let: skipping %d leju_claw bag(s): grippers, not dexterous hands", len(claws))
        return [str(b) for b in bags if b not in claws]

    def read_episode(self, ref: str) -> RawEpisode:
        path = Path(ref)
        hand = self._hand_of(path)
        extractors = {COMMAND_TOPIC: _command, STATE_TOPIC: rb.joint_state}
        if self.arms:
            extractors |= {ARM_STATE_TOPIC: _arm_state, ARM_COMMAND_TOPIC: _arm_command}
        streams = rb.read_streams(path, extractors)
        if COMMAND_TOPIC not in streams:
            raise LETFormatError(f"{path}: missing topic {COMMAND_TOPIC!r} (kuavo_msgs/robotHandPosition)")
        state_stream = streams.get(STATE_TOPIC) if self.use_state_topic else None
        used = [streams[COMMAND_TOPIC]] + [s for s in (state_stream, streams.get(ARM_STATE_TOPIC)) if s is not None]
        grid = rb.grid_for(used, self.fps, path)
        command = rb.resample(streams[COMMAND_TOPIC], grid, "nearest")  # (T, 12)
        state = command if state_stream is None else self._state(state_stream, grid, path)
        scale = (lambda v: 255.0 * (1.0 - v / KUAVO_FULL_SCALE)) if hand == "linkerhand_l6" else (lambda v: v)
        hands = []
        for k, side in enumerate(("left", "right")):
            cols = slice(6 * k, 6 * k + 6)
            hands.append(
                HandStream(
                    side=side,
                    hand=hand,
                    state_native=scale(state[:, cols]),
                    action_native=scale(command[:, cols]),
                    state_columns=STATE_NAMES[side],
                    action_columns=tuple(f"{side}_hand_position[{i}]" for i in range(6)),
                )
            )
        passthrough, native = self._arms(streams, grid, hands)
        rates = {t: round(rb.measured_rate_hz(s), 3) for t, s in streams.items()}
        task, marks = _task(path)
        return RawEpisode(
            source_file=str(path),
            fps=float(self.fps),
            hands=hands,
            task=task,
            extra={"let_task": _task_folder(path), "skill_marks": marks, "hand": hand},
            passthrough=passthrough,
            native_names=native,
            source_episode={"measured_hz": rates, "resampled_fps": self.fps},
        )

    def _state(self, stream: rb.Stream, grid: np.ndarray, path: Path) -> np.ndarray:
        values = rb.resample(stream, grid, self.interpolation)
        if values.shape[1] != 12:
            raise LETFormatError(f"{path}: {STATE_TOPIC} has {values.shape[1]} positions, expected 12 (6 per hand)")
        if stream.names:
            order = [*STATE_NAMES["left"], *STATE_NAMES["right"]]
            missing = [n for n in order if n not in stream.names]
            if missing:
                raise LETFormatError(f"{path}: {STATE_TOPIC} names {stream.names} lack {missing}")
            values = values[:, [stream.names.index(n) for n in order]]
        return values

    def _arms(self, streams: dict, grid: np.ndarray, hands: list[HandStream]):
        if ARM_STATE_TOPIC not in streams:
            return {}, {}
        arm_state = rb.resample(streams[ARM_STATE_TOPIC], grid, self.interpolation)
        passthrough = {"observation.state": Passthrough(ARM_NAMES, arm_state)}
        native = {"observation.state": [*ARM_NAMES, *(c for h in hands for c in h.state_columns)]}
        if ARM_COMMAND_TOPIC in streams:
            passthrough["action"] = Passthrough(ARM_NAMES, rb.resample(streams[ARM_COMMAND_TOPIC], grid, "nearest"))
            native["action"] = [*ARM_NAMES, *(c for h in hands for c in h.action_columns)]
        return passthrough, native


def _task_folder(path: Path) -> str:
    for part in reversed(path.parent.parts):
        if "-P4-" in part or folder_hand(Path(part)):
            return part
    return path.parent.name


def _task(path: Path) -> tuple[str, list[dict]]:
    """Task text from the annotation sidecar `<stem>.json` (`marks[].enSkillDetail`), else the folder name."""
    sidecar = path.with_suffix(".json") if path.is_file() else path / f"{path.name}.json"
    marks: list[dict] = []
    if sidecar.is_file():
        try:
            data = json.loads(sidecar.read_text())
        except json.JSONDecodeError as exc:
            raise LETFormatError(f"{sidecar}: not valid JSON, truncated? ({exc})") from exc
        found = data.get("marks") or (data.get("annotation") or {}).get("marks") or []
        marks = [m for m in found if isinstance(m, dict)]
    details = [str(m["enSkillDetail"]) for m in marks if m.get("enSkillDetail")]
    if details:
        return "; ".join(details), marks
    return _task_folder(path).split("-P4-")[0].replace("_", " "), marks
