"""Dexora reader: LeRobot v2.1 (or v3.0) datasets of the AIRBOT + two Robotera XHand1 robot, hands in radians.

Dexora's own code writes two naming schemes, and both are read, slicing by the names in
`meta/info.json`, never by position (the Dexora README and its converter disagree on the block order):

- scheme 1, dexoravla/Dexora `dataprocess/airbot_config.py`: features `observation.state` / `action`,
  39-D, `left_hand_joint_1_obs .. left_hand_joint_12_obs` (state) and `left_hand_joint_1 ..` (action),
  blocks left arm, left hand, right arm, right hand, then head and spine;
- scheme 2, `dataprocess/airbot_lerobot.py`: features `states` / `actions`, 36-D,
  `left_hand_joint_0 .. left_hand_joint_11` and `left_hand_action_0 .. 11`, blocks both arms then both hands.

Hand joints are the names `<side>_hand_(joint|action)_<k>[_suffix]` with k = 1..12 or 0..11, ordered by k.
Everything else (arms, head, spine, cameras) is kept as in the `lerobot` source: passthrough columns,
copied features, videos. A dataset's hand columns are resolved once when its episodes are listed.
"""

from __future__ import annotations

import re
from pathlib import Path

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.conversion.episode import RawEpisode
from lerobot_unidextok.conversion.registry import check_hand, register_source
from lerobot_unidextok.converters import _lerobot_files as lr
from lerobot_unidextok.converters.lerobot import HandColumns, check_keep, read_mapped_episode
from lerobot_unidextok.errors import SourceFormatError

XHAND = "xhand1"
XHAND_JOINTS = 12
STATE_KEYS = ("observation.state", "states")  # scheme 1, scheme 2
ACTION_KEYS = ("action", "actions")
_HAND_NAME = re.compile(r"^(left|right)_hand_(?:joint|action)_(\d+)(?:_\w+)?$")


class DexoraFormatError(SourceFormatError):
    """A Dexora dataset lacks a feature or hand joint names; the message names the file and field."""


def hand_columns(names: list[str], where: str) -> dict[str, list[str]]:
    """{side: the 12 hand joint names of that side, ordered by joint number (from 1 or from 0)}; strict."""
    found: dict[str, dict[int, str]] = {"left": {}, "right": {}}
    for name in names:
        m = _HAND_NAME.match(name)
        if m:
            found[m.group(1)][int(m.group(2))] = name
    out = {}
    for side, by_k in found.items():
        for first in (1, 0):
            wanted = list(range(first, first + XHAND_JOINTS))
            if all(k in by_k for k in wanted):
                out[side] = [by_k[k] for k in wanted]
                break
        else:
            missing = [k for k in range(1, XHAND_JOINTS + 1) if k not in by_k]
            raise DexoraFormatError(
                f"{where}: missing {side} hand joint names {[f'{side}_hand_joint_{k}' for k in missing]} "
                f"(expected {side}_hand_joint_1..{XHAND_JOINTS} or _0..{XHAND_JOINTS - 1}, optionally with a "
                f"suffix, or {side}_hand_action_<k>); names present: {names}"
            )
    return out


def _key(info: dict, wanted: str | None, candidates: tuple[str, ...], where: str, required: bool) -> str | None:
    if wanted is not None:
        if wanted not in info["features"] and required:
            raise DexoraFormatError(f"{where}: no feature {wanted!r}; features: {sorted(info['features'])}")
        return wanted if wanted in info["features"] else None
    found = next((k for k in candidates if k in info["features"]), None)
    if found is None and required:
        raise DexoraFormatError(
            f"{where}: none of the features {list(candidates)}; features: {sorted(info['features'])}"
        )
    return found


@register_source("dexora")
class DexoraSource:
    license = "Dexora dataset terms (HF Dexora/Dexora_Real-World_Dataset); check before redistribution"
    description = "Dexora real-world bimanual data: AIRBOT arms + two XHand1 hands, 12 joints each in radians (robot)"

    def __init__(
        self, hand: str = XHAND, state_key: str | None = None, action_key: str | None = None, keep: str = "all"
    ) -> None:
        self.hand = check_hand(hand, "dexora option hand")
        self.state_key = state_key  # None: observation.state (scheme 1) or states (scheme 2)
        self.action_key = action_key  # None: action or actions
        self.keep = check_keep(keep)  # set by --keep: "hands" reads no image/video feature

    def plan(self, root: str | Path) -> tuple[list[HandColumns], str, str | None]:
        """The hands, state key and action key of one dataset folder (raises naming info.json and the field)."""
        info = lr.load_info(root)
        where = str(Path(root) / INFO_PATH)
        state_key = _key(info, self.state_key, STATE_KEYS, where, required=True)
        action_key = _key(info, self.action_key, ACTION_KEYS, where, required=False)
        state_cols = hand_columns(lr.feature_names(info, state_key, root), f"{where} features[{state_key!r}]")
        action_cols = None
        if action_key is not None:
            action_cols = hand_columns(lr.feature_names(info, action_key, root), f"{where} features[{action_key!r}]")
        hands = [
            HandColumns(
                side,
                self.hand,
                state_names=tuple(state_cols[side]),
                action_names=tuple(action_cols[side]) if action_cols else None,
            )
            for side in ("left", "right")
        ]
        return hands, state_key, action_key

    def list_episodes(self, input_path: str | Path) -> list[lr.LeRobotEpisodeRef]:
        refs = lr.list_all_episodes(input_path)
        for root in sorted({r.root for r in refs}):  # setup check: every subset names its hand joints
            self.plan(root)
        return refs

    def robot_type(self, refs: list) -> str | None:
        return lr.robot_type_of(refs)

    def read_episode(self, ref: lr.LeRobotEpisodeRef) -> RawEpisode:
        hands, state_key, action_key = self.plan(ref.root)
        episode = read_mapped_episode(ref, hands, state_key, action_key, self.keep)
        episode.source_episode["subset"] = Path(ref.root).name
        return episode
