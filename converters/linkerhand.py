"""LinkerHand-Open-World reader: 0-255 per joint (255 = open), L6/L10/L20 hands. Schema UNCONFIRMED.

Two accepted forms (strict; errors name the file and the missing field):
1. Per-episode JSON dump of the LinkerHand ROS topics (the form `conversion.samples` writes):
   `hand_model` ("L10", "L20", ...), `topics["/cb_<side>_hand_state"]` = {stamp_s, position [T, J]}
   (-> state) and optional `topics["/cb_<side>_hand_control_cmd"]` (-> action, zero-order hold onto the
   state stamps). Sides present in the file are read.
2. A LeRobot-style export (folder with meta/info.json, v2.1 or v3.0): pass `model=` and either `hands=`
   (as for the `lerobot` source) or rely on names `<side>_hand_<k>` / `<side>_hand_joint_<k>` (k = 0..J-1
   or 1..J), ordered by k.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.converters import _lerobot_files as lr
from lerobot_unidextok.converters._topic_json import array_field, field, fps_from_stamps, load_json
from lerobot_unidextok.converters.lerobot import HandColumns, parse_hands, read_mapped_episode

MODELS: dict[str, tuple[str, int]] = {  # SDK model -> (hand spec name, joints per hand)
    "L6": ("linkerhand_l6", 6),
    "L10": ("linkerhand_l10", 10),
    "L20": ("linkerhand_l20", 20),
}
_EXPORT_NAME = re.compile(r"^(left|right)[_ ]?hand[_ ]?(?:joint[_ ]?)?(\d+)$", re.IGNORECASE)


class LinkerHandFormatError(ValueError):
    """A LinkerHand file lacks a field or has the wrong shape; the message names both."""


def _model(model: str, path: object) -> tuple[str, int]:
    key = str(model).upper()
    if key not in MODELS:
        raise LinkerHandFormatError(f"{path}: unknown LinkerHand model {model!r}; known: {sorted(MODELS)}")
    return MODELS[key]


@register_source("linkerhand")
class LinkerHandSource:
    license = "CC BY 4.0 (Linkerbot LinkerHand-Open-World dataset)"
    description = "LinkerHand-Open-World: LinkerHand L6/L10/L20, 0-255 per joint (robot)"

    def __init__(self, model: str | None = None, hands: dict | str | None = None, fps: float | None = None) -> None:
        self.model = model  # required for LeRobot-style exports; JSON dumps carry hand_model
        self.hands = parse_hands(hands) if hands is not None else None
        self.fps = fps

    def list_episodes(self, input_path: str | Path) -> list:
        root = Path(input_path)
        if not root.exists():
            raise FileNotFoundError(f"LinkerHand input {root} does not exist")
        if root.is_dir() and ((root / "meta" / "info.json").is_file() or list(root.glob("*/meta/info.json"))):
            if self.model is None and self.hands is None:
                raise LinkerHandFormatError(
                    f"{root}: a LeRobot-style LinkerHand export needs model= (L6/L10/L20) or hands= to map its columns"
                )
            return [ref for r in lr.find_dataset_roots(root) for ref in lr.list_episodes(r)]
        if root.is_file():
            return [str(root)]
        files = sorted(str(p) for p in root.rglob("*.json") if p.name != "gestures.json")
        if not files:
            raise LinkerHandFormatError(f"{root}: no per-episode *.json topic dumps and no meta/info.json found")
        return files

    def read_episode(self, ref) -> RawEpisode:
        if isinstance(ref, lr.LeRobotEpisodeRef):
            return read_mapped_episode(ref, self._export_hands(ref), "observation.state", "action")
        return self._read_json(Path(ref))

    # ----------------------------------------------------------------------------------------- #
    def _export_hands(self, ref: lr.LeRobotEpisodeRef) -> list[HandColumns]:
        if self.hands is not None:
            return self.hands
        spec, num = _model(self.model, ref.root)
        info = lr.load_info(ref.root)
        names = lr.feature_names(info, "observation.state", ref.root)
        found: dict[str, dict[int, str]] = {}
        for name in names:
            m = _EXPORT_NAME.match(name)
            if m:
                found.setdefault(m.group(1).lower(), {})[int(m.group(2))] = name
        if not found:
            raise LinkerHandFormatError(
                f"{Path(ref.root) / 'meta' / 'info.json'}: no '<side>_hand_<k>' names in observation.state; "
                f"pass hands= to map the columns (names present: {names})"
            )
        out = []
        for side, by_k in sorted(found.items()):
            ks = sorted(by_k)
            if len(ks) != num or ks not in (list(range(num)), list(range(1, num + 1))):
                info_path = Path(ref.root) / "meta" / "info.json"
                raise LinkerHandFormatError(
                    f"{info_path}: {side} hand has joints {ks}, expected {num} for {self.model}"
                )
            out.append(HandColumns(side, spec, state_names=tuple(by_k[k] for k in ks)))
        return out

    def _read_json(self, path: Path) -> RawEpisode:
        err = LinkerHandFormatError
        data = load_json(path, err)
        spec, num = _model(field(data, "hand_model", path, err), path)
        topics = field(data, "topics", path, err)
        hands = []
        stamps_ref = None
        for side in ("left", "right"):
            state_topic = f"/cb_{side}_hand_state"
            if state_topic not in topics:
                continue
            where = f"topics[{state_topic!r}]"
            stamps = array_field(err, topics[state_topic], "stamp_s", path, where, ndim=1)
            state = array_field(err, topics[state_topic], "position", path, where, ndim=2, width=num)
            if len(state) != len(stamps):
                raise err(f"{path}: {where}.position has {len(state)} rows for {len(stamps)} stamps")
            if stamps_ref is None:
                stamps_ref = stamps
            elif len(stamps) != len(stamps_ref):
                raise err(f"{path}: {where} has {len(stamps)} frames, the other hand {len(stamps_ref)}")
            action = None
            cmd_topic = f"/cb_{side}_hand_control_cmd"
            if cmd_topic in topics:
                cw = f"topics[{cmd_topic!r}]"
                c_stamps = array_field(err, topics[cmd_topic], "stamp_s", path, cw, ndim=1)
                cmd = array_field(err, topics[cmd_topic], "position", path, cw, ndim=2, width=num)
                if len(cmd) != len(c_stamps):
                    raise err(f"{path}: {cw}.position has {len(cmd)} rows for {len(c_stamps)} stamps")
                rows = np.clip(np.searchsorted(c_stamps, stamps, side="right") - 1, 0, len(c_stamps) - 1)
                action = cmd[rows]
            hands.append(HandStream(side=side, hand=spec, state_native=state, action_native=action))
        if not hands:
            raise err(f"{path}: missing field topics['/cb_left_hand_state'] or topics['/cb_right_hand_state']")
        fps = self.fps or fps_from_stamps(stamps_ref, path, err)
        return RawEpisode(
            source_file=str(path),
            fps=fps,
            hands=hands,
            task=str(data.get("task", "")),
            extra={"hand_model": str(data["hand_model"]), "synthetic": bool(data.get("synthetic", False))},
        )
