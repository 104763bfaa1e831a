"""HandSpec: one hand's native joints, their conversion to radians and their UDHM slots.

Conversions are linear per native joint and side: ``rad = offset + scale * raw``; then semantic
insertion ``udhm[slot] = sign * (rad - rest_rad)``, where ``rest_rad`` is the joint angle at which the
robot's geometry reads UDHM zero for that slot (0 for most joints; the thumb base of most robot hands sits
far from UDHM zero). Slot, sign and rest may differ per side. Everything is batched over leading dims,
numpy or torch.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch

from lerobot_unidextok.constants import (
    FINGERS,
    MAPPINGS,
    NUM_KEYPOINTS,
    UDHM_DIM,
    UDHM_INDEX,
    UDHM_JOINT_NAMES,
    UdhmMapping,
)

logger = logging.getLogger(__name__)

OutOfRange = Literal["raise", "clip"]
Array = np.ndarray | torch.Tensor

OUT_OF_RANGE_MODES: tuple[str, ...] = ("raise", "clip")
# Relative slack on range checks so float round-off at an end point is not "out of range".
_RANGE_TOL = 1e-6


# ---------------------------------------------------------------------------------------------
# data classes (what one YAML file holds)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class JointSide:
    """One native joint on one side: raw range, its radian image, UDHM slot, sign and rest angle."""

    raw_range: tuple[float, float]  # (raw_a, raw_b), raw_a < raw_b
    rad_at_raw_range: tuple[float, float]  # radians at raw_a and raw_b (direction included)
    sign: float  # +1 or -1: udhm[slot] = sign * (rad - rest_rad)
    default_raw: float  # what from_udhm writes for a dropped joint
    slot: str | None = None  # UDHM slot on this side (None = dropped)
    rest_rad: float = 0.0  # joint angle (rad) at which the UDHM slot reads 0
    urdf_joint: str | None = None  # the URDF joint this native joint drives (kinematic check); None = none
    # Retargeting onto a URDF whose angles are not this spec's radians (LinkerHand L10's rewritten right file):
    # the raw value at the URDF joint's lower and upper limit, linear between. None = the URDF angle is `rad`.
    raw_at_urdf_limits: tuple[float, float] | None = None

    @property
    def scale(self) -> float:
        return (self.rad_at_raw_range[1] - self.rad_at_raw_range[0]) / (self.raw_range[1] - self.raw_range[0])

    @property
    def offset(self) -> float:
        return self.rad_at_raw_range[0] - self.scale * self.raw_range[0]

    @property
    def limits_rad(self) -> tuple[float, float]:
        return (min(self.rad_at_raw_range), max(self.rad_at_raw_range))


@dataclass(frozen=True)
class JointSpec:
    """One native joint: name, default UDHM slot (None = dropped) and per-side conversion.

    ``slot`` is the YAML's joint-level slot; a side may override it (``sides[side].slot``), e.g. the left
    Allegro file, whose joints 8-11 are the index. A joint dropped on one side is dropped on all.
    """

    name: str
    slot: str | None
    sides: dict[str, JointSide]
    note: str = ""
    judgement: str = ""  # non-empty = a judgement call, with its reason
    # other names recordings give this joint (e.g. Unitree's "Pinky" for the Inspire's "little"): a source's
    # hand columns are bound to joints by these names and `name` (`hands.spec.column_joint`)
    aliases: tuple[str, ...] = ()


def _name_key(name: str) -> str:
    """A column or joint name for matching: lower case, letters and digits only, a trailing `pos` dropped."""
    key = "".join(ch for ch in name.lower() if ch.isalnum())
    return key.removesuffix("pos") if len(key) > 3 else key


@dataclass(frozen=True)
class CoupledJoint:
    """A passive/mimic joint of the hardware: ``angle = ratio * angle(follows) + offset_rad`` (URDF mimic).

    Never inserted into UDHM (the tokenizer sees actuated DoFs only). With ``slot`` it is drawn: the
    viewer sets that UDHM slot to the joint's angle, ``follows`` being the native joint that drives it.
    """

    joint: str
    follows: str
    ratio: float
    offset_rad: float = 0.0
    note: str = ""
    slot: str | None = None  # UDHM slot the passive joint bends when the hand is drawn; None = documentation only


@dataclass(frozen=True)
class SkeletonSpec:
    """Hand dimensions: measured (palm offsets + bone lengths, e.g. from the URDF) or a scaled human skeleton.

    With ``palm_offsets_m`` (every finger) the skeleton is exactly the measured one; otherwise the default
    human skeleton times ``scale``, with optional per-finger ``bone_lengths_m`` overrides.
    """

    scale: float = 1.0
    bone_lengths_m: dict[str, tuple[float, float, float]] | None = None  # finger -> 3 segments
    palm_offsets_m: dict[str, tuple[float, float, float]] | None = None  # finger -> base offset from the wrist
    source: str = ""  # where measured values come from (URDF file and the command that derived them)
    note: str = ""

    @property
    def measured(self) -> bool:
        return self.palm_offsets_m is not None

    def describe(self) -> str:
        """One line saying which skeleton this is (printed next to keypoint metrics)."""
        if self.measured:
            return f"measured: {self.source or 'palm offsets and bone lengths in the spec'}"
        base = "default human skeleton" + ("" if self.scale == 1.0 else f" x {self.scale:g}")
        return base + (" with per-finger bone lengths" if self.bone_lengths_m else "") + " (approximation)"

    def skeleton(self):
        """``udhm.Skeleton``: the measured one (palm offsets + bone lengths, canonicalised) when given, else the
        default human skeleton times ``scale`` with per-finger bone lengths overriding."""
        from lerobot_unidextok.udhm.skeleton import Skeleton

        if self.measured:
            offsets = np.array([self.palm_offsets_m[f] for f in FINGERS], dtype=np.float64)  # (5, 3)
            bones = np.array([self.bone_lengths_m[f] for f in FINGERS], dtype=np.float64)  # (5, 3)
            return Skeleton(offsets, bones).canonicalized()
        skel = Skeleton.default().scaled(self.scale)
        if not self.bone_lengths_m:
            return skel
        bones = np.array(skel.bone_lengths_m, dtype=np.float64)  # (5, 3)
        for finger, lengths in self.bone_lengths_m.items():
            bones[FINGERS.index(finger)] = lengths
        return Skeleton(np.array(skel.palm_offsets_m), bones)


@dataclass(frozen=True)
class UrdfKeypoint:
    """A MANO-21 keypoint on a robot: a URDF link's frame and an offset (m) in that frame."""

    link: str
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class UrdfSpec:
    """Where the hand's URDF is and how its links give the 21 MANO keypoints, per side.

    ``files[side]`` is a path relative to a URDF folder (the project's checks use ``../shared/data/urdf``,
    laid out ``<upstream folder>/<file>``); users pass their own file to the check command.
    """

    source: str
    files: dict[str, str]
    keypoints: dict[str, tuple[UrdfKeypoint, ...]]  # side -> 21 keypoints in MANO-21 order
    note: str = ""


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _to_float(x: Any) -> Array:
    """numpy/torch float view of `x` (integers become float64 / float32)."""
    if isinstance(x, torch.Tensor):
        return x if x.is_floating_point() else x.to(torch.float32)
    arr = np.asarray(x)
    if arr.dtype.kind not in "fc":
        arr = arr.astype(np.float64)
    return arr


