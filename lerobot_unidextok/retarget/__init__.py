"""Retargeting: human MANO-21 keypoint motion -> joint trajectories of a registered robot hand.

from lerobot_unidextok.retarget import HandRetargeter
res = HandRetargeter("linkerhand_l10", urdf="<folder with linkerhand_l10_right.urdf>").retarget(keypoints_m)
res.native      # (T, 10) SDK 0-255, as the hand spec defines the native units
res.udhm_rad    # (T, 22) hands.get("linkerhand_l10").to_udhm(res.native, "right")

Layer 4: imports `hands`, `udhm` and (lazily) dex-retargeting, the `retarget` extra. What it needs of a hand
(URDF file, palm and target links, joint map) is read from the hand's own spec (`hands/specs/<hand>.yaml`,
`retarget/spec.py`); users supply the URDF files.
"""

from lerobot_unidextok.hands.urdf import URDFError
from lerobot_unidextok.retarget.retargeter import (
    HandRetargeter,
    RetargetConfig,
    RetargetResult,
    palm_frame,
    require_dex_retargeting,
    retarget_keypoints,
)
from lerobot_unidextok.retarget.spec import SideRetargetSpec, get_retarget_spec, retarget_hands

__all__ = [
    "HandRetargeter",
    "RetargetConfig",
    "RetargetResult",
    "SideRetargetSpec",
    "URDFError",
    "get_retarget_spec",
    "palm_frame",
    "require_dex_retargeting",
    "retarget_hands",
    "retarget_keypoints",
]
