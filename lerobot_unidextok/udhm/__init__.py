"""UDHM: the 22-DoF Unified Dexterous Hand Model (joint names, limits, skeleton, batched FK and IK).

    from lerobot_unidextok import udhm
    res = udhm.inverse_kinematics(keypoints_m)              # (..., 21, 3) m -> IKResult
    kp = udhm.forward_kinematics(res.angles_rad, res.skeleton, (res.wrist_rotation, res.wrist_position_m))
Frames and sign conventions: `frames.py`, `fk.py`. Layer 1: numpy, scipy, torch and `constants` only.
"""

from lerobot_unidextok.constants import KEYPOINT_NAMES
from lerobot_unidextok.udhm.fk import forward_kinematics
from lerobot_unidextok.udhm.ik import IKResult, KeypointFramesError, inverse_kinematics
from lerobot_unidextok.udhm.joints import (
    JOINT_LIMITS_RAD,
    JOINT_NAMES,
    clip_to_limits,
    joint_index,
    limit_violations,
    sample_angles,
)
from lerobot_unidextok.udhm.skeleton import Skeleton

__all__ = [
    "KeypointFramesError",
    "JOINT_LIMITS_RAD",
    "JOINT_NAMES",
    "KEYPOINT_NAMES",
    "IKResult",
    "Skeleton",
    "clip_to_limits",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_index",
    "limit_violations",
    "sample_angles",
]