def _table(values: np.ndarray, like: Array) -> Array:
    if isinstance(like, torch.Tensor):
        return torch.as_tensor(values, dtype=like.dtype, device=like.device)
    return values.astype(like.dtype, copy=False)


def _isnan_any(x: Array) -> bool:
    return bool(torch.isnan(x).any()) if isinstance(x, torch.Tensor) else bool(np.isnan(x).any())


def _clip(x: Array, lo: Array, hi: Array) -> Array:
    if isinstance(x, torch.Tensor):
        return torch.minimum(torch.maximum(x, lo), hi)
    return np.minimum(np.maximum(x, lo), hi)


def _zeros(shape: tuple[int, ...], like: Array) -> Array:
    if isinstance(like, torch.Tensor):
        return torch.zeros(shape, dtype=like.dtype, device=like.device)
    return np.zeros(shape, dtype=like.dtype)


def _where(cond: Array, a: Array, b: Array) -> Array:
    return torch.where(cond, a, b) if isinstance(a, torch.Tensor) else np.where(cond, a, b)


@dataclass(frozen=True)
class _SideTable:
    """Per-side arrays over native joints, built once from the JointSpecs."""

    raw_lo: np.ndarray  # (J,)
    raw_hi: np.ndarray  # (J,)
    offset: np.ndarray  # (J,)
    scale: np.ndarray  # (J,)
    sign: np.ndarray  # (J,)
    rad_lo: np.ndarray  # (J,)
    rad_hi: np.ndarray  # (J,)
    default_raw: np.ndarray  # (J,)
    rest: np.ndarray  # (J,) rest_rad
    slot_idx: np.ndarray  # (A,) UDHM index of each active joint (native order of `active_joint_indices`)


