"""Load and validate one hand YAML into a HandSpec. Every problem names the file and the field."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from lerobot_unidextok.constants import FINGERS, KEYPOINT_NAMES, SIDES, UDHM_INDEX
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.spec import (
    CoupledJoint,
    HandSpec,
    JointSide,
    JointSpec,
    SkeletonSpec,
    UrdfKeypoint,
    UrdfSpec,
)

_TOP_KEYS = {
    "name", "embodiment", "kind", "description", "source", "sides", "native_units",
    "joints", "coupled", "skeleton", "urdf",
}  # fmt: skip
_SIDE_KEYS = {"slot", "raw_range", "rad_at_raw_range", "sign", "rest_rad", "default_raw", "urdf_joint",
              "raw_at_urdf_limits"}
_JOINT_KEYS = {"name", "note", "judgement", "aliases", *_SIDE_KEYS, *SIDES}
_COUPLED_KEYS = {"joint", "follows", "ratio", "offset_rad", "note", "slot"}
_SKELETON_KEYS = {"scale", "bone_lengths_m", "palm_offsets_m", "source", "note"}
_URDF_KEYS = {"source", "file", "keypoints", "note", *SIDES}
_URDF_SIDE_KEYS = {"file", "keypoints"}
# Name templates in `urdf_joint` and keypoint links, expanded per side (vendors prefix names by side).
_SIDE_TEMPLATES = {"<side>": {"right": "right", "left": "left"}, "<s>": {"right": "r", "left": "l"},
                   "<S>": {"right": "R", "left": "L"}}  # fmt: skip


def expand_side(name: str, side: str) -> str:
    """``name`` with ``<side>`` / ``<s>`` / ``<S>`` replaced by right/left, r/l, R/L."""
    for key, values in _SIDE_TEMPLATES.items():
        name = name.replace(key, values[side])
    return name


class SpecError(InvalidInputError):
    """A hand YAML that does not validate."""


def load_spec(path: str | Path) -> HandSpec:
    """Read one hand YAML and validate it; raises ``SpecError`` (a ValueError) naming file and field."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"hand spec file not found: {path}")
    with path.open(encoding="utf-8") as f:
        try:
            data = yaml.safe_load(f)
        except yaml.YAMLError as e:
            raise SpecError(f"{path}: not valid YAML: {e}") from e
    return spec_from_dict(data, source=str(path), path=path)


def spec_from_dict(data: Any, source: str = "<dict>", path: Path | None = None) -> HandSpec:
    """Validate a parsed hand YAML mapping and build the HandSpec."""

    def fail(field: str, msg: str) -> SpecError:
        return SpecError(f"{source}: field {field!r}: {msg}")

    if not isinstance(data, dict):
        raise SpecError(f"{source}: expected a mapping at top level, got {type(data).__name__}")
    _no_unknown(data, _TOP_KEYS, "<top level>", fail)
    for key in ("name", "embodiment", "kind", "sides", "native_units"):
        if key not in data:
            raise fail(key, "missing (required)")
    name = _string(data["name"], "name", fail)
    if path is not None and path.stem != name:
        raise fail("name", f"{name!r} must equal the file name stem {path.stem!r}")
    kind = data["kind"]
    if kind not in ("joints", "keypoints"):
        raise fail("kind", f"{kind!r} must be 'joints' or 'keypoints'")
    sides = data["sides"]
    if not isinstance(sides, list) or not sides or any(s not in SIDES for s in sides) or len(set(sides)) != len(sides):
        raise fail("sides", f"{sides!r} must be a non-empty list of distinct values from {list(SIDES)}")

    joints: list[JointSpec] = []
    if kind == "joints":
        raw_joints = data.get("joints")
        if not isinstance(raw_joints, list) or not raw_joints:
            raise fail("joints", "a kind 'joints' hand needs a non-empty list of joints")
        for i, jd in enumerate(raw_joints):
            joints.append(_joint(jd, f"joints[{i}]", sides, fail))
        _unique([j.name for j in joints], "joints[].name", fail)
        for side in sides:
            _unique([j.sides[side].slot for j in joints if j.sides[side].slot is not None], "joints[].slot", fail)
            if side != sides[0]:
                _same_slots(joints, sides[0], side, fail)
    elif data.get("joints"):
        raise fail("joints", "a kind 'keypoints' hand takes MANO-21 keypoints and lists no joints")

    coupled = tuple(_coupled(c, f"coupled[{i}]", fail) for i, c in enumerate(data.get("coupled") or []))
    _drawn_couplings(coupled, joints, fail)
    return HandSpec(
        name=name,
        embodiment=_string(data["embodiment"], "embodiment", fail),
        kind=kind,
        sides=tuple(sides),
        native_units=_string(data["native_units"], "native_units", fail),
        joints=tuple(joints),
        description=str(data.get("description", "")).strip(),
        source=str(data.get("source", "")).strip(),
        coupled=coupled,
        skeleton_spec=_skeleton(data.get("skeleton") or {}, fail),
        urdf=_urdf(data["urdf"], sides, fail) if data.get("urdf") is not None else None,
        path=path,
    )


