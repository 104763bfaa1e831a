"""Hand registry: every supported hand as a YAML spec, mapped into UDHM by semantic insertion and back.

from lerobot_unidextok import hands
spec = hands.get("linkerhand_l10")
state = spec.to_udhm(raw, side="right")      # (..., 10) SDK 0-255 -> (..., 22) rad
raw = spec.from_udhm(state, side="right")    # -> (..., 10), clipped to the joint limits
hands.check_units(spec, episode_raw, side="right")  # NativeUnitsError with the likely fix for wrong units
Kinematic check against a URDF: `hands.check.check_spec` / `python -m lerobot_unidextok.hands check`.
"""

from lerobot_unidextok.hands.loading import SpecError, load_spec, spec_from_dict
from lerobot_unidextok.hands.registry import SPECS_DIR, UnknownHandError, all_specs, describe, get, names
from lerobot_unidextok.hands.spec import (
    CoupledJoint,
    HandSpec,
    JointSide,
    JointSpec,
    SkeletonSpec,
    UrdfKeypoint,
    UrdfSpec,
)
from lerobot_unidextok.hands.units import NativeUnitsError, check_units

__all__ = [
    "SPECS_DIR",
    "CoupledJoint",
    "HandSpec",
    "JointSide",
    "JointSpec",
    "NativeUnitsError",
    "SkeletonSpec",
    "SpecError",
    "UnknownHandError",
    "UrdfKeypoint",
    "UrdfSpec",
    "all_specs",
    "check_units",
    "describe",
    "get",
    "load_spec",
    "names",
    "spec_from_dict",
]
