"""Load and validate one hand YAML into a HandSpec. Every problem names the file and the field."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from lerobot_unidextok.constants import FINGERS, SIDES, UDHM_INDEX
from lerobot_unidextok.hands.spec import CoupledJoint, HandSpec, JointSide, JointSpec, SkeletonSpec

_TOP_KEYS = {
    "name", "embodiment", "kind", "description", "source", "sides", "native_units",
    "joints", "coupled", "skeleton",
}  # fmt: skip
_JOINT_KEYS = {"name", "slot", "raw_range", "rad_at_raw_range", "sign", "default_raw", "note", "judgement", *SIDES}
_SIDE_KEYS = {"raw_range", "rad_at_raw_range", "sign", "default_raw"}
_COUPLED_KEYS = {"joint", "follows", "ratio", "offset_rad", "note"}
_SKELETON_KEYS = {"scale", "bone_lengths_m", "note"}


class SpecError(ValueError):
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
        _unique([j.slot for j in joints if j.slot is not None], "joints[].slot", fail)
    elif data.get("joints"):
        raise fail("joints", "a kind 'keypoints' hand takes MANO-21 keypoints and lists no joints")

    coupled = tuple(_coupled(c, f"coupled[{i}]", fail) for i, c in enumerate(data.get("coupled") or []))
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
    if slot is not None and slot not in UDHM_INDEX:
        raise fail(f"{where}.slot", f"{slot!r} is not a UDHM joint; use one of {list(UDHM_INDEX)} or null")
    per_side = {}
    for side in sides:
        override = jd.get(side) or {}
        if not isinstance(override, dict):
            raise fail(f"{where}.{side}", f"expected a mapping, got {override!r}")
        _no_unknown(override, _SIDE_KEYS, f"{where}.{side}", fail)
        merged = {k: jd[k] for k in _SIDE_KEYS if k in jd} | override
        per_side[side] = _joint_side(merged, f"{where}[{side}]", slot, fail)
    for side in SIDES:
        if side in jd and side not in sides:
            raise fail(f"{where}.{side}", f"side {side!r} is not in this hand's sides {sides}")
    return JointSpec(
        name=name,
        slot=slot,
        sides=per_side,
        note=str(jd.get("note", "")).strip(),
        judgement=str(jd.get("judgement", "")).strip(),
    )


def _joint_side(d: dict, where: str, slot: str | None, fail) -> JointSide:
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
    return JointSide(raw_range=raw, rad_at_raw_range=rad, sign=float(sign), default_raw=float(default_raw))


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
    )


def _skeleton(s: Any, fail) -> SkeletonSpec:
    if not isinstance(s, dict):
        raise fail("skeleton", f"expected a mapping, got {s!r}")
    _no_unknown(s, _SKELETON_KEYS, "skeleton", fail)
    scale = _number(s.get("scale", 1.0), "skeleton.scale", fail)
    if not scale > 0:
        raise fail("skeleton.scale", f"{scale} must be > 0")
    bones = s.get("bone_lengths_m")
    parsed = None
    if bones is not None:
        if not isinstance(bones, dict) or set(bones) - set(FINGERS):
            raise fail("skeleton.bone_lengths_m", f"must map finger names {list(FINGERS)} to 3 lengths in metres")
        parsed = {}
        for finger, lengths in bones.items():
            if not isinstance(lengths, list) or len(lengths) != 3:
                raise fail(f"skeleton.bone_lengths_m.{finger}", f"{lengths!r} must be 3 lengths in metres")
            vals = tuple(_number(v, f"skeleton.bone_lengths_m.{finger}", fail) for v in lengths)
            if any(not 0 < v < 0.5 for v in vals):
                raise fail(f"skeleton.bone_lengths_m.{finger}", f"{list(vals)} must be in (0, 0.5) m")
            parsed[finger] = vals
    return SkeletonSpec(scale=scale, bone_lengths_m=parsed, note=str(s.get("note", "")).strip())


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
