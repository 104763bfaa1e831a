"""LinkerHand reader: ROS 2 bags (sqlite3 or MCAP) of the LinkerHand ROS 2 SDK topics, or a LeRobot export.

Follows linker-bot/linkerhand-ros2-sdk `doc/Topic-Reference.md` and
`linker_hand_ros2_sdk/linker_hand_ros2_sdk/linker_hand.py` (the node that publishes them):

- `/cb_<side>_hand_state` (`sensor_msgs/JointState`, `position` 0-255 per joint, 255 = open) -> state;
- `/cb_<side>_hand_control_cmd` (`sensor_msgs/JointState`, 0-255; the SDK limits it to 30 Hz) -> action;
- `/cb_<side>_hand_state_arc` / `_control_cmd_arc` carry the same in radians and are not needed;
- `/cb_<side>_hand_info` (`std_msgs/String`, JSON with `hand_joint`: "L6", "L10", "L20", ...) names the
  model; without it the model comes from `model=` or from the number of joints (6 -> L6, 10 -> L10,
  20 -> L20; L7/L21/L25 have no hand spec here).
- Stamps are bag log times; both hands are resampled onto one `fps` grid (default 30): nearest command,
  linear (or nearest) state (`_rosbag`).

A LeRobot-style export (folder with meta/info.json, v2.1 or v3.0) is read like the `lerobot` source: pass
`model=` (joint names `<side>_hand_<k>`, `<side>_hand_joint_<k>`, `<side>_hand.joint_<k>.pos`,
`<side>_hand_joint_<k>.pos`, ...: k from 0 or 1, separators `_`, `.` or space, optional `.pos` suffix) or
`hands=`. `state_key` / `action_key` name the vectors as in the `lerobot` source (defaults
`observation.state` / `action`; e.g. `state` / `actions`).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.converters import _lerobot_files as lr
from lerobot_unidextok.converters import _rosbag as rb
from lerobot_unidextok.converters.lerobot import HandColumns, check_keep, column_plan, parse_hands, read_mapped_episode
from lerobot_unidextok.errors import SourceFormatError

MODELS: dict[str, tuple[str, int]] = {  # SDK model (hand_joint) -> (hand spec name, joints per hand)
    "L6": ("linkerhand_l6", 6),
    "O6": ("linkerhand_l6", 6),  # same channel layout as the L6 (SDK README)
    "L10": ("linkerhand_l10", 10),
    "L20": ("linkerhand_l20", 20),
}
BY_WIDTH = {6: "L6", 10: "L10", 20: "L20"}
SIDES = ("left", "right")
_EXPORT_NAME = re.compile(r"^(left|right)[_. ]?hand[_. ]?(?:joint[_. ]?)?(\d+)(?:[_.]pos(?:ition)?)?$", re.IGNORECASE)


class LinkerHandFormatError(SourceFormatError):
    """A LinkerHand bag or export lacks a topic/field or has the wrong shape; the message names both."""


def state_topic(side: str) -> str:
    return f"/cb_{side}_hand_state"


def command_topic(side: str) -> str:
    return f"/cb_{side}_hand_control_cmd"


def info_topic(side: str) -> str:
    return f"/cb_{side}_hand_info"


def _model(model: str, where: object) -> tuple[str, int]:
    key = str(model).upper()
    if key not in MODELS:
        raise LinkerHandFormatError(
            f"{where}: LinkerHand model {model!r} has no hand spec here; known models: {sorted(MODELS)}"
        )
    return MODELS[key]


def _hand_joint(msg) -> tuple[np.ndarray, tuple[str, ...]]:
    """`/cb_<side>_hand_info` JSON: no values, the model name (`hand_joint`) as the stream's name."""
    return np.zeros(0), (str(json.loads(msg.data).get("hand_joint", "")),)