# ---------------------------------------------------------------------------------------------
# main class
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HandSpec:
    """A hand as data: native joints, units, conversion to radians and UDHM slots.

    ``kind == "joints"``: native = joint values (..., J) in ``native_units``.
    ``kind == "keypoints"`` (the human hand): native = MANO-21 keypoints (..., 21, 3) in metres,
    mapped to UDHM by ``udhm.inverse_kinematics`` and back by forward kinematics.
    """

    name: str
    embodiment: str  # hand-type label for tokenizer conditioning
    kind: Literal["joints", "keypoints"]
    sides: tuple[str, ...]
    native_units: str
    joints: tuple[JointSpec, ...]
    description: str = ""
    source: str = ""
    coupled: tuple[CoupledJoint, ...] = ()
    skeleton_spec: SkeletonSpec = field(default_factory=SkeletonSpec)
    urdf: UrdfSpec | None = None
    path: Path | None = None

    # -- structure ------------------------------------------------------------------------------
    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def num_native(self) -> int:
        return len(self.joints)

    def bind_columns(self, columns: list[str], prefix: str = "") -> tuple[list[str], str]:
        """A source's columns of this hand, in the spec's joint order, and how they were bound.

        "name": each column names a joint (after `prefix`; case, separators and a trailing `pos` ignored; the
        joint's name or one of its `aliases`), so the columns are put in the joints' order whatever the
        source's order; "position": no column names a joint (`joint_1`, ...), so they are taken in the given
        order as the joints' (the caller says so). A ValueError names the columns when only some name joints,
        two name one joint, or the count is not the hand's.
        """
        if len(columns) != self.num_native:
            raise ValueError(
                f"{len(columns)} columns {columns} for the {self.num_native} joints of {self.name} "
                f"{list(self.joint_names)}"
            )
        keys = {_name_key(n): j.name for j in self.joints for n in (j.name, *j.aliases)}
        named = {c: keys.get(_name_key(c[len(prefix) :] if c.startswith(prefix) else c)) for c in columns}
        if not any(named.values()):
            return list(columns), "position"
        unnamed = [c for c, j in named.items() if j is None]
        twice = sorted({j for j in named.values() if j and list(named.values()).count(j) > 1})
        if unnamed or twice:
            raise ValueError(
                f"columns {columns} only partly name the joints of {self.name} {list(self.joint_names)}: "
                + (f"{unnamed} name none" if unnamed else f"two columns name {twice}")
                + "; pass state_names listing the hand's columns in its joint order"
            )
        by_joint = {j: c for c, j in named.items()}
        return [by_joint[j] for j in self.joint_names], "name"

    @cached_property
    def active_joint_indices(self) -> np.ndarray:
        """(A,) native indices of the joints with a UDHM slot, in native order."""
        return np.array([i for i, j in enumerate(self.joints) if j.slot is not None], dtype=np.int64)

    @cached_property
    def _slot_idx(self) -> np.ndarray:
        """UDHM index of each joint with a slot on the first side (same order as ``active_joint_indices``).

        The set of slots is the same on every side (checked on load); only the assignment may differ.
        """
        return self._tables[self.sides[0]].slot_idx

    @property
    def num_active(self) -> int:
        return UDHM_DIM if self.kind == "keypoints" else len(self.active_joint_indices)

    @property
    def dropped_joints(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints if j.slot is None)

    @property
    def active_mask(self) -> np.ndarray:
        """(22,) bool: UDHM slots filled by a real DoF of this hand (semantic insertion)."""
        return self.mask("semantic")

    def mask(self, mapping: UdhmMapping = "semantic") -> np.ndarray:
        """(22,) bool active-DoF mask of ``mapping``."""
        self._check_mapping(mapping)
        mask = np.zeros(UDHM_DIM, dtype=bool)
        if self.kind == "keypoints":
            mask[:] = True
        elif mapping == "semantic":
            mask[self._slot_idx] = True
        else:
            mask[: self.num_active] = True
        return mask

    def slot_map(self, side: str | None = None) -> dict[str, str | None]:
        """Native joint name -> UDHM slot name (None = dropped) on ``side`` (default: the first side)."""
        side = side or self.sides[0]
        self.check_side(side)
        return {j.name: j.sides[side].slot for j in self.joints}

    def slot_indices(self, side: str = "right") -> np.ndarray:
        """(A,) UDHM index of each joint with a slot, in native order (``append_pad`` position k holds slot k)."""
        self._require_joints("slot_indices")
        return self._side_table(side).slot_idx.copy()

    def rest_rad(self, side: str = "right") -> np.ndarray:
        """(J,) joint angles (rad) at which each joint's UDHM slot reads 0."""
        return self._side_table(side).rest.copy()

    def limits_rad(self, side: str = "right") -> np.ndarray:
        """(J, 2) joint limits in radians for ``side``."""
        t = self._side_table(side)
        return np.stack([t.rad_lo, t.rad_hi], axis=-1)

    def conversion(self, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """(offset, scale), each (J,): the exact native -> radian map ``rad = offset + scale * raw``."""
        t = self._side_table(side)
        return t.offset.copy(), t.scale.copy()

    def raw_range(self, side: str = "right") -> np.ndarray:
        """(J, 2) native raw range for ``side``."""
        t = self._side_table(side)
        return np.stack([t.raw_lo, t.raw_hi], axis=-1)

    def udhm_limits_rad(self, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """(22,) lower and upper UDHM bounds reachable by this hand (0 on inactive slots)."""
        self._require_joints("udhm_limits_rad")
        t = self._side_table(side)
        a = self.active_joint_indices
        s, rest = t.sign[a], t.rest[a]
        lo, hi = np.zeros(UDHM_DIM), np.zeros(UDHM_DIM)
        ends = np.stack([s * (t.rad_lo[a] - rest), s * (t.rad_hi[a] - rest)])
        lo[t.slot_idx], hi[t.slot_idx] = ends.min(0), ends.max(0)
        return lo, hi

    # -- native <-> radians -----------------------------------------------------------------------
    def to_radians(self, raw: Any, side: str = "right", on_out_of_range: OutOfRange = "raise") -> Array:
        """Native raw values (..., J) -> native joint angles (..., J) in radians."""
        self._require_joints("to_radians")
        raw = self._check_native(raw)
        t = self._side_table(side)
        lo, hi = _table(t.raw_lo, raw), _table(t.raw_hi, raw)
        raw = self._handle_out_of_range(raw, lo, hi, t.raw_hi - t.raw_lo, on_out_of_range, "raw", side)
        return _table(t.offset, raw) + _table(t.scale, raw) * raw

    def from_radians(self, angles_rad: Any, side: str = "right", on_out_of_range: OutOfRange = "raise") -> Array:
        """Native joint angles (..., J) in radians -> native raw values (..., J).

        Joints without a radian meaning (scale 0, e.g. reserved channels) get their default raw value.
        """
        self._require_joints("from_radians")
        rad = self._check_native(angles_rad)
        t = self._side_table(side)
        lo, hi = _table(t.rad_lo, rad), _table(t.rad_hi, rad)
        rad = self._handle_out_of_range(rad, lo, hi, t.rad_hi - t.rad_lo, on_out_of_range, "radian", side)
        return self._rad_to_raw(rad, t)

    def _rad_to_raw(self, rad: Array, t: _SideTable) -> Array:
        invertible = t.scale != 0
        safe_scale = np.where(invertible, t.scale, 1.0)
        raw = (rad - _table(t.offset, rad)) / _table(safe_scale, rad)
        raw = _where(_table(invertible, rad) > 0, raw, _table(t.default_raw, rad) + 0 * raw)
        # Division round-off must not step outside the raw range.
        return _clip(raw, _table(t.raw_lo, raw), _table(t.raw_hi, raw))

    # -- native <-> UDHM ------------------------------------------------------------------------------
    def to_udhm(
        self,
        raw: Any,
        side: str = "right",
        mapping: UdhmMapping = "semantic",
        on_out_of_range: OutOfRange = "raise",
    ) -> Array:
        """Native values -> UDHM state (..., 22) in radians; inactive slots are 0."""
        self._check_mapping(mapping)
        if self.kind == "keypoints":
            return self._keypoints_to_udhm(raw, side)
        rad = self.to_radians(raw, side, on_out_of_range)  # (..., J)
        t = self._side_table(side)
        a = self.active_joint_indices
        values = (rad[..., a] - _table(t.rest[a], rad)) * _table(t.sign[a], rad)  # (..., A)
        out = _zeros((*rad.shape[:-1], UDHM_DIM), rad)  # (..., 22)
        target = t.slot_idx if mapping == "semantic" else np.arange(len(a))
        out[..., target] = values
        return out

    def from_udhm(self, state: Any, side: str = "right", mapping: UdhmMapping = "semantic") -> Array:
        """UDHM state (..., 22) in radians -> native values (..., J), clipped to the joint limits.

        Dropped joints get their ``default_raw``. For the human hand: keypoints (..., 21, 3) in metres
        by forward kinematics with this spec's skeleton.
        """
        self._check_mapping(mapping)
        state = _to_float(state)
        self._check_width(state, UDHM_DIM, "UDHM state", UDHM_JOINT_NAMES)
        self._check_nan(state, "UDHM state")
        if self.kind == "keypoints":
            return self._udhm_to_keypoints(state, side)
        t = self._side_table(side)
        a = self.active_joint_indices
        source = t.slot_idx if mapping == "semantic" else np.arange(len(a))
        rad = _zeros((*state.shape[:-1], self.num_native), state) + _table(t.offset + t.scale * t.default_raw, state)
        rad[..., a] = state[..., source] * _table(t.sign[a], state) + _table(t.rest[a], state)
        rad = _clip(rad, _table(t.rad_lo, rad), _table(t.rad_hi, rad))
        return self._rad_to_raw(rad, t)

    # -- kinematics ----------------------------------------------------------------------------------
    def skeleton(self):
        """This hand's ``udhm.Skeleton`` (``SkeletonSpec.skeleton``: measured, or the default human skeleton
        scaled with per-finger lengths if given)."""
        return self.skeleton_spec.skeleton()

    def _keypoints_to_udhm(self, keypoints_m: Any, side: str) -> Array:
        """MANO-21 keypoints (..., 21, 3) m -> UDHM (..., 22) rad by ``udhm.inverse_kinematics``."""
        from lerobot_unidextok.udhm import inverse_kinematics

        kp = _to_float(keypoints_m)
        self.check_side(side)
        if kp.ndim < 2 or tuple(kp.shape[-2:]) != (NUM_KEYPOINTS, 3):
            raise ValueError(
                f"hand {self.name!r}: expected MANO-21 keypoints in metres of shape (..., {NUM_KEYPOINTS}, 3), "
                f"got {tuple(kp.shape)}"
            )
        self._check_nan(kp, "keypoints_m")
        if isinstance(kp, torch.Tensor):
            angles_rad = inverse_kinematics(kp.detach().cpu().double().numpy(), side=side).angles_rad
            return torch.as_tensor(angles_rad, dtype=kp.dtype, device=kp.device)
        return inverse_kinematics(np.asarray(kp, dtype=np.float64), side=side).angles_rad

    def _udhm_to_keypoints(self, state: Array, side: str) -> Array:
        """UDHM (..., 22) rad -> MANO-21 keypoints (..., 21, 3) m in the canonical wrist frame (UDHM FK)."""
        from lerobot_unidextok.udhm.fk import forward_kinematics

        self.check_side(side)
        return forward_kinematics(state, self.skeleton(), side=side)

    # -- checks ----------------------------------------------------------------------------------------
    def _side_table(self, side: str) -> _SideTable:
        self.check_side(side)
        return self._tables[side]

    @cached_property
    def _tables(self) -> dict[str, _SideTable]:
        tables = {}
        for side in self.sides:
            js = [j.sides[side] for j in self.joints]

            def col(f, js=js) -> np.ndarray:
                return np.array([f(x) for x in js], dtype=np.float64)

            tables[side] = _SideTable(
                raw_lo=col(lambda x: x.raw_range[0]),
                raw_hi=col(lambda x: x.raw_range[1]),
                offset=col(lambda x: x.offset),
                scale=col(lambda x: x.scale),
                sign=col(lambda x: x.sign),
                rad_lo=col(lambda x: x.limits_rad[0]),
                rad_hi=col(lambda x: x.limits_rad[1]),
                default_raw=col(lambda x: x.default_raw),
                rest=col(lambda x: x.rest_rad),
                slot_idx=np.array([UDHM_INDEX[x.slot] for x in js if x.slot is not None], dtype=np.int64),
            )
        return tables

    def check_side(self, side: str) -> None:
        """ValueError naming the hand's sides unless ``side`` is one of them."""
        if side not in self.sides:
            raise ValueError(f"hand {self.name!r} has no side {side!r}; its sides are {list(self.sides)}")

    @staticmethod
    def _check_mapping(mapping: str) -> None:
        if mapping not in MAPPINGS:
            raise ValueError(f"unknown mapping {mapping!r}; use one of {list(MAPPINGS)}")

    def _require_joints(self, what: str) -> None:
        if self.kind != "joints":
            raise ValueError(
                f"hand {self.name!r} is given as keypoints (..., 21, 3) in metres and has no native joint "
                f"angles; {what} is not defined for it, use to_udhm / from_udhm"
            )

    def _check_width(self, x: Array, width: int, what: str, names: tuple[str, ...]) -> None:
        if x.ndim == 0 or x.shape[-1] != width:
            raise ValueError(
                f"hand {self.name!r}: {what} must have last dimension {width} ({', '.join(names)}), "
                f"got shape {tuple(x.shape)}"
            )

    def _check_nan(self, x: Array, what: str) -> None:
        if _isnan_any(x):
            raise ValueError(f"hand {self.name!r}: {what} contains NaN; drop or fill missing frames before converting")

    def _check_native(self, raw: Any) -> Array:
        raw = _to_float(raw)
        self._check_width(raw, self.num_native, f"native input ({self.native_units})", self.joint_names)
        self._check_nan(raw, "native input")
        return raw

    def _handle_out_of_range(
        self, x: Array, lo: Array, hi: Array, span: np.ndarray, mode: str, what: str, side: str
    ) -> Array:
        if mode not in OUT_OF_RANGE_MODES:
            raise ValueError(f"unknown on_out_of_range {mode!r}; use one of {list(OUT_OF_RANGE_MODES)}")
        tol = _table(_RANGE_TOL * np.maximum(span, 1.0), x)
        bad = (x < lo - tol) | (x > hi + tol)  # (..., J)
        bad_np = bad.cpu().numpy() if isinstance(bad, torch.Tensor) else np.asarray(bad)
        n_bad = int(bad_np.sum())
        if n_bad:
            if mode == "raise":
                cols = np.flatnonzero(bad_np.reshape(-1, bad_np.shape[-1]).any(0))
                detail = ", ".join(f"{self.joint_names[c]} in [{float(lo[c]):g}, {float(hi[c]):g}]" for c in cols)
                raise ValueError(
                    f"hand {self.name!r} ({side}): {n_bad} {what} value(s) out of range: {detail}. "
                    f"Pass on_out_of_range='clip' to clip them with a warning"
                )
            logger.warning(
                "hand %r (%s): clipped %d of %d %s values to the joint range", self.name, side, n_bad, bad_np.size, what
            )
        return _clip(x, lo, hi)
