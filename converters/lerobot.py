"""Generic LeRobot reader: any LeRobot dataset (v2.1 or v3.0) whose hand columns the user names.

`hands` maps each side to a hand spec and its columns in `observation.state` (and `action`):

    {"left":  {"hand": "inspire_rh56_unitree", "state_names": ["kLeftHandPinky", ...]},
     "right": {"hand": "inspire_rh56_unitree", "prefix": "kRightHand"}}
    {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}   # shorthand

`prefix` selects the names starting with it, in dataset order. `action_names` default to the state
names when the action feature has them all (else no action). Names are normalised from flat, nested
`[[...]]` and dict forms. Both versions are read straight from parquet (lerobot 0.6 refuses v2.1).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from lerobot_unidextok.converters import _lerobot_files as lr

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source


@dataclass(frozen=True)
class HandColumns:
    """One hand of a LeRobot dataset: side, hand spec name and how to find its columns."""

    side: str
    hand: str
    state_names: tuple[str, ...] | None = None
    action_names: tuple[str, ...] | None = None
    prefix: str | None = None

    def resolve(self, names: list[str], where: str, explicit: tuple[str, ...] | None) -> list[str]:
        """The column names of this hand among `names` (a feature's flat names)."""
        if explicit is not None:
            lr.select_columns(names, list(explicit), where)  # raises naming the unknown ones
            return list(explicit)
        picked = [n for n in names if n.startswith(self.prefix or "")]
        if not picked:
            raise lr.LeRobotFormatError(
                f"{where}: no names start with prefix {self.prefix!r}; available names: {names}"
            )
        return picked


def parse_hands(hands: dict | str) -> list[HandColumns]:
    """Parse the `hands` option (dict or its JSON text) into one `HandColumns` per side."""
    if isinstance(hands, str):
        try:
            hands = json.loads(hands)
        except json.JSONDecodeError as exc:
            raise ValueError(f"--hands is not valid JSON ({exc}): {hands!r}") from exc
    if not isinstance(hands, dict) or not hands:
        raise ValueError(
            "hands must map 'left'/'right' to a hand spec and its columns, e.g. "
            '{"right": {"hand": "inspire_rh56_unitree", "prefix": "kRightHand"}} '
            'or {"right": "inspire_rh56_unitree:kRightHand"}'
        )
    out = []
    for side, entry in hands.items():
        if side not in ("left", "right"):
            raise ValueError(f"hands key {side!r} must be 'left' or 'right'")
        if isinstance(entry, str):
            hand, sep, prefix = entry.partition(":")
            if not sep or not hand or not prefix:
                raise ValueError(f"hands[{side!r}] shorthand must be '<hand spec>:<name prefix>', got {entry!r}")
            out.append(HandColumns(side, hand, prefix=prefix))
            continue
        if not isinstance(entry, dict) or "hand" not in entry:
            raise ValueError(f"hands[{side!r}] must be a dict with 'hand' and 'state_names' or 'prefix', got {entry!r}")
        unknown = set(entry) - {"hand", "state_names", "action_names", "prefix"}
        if unknown:
            raise ValueError(
                f"hands[{side!r}] has unknown keys {sorted(unknown)}; use hand, state_names, action_names, prefix"
            )
        if ("state_names" in entry) == ("prefix" in entry):
            raise ValueError(f"hands[{side!r}] needs exactly one of 'state_names' or 'prefix'")
        state = tuple(entry["state_names"]) if "state_names" in entry else None
        action = tuple(entry["action_names"]) if entry.get("action_names") is not None else None
        out.append(HandColumns(side, str(entry["hand"]), state, action, entry.get("prefix")))
    return out


@register_source("lerobot")
class LeRobotSource:
    license = "as stated by the source dataset (see its README / info.json)"
    description = "any LeRobot dataset (v2.1 or v3.0); hand columns mapped by feature names (robot)"

    def __init__(
        self, hands: dict | str | None = None, state_key: str = "observation.state", action_key: str | None = "action"
    ) -> None:
        if hands is None:
            raise ValueError(
                "the lerobot source needs hands=: which columns belong to which hand, e.g. "
                '--source_options=\'{"hands": {"left": "inspire_rh56_unitree:kLeftHand", '
                '"right": "inspire_rh56_unitree:kRightHand"}}\''
            )
        self.hands = parse_hands(hands)
        self.state_key = state_key
        self.action_key = action_key

    def list_episodes(self, input_path: str | Path) -> list[lr.LeRobotEpisodeRef]:
        refs = []
        for root in lr.find_dataset_roots(input_path):
            refs += lr.list_episodes(root)
        return refs

    def read_episode(self, ref: lr.LeRobotEpisodeRef) -> RawEpisode:
        return read_mapped_episode(ref, self.hands, self.state_key, self.action_key)


def read_mapped_episode(
    ref: lr.LeRobotEpisodeRef, hands: list[HandColumns], state_key: str, action_key: str | None
) -> RawEpisode:
    """One episode with each hand's state (and action) columns picked by name."""
    info = lr.load_info(ref.root)
    info_path = Path(ref.root) / "meta" / "info.json"
    state_names = lr.feature_names(info, state_key, ref.root)
    action_names = (
        lr.feature_names(info, action_key, ref.root) if action_key and action_key in info["features"] else None
    )
    plan = []
    for h in hands:
        s_cols = h.resolve(state_names, f"{info_path} features[{state_key!r}] ({h.side} hand)", h.state_names)
        a_cols = None
        if action_names is not None:
            wanted = h.action_names or tuple(s_cols)
            if h.action_names is not None or all(n in action_names for n in wanted):
                a_cols = h.resolve(action_names, f"{info_path} features[{action_key!r}] ({h.side} hand)", tuple(wanted))
        plan.append((h, s_cols, a_cols))
    keys = [state_key] + ([action_key] if any(a is not None for _, _, a in plan) else [])
    episode = lr.read_episode(ref, keys)
    streams = []
    for h, s_cols, a_cols in plan:
        state = episode.columns[state_key][:, lr.select_columns(state_names, s_cols, str(info_path))]
        action = None
        if a_cols is not None:
            action = episode.columns[action_key][:, lr.select_columns(action_names, a_cols, str(info_path))]
        streams.append(HandStream(side=h.side, hand=h.hand, state_native=state, action_native=action))
    return RawEpisode(
        source_file=episode.source_file,
        fps=episode.fps,
        hands=streams,
        task=episode.task,
        extra={
            "robot_type": info.get("robot_type", ""),
            "episode_index": ref.episode_index,
            "codebase_version": info["codebase_version"],
        },
    )