@register_source("linkerhand")
class LinkerHandSource:
    license = "CC BY 4.0 (Linkerbot LinkerHand-Open-World dataset); Apache-2.0 SDK topic layout"
    description = "LinkerHand ROS 2 SDK bags (or LeRobot exports): LinkerHand L6/L10/L20, 0-255 per joint (robot)"

    def __init__(
        self,
        model: str | None = None,
        hands: dict | str | None = None,
        fps: int = 30,
        interpolation: str = "linear",
        state_key: str = "observation.state",
        action_key: str | None = "action",
        keep: str = "all",
    ) -> None:
        if model is not None:
            _model(model, "linkerhand option model")
        self.model = model
        self.hands = parse_hands(hands) if hands is not None else None
        self.state_key, self.action_key = state_key, action_key  # LeRobot exports: the vectors' feature keys
        self.keep = check_keep(keep)  # set by --keep: "hands" reads no image/video feature of an export
        self.fps, self.interpolation = rb.resampling_options(fps, interpolation)

    def list_episodes(self, input_path: str | Path) -> list:
        root = Path(input_path)
        if not root.exists():
            raise FileNotFoundError(f"LinkerHand input {root} does not exist")
        if root.is_dir() and ((root / INFO_PATH).is_file() or list(root.glob(f"*/{INFO_PATH}"))):
            if self.model is None and self.hands is None:
                raise LinkerHandFormatError(
                    f"{root}: a LeRobot-style LinkerHand export needs model= (L6/L10/L20) or hands= to map its columns"
                )
            refs = [ref for r in lr.find_dataset_roots(root) for ref in lr.list_episodes(r)]
            for export in sorted({r.root for r in refs}):  # setup check: the columns map, before any episode
                ref = next(r for r in refs if r.root == export)
                column_plan(lr.load_info(export), export, self._export_hands(ref), self.state_key, self.action_key)
            return refs
        rb.require_rosbags()
        bags = rb.list_bags(root)
        if not bags:
            raise LinkerHandFormatError(
                f"{root}: no ROS 2 bags (metadata.yaml folders, *.mcap, *.db3) and no meta/info.json"
            )
        return [str(b) for b in bags]

    def robot_type(self, refs: list) -> str | None:
        """A LeRobot export's `robot_type`; bags record none."""
        return lr.robot_type_of(refs)

    def read_episode(self, ref) -> RawEpisode:
        if isinstance(ref, lr.LeRobotEpisodeRef):
            return read_mapped_episode(ref, self._export_hands(ref), self.state_key, self.action_key, self.keep)
        return self._read_bag(Path(ref))

    # ----------------------------------------------------------------------------------------- #
    def _export_hands(self, ref: lr.LeRobotEpisodeRef) -> list[HandColumns]:
        if self.hands is not None:
            return self.hands
        spec, num = _model(self.model, ref.root)
        info = lr.load_info(ref.root)
        names = lr.feature_names(info, self.state_key, ref.root)
        found: dict[str, dict[int, str]] = {}
        for name in names:
            m = _EXPORT_NAME.match(name)
            if m:
                found.setdefault(m.group(1).lower(), {})[int(m.group(2))] = name
        if not found:
            raise LinkerHandFormatError(
                f"{Path(ref.root) / 'meta' / 'info.json'}: no '<side>_hand_<k>' names in {self.state_key}; "
                f"pass hands= to map the columns (names present: {names})"
            )
        out = []
        for side, by_k in sorted(found.items()):
            ks = sorted(by_k)
            if len(ks) != num or ks not in (list(range(num)), list(range(1, num + 1))):
                info_path = Path(ref.root) / INFO_PATH
                raise LinkerHandFormatError(
                    f"{info_path}: {side} hand has joints {ks}, expected {num} for {self.model}"
                )
            out.append(HandColumns(side, spec, state_names=tuple(by_k[k] for k in ks)))
        return out

    def _read_bag(self, path: Path) -> RawEpisode:
        extractors = {}
        for side in SIDES:
            extractors |= {
                state_topic(side): rb.joint_state,
                command_topic(side): rb.joint_state,
                info_topic(side): _hand_joint,
            }
        streams = rb.read_streams(path, extractors)
        sides = [s for s in SIDES if state_topic(s) in streams]
        if not sides:
            raise LinkerHandFormatError(f"{path}: missing topic {state_topic('left')!r} or {state_topic('right')!r}")
        commands = [command_topic(s) in streams for s in sides]
        if any(commands) and not all(commands):
            missing = [command_topic(s) for s, c in zip(sides, commands, strict=True) if not c]
            raise LinkerHandFormatError(f"{path}: missing topic {missing[0]!r} (the other hand has commands)")
        used = [streams[state_topic(s)] for s in sides] + [streams[command_topic(s)] for s in sides if all(commands)]
        grid = rb.grid_for(used, self.fps, path)
        hands, models = [], {}
        for side in sides:
            state = rb.resample(streams[state_topic(side)], grid, self.interpolation)
            model = self._bag_model(streams, side, state.shape[1], path)
            spec, num = _model(model, path)
            if state.shape[1] != num:
                raise LinkerHandFormatError(
                    f"{path}: {state_topic(side)} position has {state.shape[1]} joints, expected {num} for {model}"
                )
            action = None
            if all(commands):
                action = rb.resample(streams[command_topic(side)], grid, "nearest")
                if action.shape[1] != num:
                    raise LinkerHandFormatError(
                        f"{path}: {command_topic(side)} position has {action.shape[1]} joints, expected {num}"
                    )
            columns = tuple(f"{side}_{model.lower()}_{k}" for k in range(num))
            hands.append(
                HandStream(
                    side,
                    spec,
                    state,
                    action,
                    state_columns=columns,
                    action_columns=columns if action is not None else None,
                )
            )
            models[side] = model
        rates = {t: round(rb.measured_rate_hz(s), 3) for t, s in streams.items() if not t.endswith("_info")}
        return RawEpisode(
            source_file=str(path),
            fps=float(self.fps),
            hands=hands,
            task=path.parent.name.replace("_", " ") if path.parent != path else "",
            extra={"hand_model": ",".join(models[s] for s in sides)},
            source_episode={"measured_hz": rates, "resampled_fps": self.fps},
        )

    def _bag_model(self, streams: dict, side: str, width: int, path: Path) -> str:
        if info_topic(side) in streams and streams[info_topic(side)].names:
            model = streams[info_topic(side)].names[0].strip()
            if model:
                return model
        if self.model is not None:
            return self.model
        if width in BY_WIDTH:
            return BY_WIDTH[width]
        raise LinkerHandFormatError(
            f"{path}: {state_topic(side)} has {width} joints and no {info_topic(side)}; pass model= (L6/L10/L20)"
        )