# ---------------------------------------------------------------------------------------------
# field parsers
# ---------------------------------------------------------------------------------------------
def _joint(jd: Any, where: str, sides: list[str], fail) -> JointSpec:
    if not isinstance(jd, dict):
        raise fail(where, f"expected a mapping, got {jd!r}")
    _no_unknown(jd, _JOINT_KEYS, where, fail)
    if "name" not in jd:
        raise fail(f"{where}.name", "missing (required)")
    name = _string(jd["name"], f"{where}.name", fail)
    where = f"{where} ({name})"
    if "slot" not in jd:
        raise fail(f"{where}.slot", "missing; give a UDHM joint name or null for a dropped joint")
    slot = jd["slot"]
    per_side = {}
    for side in sides:
        override = jd.get(side) or {}
        if not isinstance(override, dict):
            raise fail(f"{where}.{side}", f"expected a mapping, got {override!r}")
        _no_unknown(override, _SIDE_KEYS, f"{where}.{side}", fail)
        merged = {k: jd[k] for k in _SIDE_KEYS if k in jd} | override
        per_side[side] = _joint_side(merged, f"{where}[{side}]", side, fail)
    for side in SIDES:
        if side in jd and side not in sides:
            raise fail(f"{where}.{side}", f"side {side!r} is not in this hand's sides {sides}")
    return JointSpec(
        name=name,
        slot=slot,
        sides=per_side,
        note=str(jd.get("note", "")).strip(),
        judgement=str(jd.get("judgement", "")).strip(),
        aliases=tuple(_string(a, f"{where}.aliases", fail) for a in jd.get("aliases") or ()),
    )


def _joint_side(d: dict, where: str, side: str, fail) -> JointSide:
    slot = d["slot"]
    if slot is not None and slot not in UDHM_INDEX:
        raise fail(f"{where}.slot", f"{slot!r} is not a UDHM joint; use one of {list(UDHM_INDEX)} or null")
    for key in ("raw_range", "rad_at_raw_range"):
        if key not in d:
            raise fail(f"{where}.{key}", "missing (give it on the joint or under each side)")
    raw = _pair(d["raw_range"], f"{where}.raw_range", fail)
    rad = _pair(d["rad_at_raw_range"], f"{where}.rad_at_raw_range", fail)
    if not raw[0] < raw[1]:
        raise fail(f"{where}.raw_range", f"min {raw[0]} must be < max {raw[1]}")
    if rad[0] == rad[1] and slot is not None:
        raise fail(f"{where}.rad_at_raw_range", f"{list(rad)} has zero span; only a dropped joint (slot null) may")
    sign = d.get("sign", 1)
    if sign not in (1, -1):
        raise fail(f"{where}.sign", f"{sign!r} must be 1 or -1")
    default_raw = d.get("default_raw", _raw_at_zero_rad(raw, rad))
    if not isinstance(default_raw, int | float) or not raw[0] <= default_raw <= raw[1]:
        raise fail(f"{where}.default_raw", f"{default_raw!r} must be a number inside raw_range {list(raw)}")
    rest = _number(d.get("rest_rad", 0.0), f"{where}.rest_rad", fail)
    urdf_joint = d.get("urdf_joint")
    if urdf_joint is not None:
        urdf_joint = expand_side(_string(urdf_joint, f"{where}.urdf_joint", fail), side)
    at_limits = d.get("raw_at_urdf_limits")
    if at_limits is not None:
        at_limits = _pair(at_limits, f"{where}.raw_at_urdf_limits", fail)
        if at_limits[0] == at_limits[1]:
            raise fail(f"{where}.raw_at_urdf_limits", f"{list(at_limits)} must be two different raw values")
    return JointSide(
        raw_range=raw,
        rad_at_raw_range=rad,
        sign=float(sign),
        default_raw=float(default_raw),
        slot=slot,
        rest_rad=rest,
        urdf_joint=urdf_joint,
        raw_at_urdf_limits=at_limits,
    )


