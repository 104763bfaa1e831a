"""The canonical hand frame, fitted to the palm, and the left/right mirror.

Canonical (right-hand) frame, used by every UDHM module:
    origin  wrist (keypoint 0)
    x       palm normal pointing out of the palm (palmar side; curled fingers move toward +x)
    z       in the palm plane, perpendicular to the knuckle row (ring MCP -> index MCP), distal
    y       z cross x, toward the thumb side of a right hand
The palm plane is the least-squares plane through wrist, index, middle and ring MCP.

Why the knuckle row and not wrist -> middle MCP: z is the zero of every abduction, and trackers agree on
where the knuckles are but not on where the wrist is. MediaPipe Hands, MANO, WebXR / OpenXR and ARKit
(visionOS `HandSkeleton`, EgoDex) all have the MCP joints (MediaPipe `*_MCP`, MANO `*1`, WebXR
`*-phalanx-proximal`, ARKit `*Knuckle`), while the wrist point is a different thing in each: MediaPipe's
landmark 0 is annotated on images, MANO's root joint is regressed from the mesh, OpenXR's (which browsers
pass on as WebXR's, chromium `device/vr/openxr/openxr_hand_utils.cc`) sits "at the pivot point of the wrist which is location invariant when twisting hand without moving the
forearm" (KhronosGroup/OpenXR-Docs `ext_hand_tracking.adoc`), on the forearm's twist axis beside the ulna,
and ARKit names `wrist` and `forearmWrist` without positions. A wrist point 1 cm to one side turns
wrist -> middle MCP by ~6 deg, and every abduction with it. The index MCP sits on the 2nd metacarpal, fixed
to the carpus, the ring MCP on the 4th, which moves little (the mobile 5th is left out), so the row is rigid
in the palm and z is the same for every tracker whatever its wrist. Only the palm normal still uses the
wrist (the knuckles alone are nearly collinear): a wrist point in front of the palm tilts it and shifts
flexion, not abduction. dex-retargeting's MANO frame (OPERATOR2MANO, z = wrist -> middle MCP) differs from
this one by a turn of a few degrees about x.

Left hands: their palm frame uses the same rule for x and z, so y = z cross x points toward the little
finger. Mirroring y (MIRROR_Y) turns left-hand canonical coordinates into those of the mirror-image
right hand; UDHM angles and skeletons are always those of that right hand.
"""

from __future__ import annotations

import numpy as np

from lerobot_unidextok.constants import SIDES

MIRROR_Y = np.diag([1.0, -1.0, 1.0])  # left-hand canonical coords <-> mirrored right-hand coords
PALM_PLANE_INDICES = (0, 5, 9, 13)  # wrist, index/middle/ring MCP
BASE_INDICES = (1, 5, 9, 13, 17)  # thumb CMC and the four MCPs, one per finger
KNUCKLE_ROW_INDICES = (13, 5)  # ring MCP -> index MCP: z is perpendicular to it in the palm plane


def check_side(side: str) -> str:
    """`side` if it is "right" or "left", else ValueError."""
    if side not in SIDES:
        raise ValueError(f"unknown side {side!r}; use one of {SIDES}")
    return side


def palm_frame(keypoints_m: np.ndarray, side: str = "right") -> np.ndarray:
    """Rotation (..., 3, 3) whose columns are the canonical x, y, z axes in the input frame.

    Canonical coordinates of a point p: R^T (p - wrist). Degenerate palms (collinear points) give NaN.
    """
    check_side(side)
    kp = np.asarray(keypoints_m, dtype=np.float64)  # (..., 21, 3)
    wrist = kp[..., 0, :]
    pts = kp[..., PALM_PLANE_INDICES, :]  # (..., 4, 3)
    centred = pts - pts.mean(axis=-2, keepdims=True)
    cov = np.swapaxes(centred, -1, -2) @ centred  # (..., 3, 3)
    _, vecs = np.linalg.eigh(cov)
    normal = vecs[..., :, 0]  # smallest eigenvalue -> plane normal, (..., 3)
    # Palmar side: curled fingers of a right hand bend toward (index MCP - wrist) x (pinky MCP - wrist).
    palmar = np.cross(kp[..., 5, :] - wrist, kp[..., 17, :] - wrist)
    if side == "left":
        palmar = -palmar
    sign = np.where(np.sum(normal * palmar, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    x = normal * sign
    # The knuckle row points to the thumb side: +y of a right hand, -y of a left one (y = z cross x).
    row = kp[..., KNUCKLE_ROW_INDICES[1], :] - kp[..., KNUCKLE_ROW_INDICES[0], :]
    z = np.cross(x, -row if side == "left" else row)  # in the palm plane, perpendicular to the row, distal
    with np.errstate(invalid="ignore", divide="ignore"):
        z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def to_canonical(keypoints_m: np.ndarray, rotation: np.ndarray, side: str = "right") -> np.ndarray:
    """Keypoints (..., K, 3) in the (mirrored, for left) right-hand canonical frame."""
    kp = np.asarray(keypoints_m, dtype=np.float64)
    local = (kp - kp[..., :1, :]) @ rotation  # (..., K, 3) = R^T (p - wrist)
    if check_side(side) == "left":
        local = local * np.diag(MIRROR_Y)
    return local
