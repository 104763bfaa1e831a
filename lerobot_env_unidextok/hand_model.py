"""A hand in the simulator: its MuJoCo model, where it sits on the wrist, and how its native joints drive it.

The types (`SimHand`, `Drive`), the postures every hand shares, and the hands on a model file from elsewhere: one
YAML per embodiment in `hand_models/<embodiment>.yaml` (the Inspire's robosuite model, the Shadow's
gymnasium-robotics model); every hand spec of that embodiment runs on it (`inspire_rh56_unitree` and
`inspire_rh56` share the Inspire's). A hand built from its URDF is `urdf_hand.py`'s; which of the two a hand runs
on is `sim_hands.py`'s choice (a model file wins). A native joint
(the spec's, in the spec's radians) drives one or more MJCF joints, each through a linear map written as two
points (`native_rad: [a, b]` -> `joint_rad: [qa, qb]`); one of them, `measures: true`, is read back as the
native state. That is how coupled joints are written: the Inspire's 6 native DoF drive its 12 MJCF joints, the
Shadow's distal joints follow their middle joints through the model's own tendons (no actuator: the native
command of a distal joint is not used, as on the real hand).

Nothing here imports MuJoCo: the scene (`scene.py`) builds the model, this module is the data and the maps.
"""

from __future__ import annotations

import functools
import importlib.metadata
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lerobot_env_unidextok.columns import FINGERS
from lerobot_env_unidextok.errors import SimHandError
from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_JOINT_NAMES

MODELS_DIR = Path(__file__).parent / "hand_models"


@dataclass(frozen=True)
class Drive:
    """One MJCF joint driven by one native joint: joint_rad = qa + (native_rad - a) * (qb - qa) / (b - a)."""

    joint: str
    native: str
    native_rad: tuple[float, float]
    joint_rad: tuple[float, float]
    actuator: str | None = None  # None: the model couples this joint to another (tendon), no command of its own
    measures: bool = False  # the native joint's state is read from this joint

    def to_joint(self, native_rad: np.ndarray) -> np.ndarray:
        (a, b), (qa, qb) = self.native_rad, self.joint_rad
        return qa + (native_rad - a) * (qb - qa) / (b - a)

    def to_native(self, joint_rad: np.ndarray) -> np.ndarray:
        (a, b), (qa, qb) = self.native_rad, self.joint_rad
        return a + (joint_rad - qa) * (b - a) / (qb - qa)


@dataclass(frozen=True)
class SimHand:
    """One embodiment's simulation model (from its YAML) bound to one hand spec (native units)."""

    spec: hands.HandSpec
    side: str
    model_xml: str  # a complete MJCF document with absolute file paths
    root: str  # the hand's root body
    mount_pos_m: tuple[float, float, float]  # root origin in the wrist frame
    mount_matrix: tuple[tuple[float, ...], ...]  # root axes in the wrist frame (columns: root x, y, z)
    drives: tuple[Drive, ...]
    held: dict[str, float]  # actuators of the model held at a fixed target (the Shadow's own wrist)
    fingertips: dict[str, tuple[str, tuple[float, float, float]]]  # finger -> (body, point in it, m)
    finger_bodies: dict[str, tuple[str, ...]]  # finger -> bodies whose geoms belong to it
    open_raw: np.ndarray  # (J,) native open pose
    postures: dict[str, dict[str, float]]  # name -> UDHM slot overrides (rad) of the open pose
    grasp: dict[str, dict[str, Any]]  # "power"/"pinch" -> {"preshape", "posture": names, "offset_m": wrist offset}
    source: str

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def native_names(self) -> tuple[str, ...]:
        return self.spec.joint_names

    @property
    def fingers(self) -> tuple[str, ...]:
        return tuple(f for f in FINGERS if f in self.fingertips)

    @functools.cached_property
    def measuring(self) -> tuple[Drive | None, ...]:
        """The drive each native joint is read from, in native order (None: a native joint the model lacks, e.g.
        a reserved channel; it reads back its open value)."""
        by_native = {d.native: d for d in self.drives if d.measures}
        return tuple(by_native.get(n) for n in self.native_names)

    def command(self, native_raw: np.ndarray) -> dict[str, float]:
        """Native command (J,) -> target angle (rad) per actuator."""
        rad = np.asarray(self.spec.to_radians(np.asarray(native_raw, dtype=np.float64), self.side, "clip"))
        index = {n: i for i, n in enumerate(self.native_names)}
        targets = {d.actuator: float(d.to_joint(rad[index[d.native]])) for d in self.drives if d.actuator}
        return {**targets, **self.held}

    def native_state(self, joint_rad: dict[str, float]) -> np.ndarray:
        """Measured joint angles (rad, by MJCF joint name) -> native state (J,), clipped to the native range."""
        rad = np.asarray(self.spec.to_radians(self.open_raw, self.side, "clip"), dtype=np.float64).copy()
        for i, d in enumerate(self.measuring):
            if d is not None:
                rad[i] = d.to_native(joint_rad[d.joint])
        lo, hi = self.spec.limits_rad(self.side).T
        return np.asarray(self.spec.from_radians(np.clip(rad, lo, hi), self.side, "clip"), dtype=np.float64)

    def posture(self, name: str) -> np.ndarray:
        """A named posture in native units: the open pose with the posture's UDHM slots set (spec.from_udhm)."""
        return self.open_raw.copy() if name == "open" else self.with_slots(self.postures[name])

    def with_slots(self, overrides_rad: dict[str, float]) -> np.ndarray:
        """(J,) native command of the open pose with the UDHM slots `overrides_rad` set (slot name -> rad)."""
        udhm = np.asarray(self.spec.to_udhm(self.open_raw, self.side), dtype=np.float64)
        for slot, value in overrides_rad.items():
            udhm[UDHM_JOINT_NAMES.index(slot)] = value
        raw = np.asarray(self.spec.from_udhm(udhm, self.side), dtype=np.float64)
        dropped = ~np.isin(np.arange(len(raw)), self.spec.active_joint_indices)
        raw[dropped] = self.open_raw[dropped]  # joints without a UDHM slot keep the open pose
        return raw


