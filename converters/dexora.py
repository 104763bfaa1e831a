"""Dexora reader: LeRobot v2.1 (or v3.0) episodes, two Robotera XHand1 hands (12 joints each, radians).

The 39-D `observation.state` / `action` are sliced by the names in `meta/info.json`, never by position
(the Dexora README and its converter disagree on the block order): hand joints are the names matching
`<side>_hand_joint_<k>[_suffix]`, k = 1..12, ordered by k.
"""

from __future__ import annotations

import re
from pathlib import Path

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.converters import _lerobot_files as lr

XHAND = "xhand1"
XHAND_JOINTS = 12
_HAND_NAME = re.compile(r"^(left|right)_hand_joint_(\d+)(?:_\w+)?$")


class DexoraFormatError(ValueError):
    """A Dexora dataset lacks a feature or hand joint names; the message names the file and field."""


def hand_columns(names: list[str], where: str) -> dict[str, list[str]]:
    """{side: the 12 hand joint names of that side, ordered by joint number}; strict."""
    found: dict[str, dict[int, str]] = {"left": {}, "right": {}}
    for name in names:
        m = _HAND_NAME.match(name)
        if m:
            found[m.group(1)][int(m.group(2))] = name
    out = {}
    for side, by_k in found.items():
        missing = [k for k in range(1, XHAND_JOINTS + 1) if k not in by_k]
        if missing:
            raise DexoraFormatError(
                f"{where}: missing {side} hand joint names {[f'{side}_hand_joint_{k}' for k in missing]} "
                f"(expected {side}_hand_joint_1..{XHAND_JOINTS}, optionally with a suffix); names present: {names}"
            )
        out[side] = [by_k[k] for k in range(1, XHAND_JOINTS + 1)]
    return out


@register_source("dexora")
class DexoraSource:
    license = "Dexora dataset terms (HF Dexora/Dexora_Real-World_Dataset); check before redistribution"
    description = "Dexora real-world bimanual data: AIRBOT arms + two XHand1 hands, 12 joints each in radians (robot)"

    def __init__(
        self, hand: str = XHAND, state_key: str = "observation.state", action_key: str | None = "action"
    ) -> None:
        self.hand = hand
        self.state_key = state_key
        self.action_key = action_key

    def list_episodes(self, input_path: str | Path) -> list[lr.LeRobotEpisodeRef]:
        return lr.list_all_episodes(input_path)

    def read_episode(self, ref: lr.LeRobotEpisodeRef) -> RawEpisode:
        info = lr.load_info(ref.root)
        where = f"{Path(ref.root) / 'meta' / 'info.json'}"
        state_names = lr.feature_names(info, self.state_key, ref.root)
        state_cols = hand_columns(state_names, f"{where} features[{self.state_key!r}]")
        keys = [self.state_key]
        action_cols = None
        if self.action_key and self.action_key in info["features"]:
            action_names = lr.feature_names(info, self.action_key, ref.root)
            action_cols = hand_columns(action_names, f"{where} features[{self.action_key!r}]")
            keys.append(self.action_key)
        episode = lr.read_episode(ref, keys)
        hands = []
        for side in ("left", "right"):
            state = episode.columns[self.state_key][:, lr.select_columns(state_names, state_cols[side], where)]
            action = None
            if action_cols is not None:
                action = episode.columns[self.action_key][:, lr.select_columns(action_names, action_cols[side], where)]
            hands.append(HandStream(side=side, hand=self.hand, state_native=state, action_native=action))
        return RawEpisode(
            source_file=episode.source_file,
            fps=episode.fps,
            hands=hands,
            task=episode.task,
            extra={"robot_type": info.get("robot_type", ""), "episode_index": ref.episode_index},
        )