def _same_slots(joints: list[JointSpec], first: str, side: str, fail) -> None:
    """Every side fills the same UDHM slots and drops the same joints (only the assignment may differ)."""
    for j in joints:
        if (j.sides[first].slot is None) != (j.sides[side].slot is None):
            raise fail(f"joints ({j.name}).slot", f"dropped on one side only ({first} vs {side}); drop it on both")
    a = {j.sides[first].slot for j in joints} - {None}
    b = {j.sides[side].slot for j in joints} - {None}
    if a != b:
        raise fail(
            "joints[].slot",
            f"sides fill different UDHM slots: {sorted(a - b)} only on {first}, {sorted(b - a)} only on {side}",
        )


def _raw_at_zero_rad(raw: tuple[float, float], rad: tuple[float, float]) -> float:
    """Raw value whose angle is closest to 0 rad: the default for dropped joints."""
    if rad[0] == rad[1]:
        return raw[1]
    t = min(max(-rad[0] / (rad[1] - rad[0]), 0.0), 1.0)
    return raw[0] + t * (raw[1] - raw[0])


def _coupled(c: Any, where: str, fail) -> CoupledJoint:
    if not isinstance(c, dict):
        raise fail(where, f"expected a mapping, got {c!r}")
    _no_unknown(c, _COUPLED_KEYS, where, fail)
    for key in ("joint", "follows", "ratio"):
        if key not in c:
            raise fail(f"{where}.{key}", "missing (required)")
    return CoupledJoint(
        joint=_string(c["joint"], f"{where}.joint", fail),
        follows=_string(c["follows"], f"{where}.follows", fail),
        ratio=_number(c["ratio"], f"{where}.ratio", fail),
        offset_rad=_number(c.get("offset_rad", 0.0), f"{where}.offset_rad", fail),
        note=str(c.get("note", "")).strip(),
        slot=None if c.get("slot") is None else _string(c["slot"], f"{where}.slot", fail),
    )


def _drawn_couplings(coupled: tuple[CoupledJoint, ...], joints: list[JointSpec], fail) -> None:
    """A coupled joint with a ``slot`` follows a native joint that has a slot and bends a slot no joint fills."""
    by_name = {j.name: j for j in joints}
    filled = {s.slot for j in joints for s in j.sides.values()} - {None}
    drawn: set[str] = set()
    for i, c in enumerate(coupled):
        if c.slot is None:
            continue
        where = f"coupled[{i}]"
        if c.slot not in UDHM_INDEX:
            raise fail(f"{where}.slot", f"{c.slot!r} is not a UDHM joint; use one of {list(UDHM_INDEX)}")
        if c.slot in filled or c.slot in drawn:
            raise fail(f"{where}.slot", f"{c.slot!r} is already filled by a joint or another coupling")
        leader = by_name.get(c.follows)
        if leader is None or leader.slot is None:
            raise fail(f"{where}.follows", f"{c.follows!r} must name a native joint with a UDHM slot when slot is given; "
                                           f"joints: {[j.name for j in joints if j.slot is not None]}")  # fmt: skip
        drawn.add(c.slot)


def _skeleton(s: Any, fail) -> SkeletonSpec:
    if not isinstance(s, dict):
        raise fail("skeleton", f"expected a mapping, got {s!r}")
    _no_unknown(s, _SKELETON_KEYS, "skeleton", fail)
    scale = _number(s.get("scale", 1.0), "skeleton.scale", fail)
    if not scale > 0:
        raise fail("skeleton.scale", f"{scale} must be > 0")
    bones = _per_finger(s.get("bone_lengths_m"), "skeleton.bone_lengths_m", (0.0, 0.5), fail)
    offsets = _per_finger(s.get("palm_offsets_m"), "skeleton.palm_offsets_m", (-0.5, 0.5), fail)
    if offsets is not None:
        if set(offsets) != set(FINGERS) or bones is None or set(bones) != set(FINGERS):
            raise fail(
                "skeleton.palm_offsets_m",
                f"a measured skeleton needs palm_offsets_m and bone_lengths_m for every finger {list(FINGERS)}",
            )
        if "scale" in s and scale != 1.0:
            raise fail("skeleton.scale", "a measured skeleton (palm_offsets_m) takes no scale")
    return SkeletonSpec(
        scale=scale,
        bone_lengths_m=bones,
        palm_offsets_m=offsets,
        source=str(s.get("source", "")).strip(),
        note=str(s.get("note", "")).strip(),
    )