# ---------------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------------
def model_names() -> tuple[str, ...]:
    """Embodiments with a model file here (a model from another source than the builder)."""
    return tuple(sorted(p.stem for p in MODELS_DIR.glob("*.yaml")))


def from_model_file(spec: hands.HandSpec) -> SimHand:
    """The simulated hand of `spec` on its embodiment's model file (`model_names()`)."""
    hand, path = spec.name, MODELS_DIR / f"{spec.embodiment}.yaml"
    data = yaml.safe_load(path.read_text())
    side = data["side"]
    model = data["model"]
    drives = tuple(_drive(d, spec, side) for d in data["drives"])
    missing = set(spec.joint_names) - {d.native for d in drives if d.measures}
    if missing:
        raise ValueError(f"{path}: native joints {sorted(missing)} of {hand} have no measuring drive")
    open_raw = np.asarray(spec.from_radians(np.asarray(data["open_rad"], dtype=np.float64), side, "clip"))
    return SimHand(
        spec=spec,
        side=side,
        model_xml=_model_xml(model),
        root=model["root"],
        mount_pos_m=tuple(data["mount"]["pos"]),
        mount_matrix=tuple(tuple(r) for r in data["mount"]["matrix"]),
        drives=drives,
        held={k: float(v) for k, v in data.get("held", {}).items()},
        fingertips={f: (b, tuple(p)) for f, (b, p) in data["fingertips"].items()},
        finger_bodies={f: tuple(b) for f, b in data["finger_bodies"].items()},
        open_raw=open_raw,
        postures={**POSTURES, **{k: dict(v) for k, v in data.get("postures", {}).items()}},
        grasp={k: dict(v) for k, v in data["grasp"].items()},
        source=data["source"],
    )


def _press(udhm_finger: str) -> dict[str, float]:
    return {f"{udhm_finger}_mcp_flex": 0.9, f"{udhm_finger}_pip_flex": 0.6, f"{udhm_finger}_dip_flex": 0.4}


def _flex(mcp: float, pip: float, dip: float, fingers=("index", "middle", "ring", "pinky")) -> dict[str, float]:
    return {f"{f}_{j}_flex": v for f in fingers for j, v in (("mcp", mcp), ("pip", pip), ("dip", dip))}


# The postures, as UDHM slot angles (rad) set over the hand's open pose and turned into each hand's native command
# by its spec (`SimHand.posture`): written once for every hand; a hand fills the slots it has. A model file may
# override one, saying why. thumb_cmc_flex swings the thumb in front of the palm (opposition). A hand built from its
# URDF then fits its thumb's slots of `pinch` and `power` and its pre-shapes by forward kinematics
# (`urdf_hand.fit_postures`): a pinch is a tripod, the thumb onto the index's and middle's tips.
POSTURES: dict[str, dict[str, float]] = {
    "preshape": {"thumb_cmc_flex": 1.2},  # the thumb opposed, fingers open: before a power grasp
    "power": {**_flex(1.3, 1.1, 0.7), "thumb_cmc_flex": 1.2, "thumb_mcp_flex": 0.6, "thumb_ip_flex": 0.6},
    "pinch_pre": {**_flex(0.4, 0.3, 0.2, ("index", "middle")), "thumb_cmc_flex": 1.0},
    "pinch": {**_flex(1.0, 0.8, 0.5, ("index", "middle")), "thumb_cmc_flex": 1.2, "thumb_mcp_flex": 0.5,
              "thumb_ip_flex": 0.5},
    **{f"press_{f}": _press(u) for f, u in (("index", "index"), ("middle", "middle"), ("ring", "ring"),
                                             ("little", "pinky"))},
}  # fmt: skip


def _drive(d: dict[str, Any], spec: hands.HandSpec, side: str) -> Drive:
    if d["native"] not in spec.joint_names:
        raise ValueError(f"drive of {d['joint']}: {d['native']!r} is not a native joint of {spec.name}")
    j = spec.joint_names.index(d["native"])
    limits = tuple(float(x) for x in spec.limits_rad(side)[j])
    native_rad = tuple(d.get("native_rad", limits))
    return Drive(joint=d["joint"], native=d["native"], native_rad=native_rad,
                 joint_rad=tuple(d.get("joint_rad", native_rad)), actuator=d.get("actuator", f"{d['joint']}_drive"),
                 measures=bool(d.get("measures", False)))  # fmt: skip


def _model_xml(model: dict[str, Any]) -> str:
    """A complete MJCF document for the hand's model, file paths made absolute."""
    if "file" in model:
        return (MODELS_DIR / model["file"]).resolve().read_text()
    dist = importlib.metadata.distribution(model["package"])  # reading its files does not import it
    base = Path(dist.locate_file(model["folder"]))
    meshes = Path(dist.locate_file(model["meshdir"]))
    return model["template"].format(folder=base, meshdir=meshes)


__all__ = ["Drive", "FINGERS", "POSTURES", "SimHand", "SimHandError", "from_model_file", "model_names"]
