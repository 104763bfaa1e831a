"""Bridge from hand specs to UDHM kinematics: per-hand skeletons, human keypoints <-> UDHM."""

from __future__ import annotations

import numpy as np
import torch

from lerobot_unidextok.constants import FINGERS
from lerobot_unidextok.hands.spec import Array, SkeletonSpec


def skeleton_for(spec: SkeletonSpec):
    """``udhm.Skeleton``: the measured one (palm offsets + bone lengths, canonicalised) when the spec has it,
    else the default human skeleton times ``spec.scale`` with per-finger bone lengths overriding."""
    from lerobot_unidextok.udhm.skeleton import Skeleton

    if spec.measured:
        offsets = np.array([spec.palm_offsets_m[f] for f in FINGERS], dtype=np.float64)  # (5, 3)
        bones = np.array([spec.bone_lengths_m[f] for f in FINGERS], dtype=np.float64)  # (5, 3)
        return Skeleton(offsets, bones).canonicalized()
    skel = Skeleton.default().scaled(spec.scale)
    if not spec.bone_lengths_m:
        return skel
    bones = np.array(skel.bone_lengths_m, dtype=np.float64)  # (5, 3)
    for finger, lengths in spec.bone_lengths_m.items():
        bones[FINGERS.index(finger)] = lengths
    return Skeleton(np.array(skel.palm_offsets_m), bones)


def keypoints_to_udhm(keypoints_m: Array, side: str) -> Array:
    """MANO-21 keypoints (..., 21, 3) m -> UDHM (..., 22) rad by ``udhm.inverse_kinematics``."""
    from lerobot_unidextok.udhm import inverse_kinematics

    if isinstance(keypoints_m, torch.Tensor):
        angles = inverse_kinematics(keypoints_m.detach().cpu().double().numpy(), side=side)
        angles = getattr(angles, "angles_rad", angles)
        return torch.as_tensor(np.asarray(angles), dtype=keypoints_m.dtype, device=keypoints_m.device)
    angles = inverse_kinematics(np.asarray(keypoints_m, dtype=np.float64), side=side)
    return np.asarray(getattr(angles, "angles_rad", angles))


def udhm_to_keypoints(state: Array, skeleton, side: str) -> Array:
    """UDHM (..., 22) rad -> MANO-21 keypoints (..., 21, 3) m in the canonical wrist frame."""
    from lerobot_unidextok.udhm.fk import forward_kinematics

    return forward_kinematics(state, skeleton, side=side)
