"""What retargeting needs of a robot hand, read from its hand spec (`hands/specs/<hand>.yaml`): one YAML per
hand, the same the registry, the kinematic check and the viewer read.

From the spec's `urdf:` section of one side:
- `file`: the URDF file name, looked up under the folder the user passes (users supply their URDFs);
- `wrist_link` and `palm_links` (index / middle / pinky MCP): the links of the `wrist`, `index_mcp`,
  `middle_mcp` and `pinky_mcp` keypoints, the robot palm frame matched to the human palm frame of each
  keypoint frame (so human keypoints in any frame work);
- `targets`: per finger, the outermost keypoint that is a link's origin (no offset): the link dex-retargeting's
  vector optimizer moves and the MANO-21 keypoint it follows (a finger made of offsets only, a rigid
  stand-in, has none);
and from its joints: each native joint's `urdf_joint` (default: its own name) with the map from the URDF angle
to the native value, the spec's own (`rad_at_raw_range` over `raw_range`) or, where the URDF's angles are not
the spec's radians, `raw_at_urdf_limits` (linear over the URDF limits). Which joints the URDF drives is read
from the URDF itself (`HandRetargeter`): reserved channels and joints the file does not have keep their
spec default.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lerobot_unidextok import hands
from lerobot_unidextok.constants import KEYPOINT_NAMES
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.spec import JointSide

PALM_KEYS = ("index_mcp", "middle_mcp", "pinky_mcp")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")


@dataclass(frozen=True)
class JointLink:
    """One native joint of the hand spec, the URDF joint it is, and how a URDF angle becomes its native value."""

    native: str
    urdf: str
    side: JointSide  # the spec's joint on this side: its linear raw <-> rad map and `raw_at_urdf_limits`

    @property
    def raw_at_urdf_limits(self) -> tuple[float, float] | None:
        return self.side.raw_at_urdf_limits

    def to_native(self, angle_rad, limits_rad: tuple[float, float]):
        """URDF angles (any shape) -> native values: linearly over the URDF limits where the spec says the URDF's
        angles are not its radians (`raw_at_urdf_limits`), else the inverse of the spec's rad = offset + scale * raw."""
        if self.raw_at_urdf_limits is not None:
            lo, hi = limits_rad
            frac = (angle_rad - lo) / (hi - lo) if hi > lo else 0.0 * angle_rad
            return self.raw_at_urdf_limits[0] + frac * (self.raw_at_urdf_limits[1] - self.raw_at_urdf_limits[0])
        if self.side.scale == 0:  # a dropped joint with no radians: its raw value is fixed
            return self.side.raw_range[0] + 0.0 * angle_rad
        return (angle_rad - self.side.offset) / self.side.scale


@dataclass(frozen=True)
class SideRetargetSpec:
    """URDF file, palm links, target links and joint map of one side of a hand."""

    urdf: str
    wrist_link: str
    palm_links: dict[str, str]  # index_mcp / middle_mcp / pinky_mcp -> link name
    target_links: tuple[str, ...]
    target_keypoints: tuple[int, ...]  # MANO-21 index of each target link
    joints: tuple[JointLink, ...]  # every native joint; the URDF decides which of them it drives


def retarget_hands() -> list[str]:
    """Registered robot hands whose spec maps a URDF (retargeting targets)."""
    return [n for n in hands.names() if hands.get(n).kind == "joints" and hands.get(n).urdf is not None]


def get_retarget_spec(hand: str, side: str) -> SideRetargetSpec:
    """The retargeting view of a registered hand's spec on one side; the error lists the hands that have one."""
    if hand not in retarget_hands():
        raise InvalidInputError(
            f"no URDF map for hand {hand!r}, so it cannot be retargeted onto; hands with one: {retarget_hands()}. "
            f"Add the `urdf:` section to lerobot_unidextok/hands/specs/{hand}.yaml (docs/hands.md, 'Add your own hand')"
        )
    spec = hands.get(hand)
    if side not in spec.sides:
        raise InvalidInputError(f"hand {hand!r} has no {side!r} side; it has {list(spec.sides)}")
    keypoints = dict(zip(KEYPOINT_NAMES, spec.urdf.keypoints[side], strict=True))
    targets = []
    for finger in FINGERS:
        origins = [n for n in KEYPOINT_NAMES if n.startswith(f"{finger}_") and not any(keypoints[n].offset_m)]
        if origins:
            targets.append((keypoints[origins[-1]].link, KEYPOINT_NAMES.index(origins[-1])))
    joints = tuple(JointLink(j.name, j.sides[side].urdf_joint or j.name, j.sides[side]) for j in spec.joints)
    return SideRetargetSpec(
        urdf=Path(spec.urdf.files[side]).name,
        wrist_link=keypoints["wrist"].link,
        palm_links={key: keypoints[key].link for key in PALM_KEYS},
        target_links=tuple(link for link, _ in targets),
        target_keypoints=tuple(k for _, k in targets),
        joints=joints,
    )
