"""Retargeting specs as data: which URDF file, links and joints stand for a registered hand.

One YAML per hand in `retarget/specs/<hand>.yaml` (see `linkerhand_l10.yaml` for the annotated format):

- `urdf`: the URDF file name, looked up under the folder the user passes (users supply their URDFs).
- `wrist_link` and `palm_links` (`index_mcp`, `middle_mcp`, `pinky_mcp`): the robot palm frame, matched to
  the human palm frame of each keypoint frame (so human keypoints in any frame work).
- `targets`: robot link <-> MANO-21 keypoint pairs; dex-retargeting's vector optimizer matches the
  wrist -> target vectors.
- `joints`: the hand spec's native joints (`hands.get(hand).joint_names`) and the URDF joint each one is, with
  `raw_at_limits: [raw at the URDF lower limit, raw at the upper limit]` (linear), or no `raw_at_limits` when
  the native value is the URDF angle in radians. Native joints not listed (reserved channels) take their
  spec default.
- A side may be `{same_as: right, rename: {old: new}}`: the other side's entry with substrings replaced.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import yaml

from lerobot_unidextok.constants import KEYPOINT_NAMES, SIDES
from lerobot_unidextok.errors import InvalidInputError

SPECS_DIR = Path(__file__).parent / "specs"
PALM_KEYS = ("index_mcp", "middle_mcp", "pinky_mcp")


class RetargetSpecError(InvalidInputError):
    """A retarget spec YAML is malformed; the message names the file and the field."""


@dataclass(frozen=True)
class JointLink:
    """One native joint of the hand spec and the URDF joint it is."""

    native: str
    urdf: str
    raw_at_limits: tuple[float, float] | None  # raw at (URDF lower, URDF upper); None = raw is the URDF angle (rad)


@dataclass(frozen=True)
class SideRetargetSpec:
    """URDF, palm links, target links and joint map of one side of a hand."""

    urdf: str
    wrist_link: str
    palm_links: dict[str, str]  # index_mcp / middle_mcp / pinky_mcp -> link name
    target_links: tuple[str, ...]
    target_keypoints: tuple[int, ...]  # MANO-21 index of each target link
    joints: tuple[JointLink, ...]


@dataclass(frozen=True)
class RetargetSpec:
    hand: str
    sides: dict[str, SideRetargetSpec]
    path: Path | None = None

    def side(self, side: str) -> SideRetargetSpec:
        if side not in self.sides:
            raise ValueError(
                f"retarget spec {self.hand!r} has no {side!r} side; it has {sorted(self.sides)} ({self.path})"
            )
        return self.sides[side]


def _rename(value, table: dict[str, str]):
    if isinstance(value, str):
        for old, new in table.items():
            value = value.replace(old, new)
        return value
    if isinstance(value, list):
        return [_rename(v, table) for v in value]
    if isinstance(value, dict):
        return {k: _rename(v, table) for k, v in value.items()}
    return value


def _side_from_dict(entry: dict, where: str) -> SideRetargetSpec:
    need = {"urdf", "wrist_link", "palm_links", "targets", "joints"}
    missing = sorted(need - set(entry))
    if missing:
        raise RetargetSpecError(f"{where}: missing fields {missing} (need {sorted(need)})")
    unknown = sorted(set(entry) - need)
    if unknown:
        raise RetargetSpecError(f"{where}: unknown fields {unknown} (allowed {sorted(need)})")
    palm = dict(entry["palm_links"])
    if sorted(palm) != sorted(PALM_KEYS):
        raise RetargetSpecError(f"{where}.palm_links must name exactly {list(PALM_KEYS)}, got {sorted(palm)}")
    links, kps = [], []
    for i, t in enumerate(entry["targets"]):
        if not isinstance(t, dict) or set(t) != {"link", "keypoint"}:
            raise RetargetSpecError(f"{where}.targets[{i}] must be {{link: <robot link>, keypoint: <MANO-21 name>}}")
        if t["keypoint"] not in KEYPOINT_NAMES:
            raise RetargetSpecError(f"{where}.targets[{i}].keypoint {t['keypoint']!r} is not one of {KEYPOINT_NAMES}")
        links.append(str(t["link"]))
        kps.append(KEYPOINT_NAMES.index(t["keypoint"]))
    if len(links) < 2:
        raise RetargetSpecError(f"{where}.targets: need at least 2 target links, got {len(links)}")
    joints = []
    for i, j in enumerate(entry["joints"]):
        if not isinstance(j, dict) or not {"native", "urdf"} <= set(j) or set(j) - {"native", "urdf", "raw_at_limits"}:
            raise RetargetSpecError(f"{where}.joints[{i}] must be {{native, urdf[, raw_at_limits]}}, got {j!r}")
        ral = j.get("raw_at_limits")
        if ral is not None and (len(ral) != 2 or float(ral[0]) == float(ral[1])):
            raise RetargetSpecError(f"{where}.joints[{i}].raw_at_limits must be two different numbers, got {ral!r}")
        joints.append(
            JointLink(str(j["native"]), str(j["urdf"]), None if ral is None else (float(ral[0]), float(ral[1])))
        )
    natives = [j.native for j in joints]
    if len(set(natives)) != len(natives):
        raise RetargetSpecError(f"{where}.joints: a native joint is listed twice: {natives}")
    return SideRetargetSpec(
        urdf=str(entry["urdf"]),
        wrist_link=str(entry["wrist_link"]),
        palm_links=palm,
        target_links=tuple(links),
        target_keypoints=tuple(kps),
        joints=tuple(joints),
    )


def load_retarget_spec(path: str | Path) -> RetargetSpec:
    """Parse one retarget spec YAML (raises RetargetSpecError naming the file and field)."""
    path = Path(path)
    data = yaml.safe_load(path.read_text())
    if not isinstance(data, dict) or "hand" not in data or "sides" not in data:
        raise RetargetSpecError(f"{path}: a retarget spec needs `hand:` and `sides:`")
    raw_sides = data["sides"]
    sides = {}
    for side, entry in raw_sides.items():
        if side not in SIDES:
            raise RetargetSpecError(f"{path}: side {side!r} must be one of {SIDES}")
        if "same_as" in entry:
            other = entry["same_as"]
            if other not in raw_sides or "same_as" in raw_sides[other]:
                raise RetargetSpecError(f"{path}: sides.{side}.same_as must name a side given in full, got {other!r}")
            entry = _rename(raw_sides[other], dict(entry.get("rename", {})))
        sides[side] = _side_from_dict(entry, f"{path}: sides.{side}")
    return RetargetSpec(hand=str(data["hand"]), sides=sides, path=path)


@cache
def _registry() -> dict[str, RetargetSpec]:
    specs = [load_retarget_spec(p) for p in sorted(SPECS_DIR.glob("*.yaml"))]
    return {s.hand: s for s in specs}


def retarget_hands() -> list[str]:
    """Hands with a retarget spec (retargeting targets)."""
    return sorted(_registry())


def get_retarget_spec(hand: str) -> RetargetSpec:
    """The retarget spec of a registered hand; the error lists the hands that have one."""
    if hand not in _registry():
        raise ValueError(
            f"no retarget spec for hand {hand!r}; hands with one: {retarget_hands()}. "
            f"Add lerobot_unidextok/retarget/specs/{hand}.yaml (URDF file, links, joint map)"
        )
    return _registry()[hand]