def _per_finger(v: Any, field: str, bounds: tuple[float, float], fail) -> dict[str, tuple] | None:
    """finger -> 3 numbers in metres within ``bounds`` (bone lengths must also be > 0)."""
    if v is None:
        return None
    if not isinstance(v, dict) or set(v) - set(FINGERS):
        raise fail(field, f"must map finger names {list(FINGERS)} to 3 values in metres")
    parsed = {}
    for finger, values in v.items():
        if not isinstance(values, list) or len(values) != 3:
            raise fail(f"{field}.{finger}", f"{values!r} must be 3 values in metres")
        vals = tuple(_number(x, f"{field}.{finger}", fail) for x in values)
        if any(not bounds[0] < x < bounds[1] for x in vals):
            raise fail(f"{field}.{finger}", f"{list(vals)} must be in ({bounds[0]:g}, {bounds[1]:g}) m")
        parsed[finger] = vals
    return parsed


def _urdf(u: Any, sides: list[str], fail) -> UrdfSpec:
    """The `urdf:` block: source, file per side and the 21 keypoints as links (+ offsets), per side."""
    if not isinstance(u, dict):
        raise fail("urdf", f"expected a mapping, got {u!r}")
    _no_unknown(u, _URDF_KEYS, "urdf", fail)
    files, keypoints = {}, {}
    for side in sides:
        override = u.get(side) or {}
        if not isinstance(override, dict):
            raise fail(f"urdf.{side}", f"expected a mapping, got {override!r}")
        _no_unknown(override, _URDF_SIDE_KEYS, f"urdf.{side}", fail)
        file = override.get("file", u.get("file"))
        if file is None:
            raise fail(f"urdf.{side}.file", "missing: the URDF file of this side (relative to a URDF folder)")
        files[side] = expand_side(_string(file, f"urdf.{side}.file", fail), side)
        merged = dict(u.get("keypoints") or {}) | dict(override.get("keypoints") or {})
        missing = [k for k in KEYPOINT_NAMES if k not in merged]
        unknown = sorted(set(merged) - set(KEYPOINT_NAMES))
        if missing or unknown:
            raise fail(
                f"urdf.{side}.keypoints",
                f"must give every MANO-21 keypoint {list(KEYPOINT_NAMES)}; missing {missing}, unknown {unknown}",
            )
        keypoints[side] = tuple(_keypoint(merged[k], f"urdf.keypoints.{k}", side, fail) for k in KEYPOINT_NAMES)
    return UrdfSpec(
        source=_string(u.get("source", ""), "urdf.source", fail),
        files=files,
        keypoints=keypoints,
        note=str(u.get("note", "")).strip(),
    )


def _keypoint(v: Any, field: str, side: str, fail) -> UrdfKeypoint:
    """``link`` or ``[link, [x, y, z]]`` (offset in metres in the link frame)."""
    if isinstance(v, str):
        return UrdfKeypoint(expand_side(_string(v, field, fail), side))
    if isinstance(v, list) and len(v) == 2 and isinstance(v[0], str) and isinstance(v[1], list) and len(v[1]) == 3:
        offset = tuple(_number(x, field, fail) for x in v[1])
        if any(abs(x) > 0.5 for x in offset):
            raise fail(field, f"offset {list(offset)} must be in metres (|x| <= 0.5)")
        return UrdfKeypoint(expand_side(_string(v[0], field, fail), side), offset)
    raise fail(field, f"{v!r} must be a link name or [link, [x, y, z]] with the offset in metres")


# ---------------------------------------------------------------------------------------------
# small validators
# ---------------------------------------------------------------------------------------------
def _no_unknown(d: dict, allowed: set[str], where: str, fail) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise fail(where, f"unknown key(s) {unknown}; allowed: {sorted(allowed)}")


def _unique(values: list, field: str, fail) -> None:
    seen, dup = set(), []
    for v in values:
        (dup.append(v) if v in seen else seen.add(v))
    if dup:
        raise fail(field, f"duplicate value(s) {sorted(set(dup))}")


def _string(v: Any, field: str, fail) -> str:
    if not isinstance(v, str) or not v.strip():
        raise fail(field, f"{v!r} must be a non-empty string")
    return v.strip()


def _number(v: Any, field: str, fail) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise fail(field, f"{v!r} must be a finite number")
    return float(v)


def _pair(v: Any, field: str, fail) -> tuple[float, float]:
    if not isinstance(v, list) or len(v) != 2:
        raise fail(field, f"{v!r} must be a list [a, b] of two numbers")
    return (_number(v[0], field, fail), _number(v[1], field, fail))
