"""Generic LeRobot reader: any LeRobot dataset (v2.1 or v3.0) whose hand columns the user names.

`hands` maps each side to a hand spec and its columns in `observation.state` (and `action`):

    {"left":  {"hand": "inspire_rh56_unitree", "state_names": ["kLeftHandPinky", ...]},
     "right": {"hand": "inspire_rh56_unitree", "prefix": "kRightHand"}}
    {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}   # shorthand
    "unitree_g1_inspire"                                                                      # a known robot

`prefix` selects the names starting with it, in dataset order. `action_names` default to the state names
when the action feature has them all (else no action). A hand stored in a feature of its own takes
`{"hand": ..., "state_key": "observation.state.right_hand", "action_key": "action.right_hand"}` (every
column; names optional). Names are normalised from flat, nested `[[...]]` and dict forms. Both versions
are read straight from parquet (lerobot 0.6 refuses v2.1), following LeRobot's layout code (see
`_lerobot_files`).

The whole robot is kept: every state/action column that belongs to no hand (arms, grippers, base) is a
passthrough column (source name, source order, stored value), every other feature (images, other
observations) is copied unchanged and every video feature is copied as a file segment. A wrist frame the
recorder wrote (`meta/unidextok_wrist_frame.json`: the simulator's wrist columns and the hand's grasp centre) is
carried into the conversion record (`wrist_frame`) when its columns are kept.
Hand names and columns are checked once against each dataset's `meta/info.json` when the episodes are
listed, so a typo fails before any episode is read.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok import hands
from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.conversion.episode import HandStream, Passthrough, RawEpisode
from lerobot_unidextok.conversion.registry import check_hand, register_source
from lerobot_unidextok.converters import _lerobot_files as lr
from lerobot_unidextok.data.wrist_frame import WristFrame, merge_frames, read_recorded

logger = logging.getLogger(__name__)

ALL_COLUMNS = ("*",)  # state_names meaning "every column of the hand's own feature"
# The hands of robots whose LeRobot recordings are common, by name: `hands="unitree_g1_inspire"`.
# Unitree G1 + two Inspire hands (unitreerobotics/xr_teleoperate, teleop/robot_control/robot_hand_inspire.py:
# kLeftHand* / kRightHand* columns, normalised 0-1, 1 = open).
G1_INSPIRE_HANDS = {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}
# Unitree G1 with its own Dex3-1 hands (unitree_lerobot exports): kLeftHandThumb0..kRightHandMiddle1, bound by
# name (the SDK lists the left hand's middle finger before its index, the right hand's after it).
G1_DEX3_HANDS = {"left": "unitree_dex3_1:kLeftHand", "right": "unitree_dex3_1:kRightHand"}
KNOWN_HANDS: dict[str, dict] = {"unitree_g1_inspire": G1_INSPIRE_HANDS, "unitree_g1_dex3": G1_DEX3_HANDS}
OUT_STATE, OUT_ACTION = "observation.state", "action"  # the converted dataset's vectors


@dataclass(frozen=True)
class HandColumns:
    """One hand of a LeRobot dataset: side, hand spec name and how to find its columns."""

    side: str
    hand: str
    state_names: tuple[str, ...] | None = None
    action_names: tuple[str, ...] | None = None
    prefix: str | None = None
    state_key: str | None = None  # this hand's own feature (e.g. "observation.state.right_hand"); None = shared
    action_key: str | None = None

    def resolve(self, names: list[str], where: str, explicit: tuple[str, ...] | None) -> list[str]:
        """The column names of this hand among `names` (a feature's flat names)."""
        if explicit == ALL_COLUMNS:
            return list(names)
        if explicit is not None:
            lr.select_columns(names, list(explicit), where)  # raises naming the unknown ones
            return list(explicit)
        picked = [n for n in names if n.startswith(self.prefix or "")]
        if not picked:
            raise lr.LeRobotFormatError(
                f"{where}: no names start with prefix {self.prefix!r}; available names: {names}"
            )
        return self.bind(picked, where)[0]

    def bind(self, picked: list[str], where: str) -> tuple[list[str], str]:
        """The prefix's columns in the hand's joint order: by name when they name its joints (another order
        in the source is put right), else in the source's order ("position"; said once, when listing)."""
        try:
            return hands.get(self.hand).bind_columns(picked, self.prefix or "")
        except ValueError as exc:
            raise lr.LeRobotFormatError(f"{where}: {exc}") from None


def check_keep(keep: str) -> str:
    """The `keep` option (set by `--keep`): "all" reads every feature and video, "hands" only the vectors."""
    if keep not in ("all", "hands"):
        raise ValueError(f"keep must be 'all' or 'hands', got {keep!r}")
    return keep


def parse_hands(hands: dict | str) -> list[HandColumns]:
    """Parse the `hands` option (dict, its JSON text, or a name of `KNOWN_HANDS`) into one `HandColumns` per side."""
    if isinstance(hands, str) and hands in KNOWN_HANDS:
        hands = KNOWN_HANDS[hands]
    elif isinstance(hands, str):
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
            out.append(HandColumns(side, check_hand(hand, f"hands[{side!r}]"), prefix=prefix))
            continue
        if not isinstance(entry, dict) or "hand" not in entry:
            raise ValueError(f"hands[{side!r}] must be a dict with 'hand' and 'state_names' or 'prefix', got {entry!r}")
        known = {"hand", "state_names", "action_names", "prefix", "state_key", "action_key"}
        unknown = set(entry) - known
        if unknown:
            raise ValueError(f"hands[{side!r}] has unknown keys {sorted(unknown)}; use {sorted(known)}")
        if "state_names" in entry and "prefix" in entry:
            raise ValueError(f"hands[{side!r}] takes 'state_names' or 'prefix', not both")
        if "state_names" not in entry and "prefix" not in entry and "state_key" not in entry:
            raise ValueError(
                f"hands[{side!r}] needs 'state_names' or 'prefix' (columns of a shared feature), or 'state_key' "
                "(a feature holding only this hand)"
            )
        state = tuple(entry["state_names"]) if "state_names" in entry else None
        if state is None and "prefix" not in entry:
            state = ALL_COLUMNS  # the hand's own feature, every column
        action = tuple(entry["action_names"]) if entry.get("action_names") is not None else None
        out.append(
            HandColumns(
                side,
                check_hand(str(entry["hand"]), f"hands[{side!r}]"),
                state,
                action,
                entry.get("prefix"),
                entry.get("state_key"),
                entry.get("action_key"),
            )
        )
    return out


STATE_KEYS = ("observation.state", "state", "states", "observation.states")  # what recordings call the state
ACTION_KEYS = ("action", "actions")
AUTO = "auto"


def vector_keys(info: dict, state_key: str, action_key: str | None) -> tuple[str, str | None, str]:
    """(state feature, action feature or None, a note when not LeRobot's own names): `auto` takes the first of
    `STATE_KEYS` / `ACTION_KEYS` the dataset has (seen: `state` / `actions` for `observation.state` / `action`)."""
    features = info["features"]
    note = ""
    if state_key == AUTO:
        state_key = next((k for k in STATE_KEYS if k in features), STATE_KEYS[0])
        if state_key != STATE_KEYS[0]:
            note = f"its state is the feature {state_key!r} (not 'observation.state')"
    if action_key == AUTO:
        action_key = next((k for k in ACTION_KEYS if k in features), None)
        if action_key not in (None, ACTION_KEYS[0]):
            note += ("; " if note else "") + f"its action is the feature {action_key!r} (not 'action')"
    return state_key, action_key, note


def absent_sides(root: str, plan: list[tuple], state_key: str) -> tuple[str, ...]:
    """Sides whose state columns hold 0 in every frame of the dataset: hands that were never recorded (a
    two-hand layout with one hand's columns left at zero). 0 is a valid value of one joint (LinkerHand: fully
    flexed), never of every joint in every frame of a recording."""
    import pyarrow.parquet as pq

    files = sorted(Path(root).glob("data/**/*.parquet"))
    out = []
    for h, s_key, s_cols, _, _ in plan:
        if s_key != state_key or not files:
            continue
        names = lr.feature_names(lr.load_info(root), s_key, root)
        idx = lr.select_columns(names, s_cols, root)
        zero = True
        for f in files:
            column = pq.read_table(f, columns=[s_key]).column(0).combine_chunks()
            values = column.values.to_numpy(zero_copy_only=False).reshape(len(column), -1)
            if np.any(values[:, idx] != 0):
                zero = False
                break
        if zero:
            out.append(h.side)
    return tuple(out)


@register_source("lerobot")
class LeRobotSource:
    license = "as stated by the source dataset (see its README / info.json)"
    description = "any LeRobot dataset (v2.1 or v3.0); hand columns mapped by feature names (robot)"

    def __init__(
        self,
        hands: dict | str | None = None,
        state_key: str = AUTO,
        action_key: str | None = AUTO,
        keep: str = "all",
    ) -> None:
        if hands is None:
            raise ValueError(
                "the lerobot source needs hands=: which columns belong to which hand, e.g. "
                '--source_options=\'{"hands": {"right": "linkerhand_l10:right_hand_"}}\', or a known robot: '
                f"--source_options='{{\"hands\": \"unitree_g1_inspire\"}}' (known: {sorted(KNOWN_HANDS)})"
            )
        self.hands = parse_hands(hands)
        self.state_key = state_key
        self.action_key = action_key
        self.keep = check_keep(keep)

    def list_episodes(self, input_path: str | Path) -> list[lr.LeRobotEpisodeRef]:
        """Every episode, after checking once per dataset that its hands map, and saying in one line each what
        does not look like LeRobot's own layout (other vector names, a shape that disagrees with its names,
        videos in another folder, hand columns bound by position, hands never recorded)."""
        refs = lr.list_all_episodes(input_path)
        absent: dict[str, tuple[str, ...]] = {}
        for root in sorted({r.root for r in refs}):  # setup check: every dataset maps, before any episode work
            info = lr.load_info(root)
            state_key, action_key, note = vector_keys(info, self.state_key, self.action_key)
            notes = [note] if note else []
            plan, _ = column_plan(info, root, self.hands, state_key, action_key, notes)
            for h, _, s_cols, _, _ in plan:
                if h.prefix is not None and h.bind(s_cols, "")[1] == "position":
                    notes.append(
                        f"the {h.side} hand's columns {s_cols} name none of the {h.hand} joints, so they are taken "
                        f"in the source's order as {list(hands.get(h.hand).joint_names)} (pass state_names in the "
                        "joint order if that is not theirs)"
                    )
            absent[root] = absent_sides(root, plan, state_key)
            if len(absent[root]) == len(plan):
                raise lr.LeRobotFormatError(
                    f"{root}: every hand's columns are 0 in every frame ({[h.side for h, *_ in plan]}): no hand was "
                    "recorded; check the hands option"
                )
            if absent[root]:
                notes.append(
                    f"the {' and '.join(absent[root])} hand's columns are 0 in every frame of every episode: that hand "
                    "was not recorded, so it is left out (a dataset of the other hands)"
                )
            if self.keep == "all" and (video := lr.video_folder_note(Path(root), info)):
                notes.append(video)
            for n in notes:
                logger.warning("%s: %s", root, n)
        return [dataclasses.replace(r, absent_sides=absent[r.root]) for r in refs]

    def robot_type(self, refs: list) -> str | None:
        return lr.robot_type_of(refs)

    def wrist_frame(self, refs: list) -> WristFrame | None:
        """The wrist frame the datasets' recorder wrote (`meta/unidextok_wrist_frame.json`, the simulator's:
        `lerobot_unidextok/data/wrist_frame.py`); None when a dataset has none. Several datasets must agree."""
        frames = [read_recorded(root) for root in sorted({r.root for r in refs})]
        if not frames or any(f is None for f in frames):
            return None
        return merge_frames(frames, "the input datasets' meta/unidextok_wrist_frame.json")

    def read_episode(self, ref: lr.LeRobotEpisodeRef) -> RawEpisode:
        return read_mapped_episode(ref, self.hands, self.state_key, self.action_key, self.keep)


def column_plan(
    info: dict,
    root: str | Path,
    hands: list[HandColumns],
    state_key: str,
    action_key: str | None,
    notes: list[str] | None = None,
) -> tuple[list[tuple], dict[str, list[str]]]:
    """Per hand (hand, state key, state columns, action key, action columns), and the names of each feature;
    raises naming the info.json field when a hand's columns are not there; what it reads past goes to `notes`."""
    info_path = Path(root) / INFO_PATH
    names: dict[str, list[str]] = {}

    def names_of(key: str, all_columns: bool) -> list[str]:
        if key not in names:
            feature = info["features"].get(key)
            if all_columns and feature is not None and feature.get("names") is None:  # unnamed own feature
                names[key] = [f"{key}[{i}]" for i in range(int(np.prod(feature.get("shape", [0]))))]
            else:
                names[key] = lr.feature_names(info, key, root, notes)
        return names[key]

    plan = []
    for h in hands:
        s_key, a_key = h.state_key or state_key, h.action_key or action_key
        s_where = f"{info_path} features[{s_key!r}] ({h.side} hand)"
        s_cols = h.resolve(names_of(s_key, h.state_names == ALL_COLUMNS), s_where, h.state_names)
        a_cols = None
        if a_key and a_key in info["features"]:
            a_names = names_of(a_key, h.state_names == ALL_COLUMNS and h.action_key is not None)
            if h.action_key is not None and h.state_names == ALL_COLUMNS:
                a_cols = a_names  # the hand's own action feature
            else:
                wanted = h.action_names or tuple(s_cols)
                if h.action_names is not None or all(n in a_names for n in wanted):
                    a_cols = h.resolve(a_names, f"{info_path} features[{a_key!r}] ({h.side} hand)", tuple(wanted))
        elif h.action_names is not None or h.action_key is not None:
            raise lr.LeRobotFormatError(f"{info_path} features[{a_key!r}]: missing, but {h.side} hand asks for it")
        plan.append((h, s_key, s_cols, a_key if a_cols is not None else None, a_cols))
    for _, s_key, s_cols, _, _ in plan:  # a column can belong to one hand only
        if len(set(s_cols)) != len(s_cols):
            raise lr.LeRobotFormatError(f"{info_path} features[{s_key!r}]: a hand lists a column twice: {s_cols}")
    taken = [c for _, _, s_cols, _, _ in plan for c in s_cols]
    if len(set(taken)) != len(taken):
        raise lr.LeRobotFormatError(
            f"{info_path}: two hands share columns {sorted({c for c in taken if taken.count(c) > 1})}"
        )
    return plan, names


def _names_or_indices(info: dict, key: str, root) -> list[str]:
    """A vector feature's names, or `key[i]` for an unnamed one (its columns still pass through)."""
    if info["features"][key].get("names") is None:
        return [f"{key}[{i}]" for i in range(int(np.prod(info["features"][key].get("shape", [0]))))]
    return lr.feature_names(info, key, root)


def read_mapped_episode(
    ref: lr.LeRobotEpisodeRef,
    hands: list[HandColumns],
    state_key: str,
    action_key: str | None,
    keep: str = "all",
) -> RawEpisode:
    """One episode with each hand's state (and action) columns picked by name, and the rest of the robot:
    passthrough columns of the shared state/action vectors, other features copied, videos.
    `keep="hands"` (`--keep=hands`) reads no other feature and no video: their files need not exist."""
    info = lr.load_info(ref.root)
    info_path = str(Path(ref.root) / INFO_PATH)
    state_key, action_key, _ = vector_keys(info, state_key, action_key)
    plan, names = column_plan(info, ref.root, hands, state_key, action_key)
    absent = [p for p in plan if p[0].side in ref.absent_sides]  # hands never recorded: left out, columns dropped
    plan = [p for p in plan if p[0].side not in ref.absent_sides]
    has_action = all(p[4] is not None for p in plan)
    vectors = {OUT_STATE: state_key}  # output vector -> source feature holding the hands' shared columns
    if has_action and action_key and action_key in info["features"]:
        vectors[OUT_ACTION] = action_key
    used = {p[1] for p in plan} | ({p[3] for p in plan if p[3]} if has_action else set())
    used |= set(vectors.values())
    copied_ft, video_ft = lr.other_features(info, used) if keep == "all" else ({}, {})
    keys = sorted(used & set(info["features"]))
    episode = lr.read_episode(ref, keys, tuple(copied_ft), tuple(video_ft))
    streams = []
    for h, s_key, s_cols, a_key, a_cols in plan:
        state = episode.columns[s_key][:, lr.select_columns(names[s_key], s_cols, info_path)]
        action = None
        if a_cols is not None and has_action:
            action = episode.columns[a_key][:, lr.select_columns(names[a_key], a_cols, info_path)]
        streams.append(
            HandStream(
                side=h.side,
                hand=h.hand,
                state_native=state,
                action_native=action,
                state_columns=tuple(s_cols),
                action_columns=tuple(a_cols) if action is not None else None,
            )
        )
    passthrough, native_names, native_keys, dropped = {}, {}, {}, {}
    for out_key, src_key in vectors.items():
        if src_key not in info["features"]:
            continue
        src_names = names.get(src_key) or _names_or_indices(info, src_key, ref.root)
        if out_key == OUT_STATE:
            hand_cols = {c for _, s_key, s_cols, _, _ in plan if s_key == src_key for c in s_cols}
            gone = [c for _, s_key, s_cols, _, _ in absent if s_key == src_key for c in s_cols]
        else:
            hand_cols = {c for _, _, _, a_key, a_cols in plan if a_key == src_key for c in a_cols}
            gone = [c for _, _, _, a_key, a_cols in absent if a_key == src_key and a_cols for c in a_cols]
        keep = [i for i, n in enumerate(src_names) if n not in hand_cols and n not in set(gone)]
        passthrough[out_key] = Passthrough(tuple(src_names[i] for i in keep), episode.columns[src_key][:, keep])
        native_names[out_key] = list(src_names)
        if gone:
            dropped[out_key] = gone
        if src_key != out_key:
            native_keys[out_key] = src_key
    return RawEpisode(
        source_file=episode.source_file,
        fps=episode.fps,
        hands=streams,
        task=episode.task,
        extra={
            "robot_type": info.get("robot_type", ""),
            "episode_index": ref.episode_index,
            "codebase_version": info["codebase_version"],
            **({"timestamp_note": episode.timestamp_note} if episode.timestamp_note else {}),
            **({"source_notes": episode.notes} if episode.notes else {}),
        },
        passthrough=passthrough,
        native_names=native_names,
        native_keys=native_keys,
        dropped=dropped,
        copied=episode.copied,
        copied_features=copied_ft,
        copied_stats=episode.stats,
        videos=episode.videos,
        video_features=video_ft,
        source_episode={"source_episode_index": ref.episode_index},
    )
