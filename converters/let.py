"""LET (Leju Kuavo + BrainCo hands) reader: per-episode JSON dump of the hand ROS topics, 0-100 per joint.

Raw LET data are ROS bags, which need ROS to read; this reader takes the topics' fields exported to one
JSON per episode (the form `conversion.samples` writes, see converters/README.md):
`topics["/control_robot_hand_position"]` = {stamp_s, left_hand_position [T,6], right_hand_position [T,6]}
(commands -> action) and optional `topics["/dexhand/state"]` = {stamp_s, position [T,12] left then right}
(-> state, sampled at the command stamps with zero-order hold). Without the state topic the commands
are also the state.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.converters._topic_json import array_field, field, fps_from_stamps, load_json

COMMAND_TOPIC = "/control_robot_hand_position"
STATE_TOPIC = "/dexhand/state"
BRAINCO_HAND = "brainco_revo1"
NUM_JOINTS = 6


class LETFormatError(ValueError):
    """A LET episode file is missing, truncated or lacks a field; the message names both."""


@register_source("let")
class LETSource:
    license = "LET dataset terms (LejuRobotics/let_dataset); check before redistribution"
    description = "LET / Le-Tong: Kuavo humanoid with two BrainCo 6-DoF hands, 0-100 per joint (robot)"

    def __init__(self, hand: str = BRAINCO_HAND, fps: float | None = None, use_state_topic: bool = True) -> None:
        self.hand = hand
        self.fps = fps  # None: from the command stamps
        self.use_state_topic = use_state_topic

    def list_episodes(self, input_path: str | Path) -> list[str]:
        root = Path(input_path)
        if root.is_file():
            return [str(root)]
        if not root.is_dir():
            raise FileNotFoundError(f"LET input {root} does not exist")
        files = sorted(str(p) for p in root.rglob("*.json") if p.name != "gestures.json")
        if not files:
            raise LETFormatError(f"{root}: no per-episode *.json topic dumps found (see converters/README.md)")
        return files

    def read_episode(self, ref: str) -> RawEpisode:
        path = Path(ref)
        data = load_json(path, LETFormatError)
        topics = field(data, "topics", path, LETFormatError)
        cmd = field(topics, COMMAND_TOPIC, path, LETFormatError, "topics")
        stamps = array_field(LETFormatError, cmd, "stamp_s", path, f"topics[{COMMAND_TOPIC!r}]", ndim=1)
        action = {
            side: array_field(
                LETFormatError,
                cmd,
                f"{side}_hand_position",
                path,
                f"topics[{COMMAND_TOPIC!r}]",
                ndim=2,
                width=NUM_JOINTS,
            )
            for side in ("left", "right")
        }
        for side, values in action.items():
            if len(values) != len(stamps):
                raise LETFormatError(f"{path}: {side}_hand_position has {len(values)} rows for {len(stamps)} stamps")
        state = dict(action)
        if self.use_state_topic and STATE_TOPIC in topics:
            where = f"topics[{STATE_TOPIC!r}]"
            st = topics[STATE_TOPIC]
            st_stamps = array_field(LETFormatError, st, "stamp_s", path, where, ndim=1)
            position = array_field(LETFormatError, st, "position", path, where, ndim=2, width=2 * NUM_JOINTS)
            if len(position) != len(st_stamps):
                raise LETFormatError(f"{path}: {where} position has {len(position)} rows for {len(st_stamps)} stamps")
            rows = np.clip(np.searchsorted(st_stamps, stamps, side="right") - 1, 0, len(st_stamps) - 1)
            state = {"left": position[rows, :NUM_JOINTS], "right": position[rows, NUM_JOINTS:]}
        fps = self.fps or fps_from_stamps(stamps, path, LETFormatError)
        hands = [
            HandStream(side=s, hand=self.hand, state_native=state[s], action_native=action[s])
            for s in ("left", "right")
        ]
        task = str(data.get("task", ""))
        marks = data.get("annotation", {}).get("marks", []) if isinstance(data.get("annotation"), dict) else []
        details = [str(m["enSkillDetail"]) for m in marks if isinstance(m, dict) and m.get("enSkillDetail")]
        return RawEpisode(
            source_file=str(path),
            fps=fps,
            hands=hands,
            task="; ".join(details) if details else task.split("-")[0].replace("_", " "),
            extra={"let_task": task, "synthetic": bool(data.get("synthetic", False))},
        )
