"""Hand registry: every supported hand as a YAML spec, mapped into UDHM by semantic insertion and back.

from lerobot_unidextok import hands
spec = hands.get("linkerhand_l10")
state = spec.to_udhm(raw, side="right")      # (..., 10) SDK 0-255 -> (..., 22) rad
raw = spec.from_udhm(state, side="right")    # -> (..., 10), clipped to the joint limits
"""

from lerobot_unidextok.hands.loading import SpecError, load_spec, spec_from_dict
from lerobot_unidextok.hands.registry import SPECS_DIR, UnknownHandError, all_specs, describe, get, names
from lerobot_unidextok.hands.spec import CoupledJoint, HandSpec, JointSide, JointSpec, SkeletonSpec

__all__ = [
    "SPECS_DIR",
    "CoupledJoint",
    "HandSpec",
    "JointSide",
    "JointSpec",
    "SkeletonSpec",
    "SpecError",
    "UnknownHandError",
    "all_specs",
    "describe",
    "get",
    "load_spec",
    "names",
    "spec_from_dict",
]
