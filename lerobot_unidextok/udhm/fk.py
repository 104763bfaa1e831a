"""UDHM forward kinematics: 22 angles + skeleton (+ wrist pose) -> 21 MANO-order keypoints.

One code path for numpy and torch (torch in -> torch out, differentiable).

Kinematic model (right-hand canonical frame of `frames.py`: x palmar normal, y thumb side, z distal):
every finger is the same chain of elementary Rodrigues rotations with six slots
    [twist, abd1, flex1, abd2, flex2, flex3]
    R_base = Rot(u_f, twist)                  u_f = unit(wrist -> finger base); used by the pinky only
    R_1    = R_base Rot_x(-abd1) Rot_y(flex1) Rot_z(pron)  base joint: abduction about the palm normal, then
                                               flexion about the local lateral (y) axis;
                                               pron = fixed axial turn (thumb only)
    R_2    = R_1 Rot_x(-abd2) Rot_y(flex2)     second joint (abd2 used by the thumb MCP only)
    R_3    = R_2 Rot_y(flex3)
    p_1 = base + R_1 e_z L_1,  p_2 = p_1 + R_2 e_z L_2,  p_3 = p_2 + R_3 e_z L_3
Zero pose: all fingers (and the thumb) straight along +z in the palm plane: flat hand, fingers together.
Flexion > 0 moves toward +x (palm), abduction > 0 toward +y (thumb side).
Thumb: abd1 = CMC spread (in the palm plane, about the palm normal), flex1 = CMC flexion (out of the
palm plane, palmar abduction); vendor names such as "thumb pitch/yaw" do not tell which is which (see
AXIAL_PRONATION_RAD). R_1 is then turned by a fixed -90 deg about the CMC->MCP axis (AXIAL_PRONATION_RAD), so the
thumb plane follows the CMC->MCP direction: MCP/IP flexion moves the tip across the palm toward the
little finger, MCP abduction moves it toward the palm side. Pinky twist > 0 rotates the pinky frame about wrist -> pinky MCP so that
its flexion plane tilts toward the thumb (palm cupping); the MCP itself stays put.
Left hands: FK of the mirror-image right hand, mirrored in y (`side="left"`), then the wrist pose.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch

from lerobot_unidextok.constants import UDHM_DIM, UDHM_INDEX
from lerobot_unidextok.udhm.frames import MIRROR_Y, check_side
from lerobot_unidextok.udhm.skeleton import Skeleton

Array = np.ndarray | torch.Tensor

# ---------------------------------------------------------------------------------------------
# UDHM 22-vector -> per-finger chain slots [twist, abd1, flex1, abd2, flex2, flex3]; 22 = fixed zero.
# ---------------------------------------------------------------------------------------------
_Z = UDHM_DIM
_I = UDHM_INDEX
CHAIN_SLOTS = np.array(
    [
        [
            _Z,
            _I["thumb_cmc_spread"],
            _I["thumb_cmc_flex"],
            _I["thumb_mcp_abd"],
            _I["thumb_mcp_flex"],
            _I["thumb_ip_flex"],
        ],
        [_Z, _I["index_mcp_abd"], _I["index_mcp_flex"], _Z, _I["index_pip_flex"], _I["index_dip_flex"]],
        [_Z, _I["middle_mcp_abd"], _I["middle_mcp_flex"], _Z, _I["middle_pip_flex"], _I["middle_dip_flex"]],
        [_Z, _I["ring_mcp_abd"], _I["ring_mcp_flex"], _Z, _I["ring_pip_flex"], _I["ring_dip_flex"]],
        [
            _I["pinky_metacarpal_twist"],
            _I["pinky_mcp_abd"],
            _I["pinky_mcp_flex"],
            _Z,
            _I["pinky_pip_flex"],
            _I["pinky_dip_flex"],
        ],
    ]
)  # (5, 6)
CHAIN_ACTIVE = CHAIN_SLOTS < _Z  # (5, 6) which slots are real DoFs

# Fixed axial rotation (rad) of each finger's frame after its base joint, about the segment axis.
# Thumb: -90 deg, the anatomical convention that thumb MCP/IP flexion happens in a plane parallel
# to the palm (the tip moves across the palm toward the little finger) while abduction is
# perpendicular to it; the thumbnail sits at ~90 deg to the fingernails (Kapandji, "The Physiology
# of the Joints" vol. 1). Thumb CMC: flex = the thumb swinging out of the palm plane to the palm side
# (palmar abduction, rotation about the local lateral axis), spread = rotation inside the palm plane about
# the palm normal, > 0 away from the index. These are geometric definitions, not vendor joint names: on
# robot hands the joint whose axis runs along the fingers (called yaw, rotation, roll or bend by vendors)
# drives thumb_cmc_flex, and the joint about the palm normal drives thumb_cmc_spread (usually with sign -1,
# toward the index), whatever it is called; `python -m lerobot_unidextok.hands check` measures it per hand.
# The finger chains have none.
AXIAL_PRONATION_RAD = np.array([-np.pi / 2, 0.0, 0.0, 0.0, 0.0])  # (5,)
AXIAL_PRONATION_RAD.setflags(write=False)


# ---------------------------------------------------------------------------------------------
# backend helpers (numpy or torch, chosen by the input type)
# ---------------------------------------------------------------------------------------------
def _stack(xs: list[Array], axis: int) -> Array:
    return torch.stack(xs, dim=axis) if isinstance(xs[0], torch.Tensor) else np.stack(xs, axis=axis)


def _norm(x: Array) -> Array:
    return (
        torch.linalg.norm(x, dim=-1, keepdim=True)
        if isinstance(x, torch.Tensor)
        else np.linalg.norm(x, axis=-1, keepdims=True)
    )


def _mat3(rows: list[list[Array]]) -> Array:
    """(..., 3, 3) from 3x3 nested lists of (...) arrays."""
    if isinstance(rows[0][0], torch.Tensor):
        return _stack([_stack(r, -1) for r in rows], -2)
    shape = np.broadcast_shapes(*(np.shape(e) for r in rows for e in r))
    out = np.empty((*shape, 3, 3))
    for i, r in enumerate(rows):
        for j, e in enumerate(r):
            out[..., i, j] = e
    return out


def _rot_x_neg(a: Array) -> Array:
    """Rot_x(-a): rotates +z toward +y by a. (..., 3, 3)"""
    c, s = (
        np.cos(a) if isinstance(a, np.ndarray) else torch.cos(a),
        np.sin(a) if isinstance(a, np.ndarray) else torch.sin(a),
    )
    o, z = c * 0 + 1, c * 0
    return _mat3([[o, z, z], [z, c, s], [z, -s, c]])


def _rot_y(f: Array) -> Array:
    """Rot_y(f): rotates +z toward +x by f. (..., 3, 3)"""
    c, s = (
        np.cos(f) if isinstance(f, np.ndarray) else torch.cos(f),
        np.sin(f) if isinstance(f, np.ndarray) else torch.sin(f),
    )
    o, z = c * 0 + 1, c * 0
    return _mat3([[c, z, s], [z, o, z], [-s, z, c]])


def _rot_z(g: Array) -> Array:
    """Rot_z(g): axial rotation about the segment, rotates +x toward +y by g. (..., 3, 3)"""
    c, s = (
        np.cos(g) if isinstance(g, np.ndarray) else torch.cos(g),
        np.sin(g) if isinstance(g, np.ndarray) else torch.sin(g),
    )
    o, z = c * 0 + 1, c * 0
    return _mat3([[c, -s, z], [s, c, z], [z, z, o]])


def rodrigues(axis: Array, angle: Array) -> Array:
    """Rotation matrices (..., 3, 3) about unit `axis` (..., 3) by `angle` (...) rad."""
    c = np.cos(angle) if isinstance(angle, np.ndarray) else torch.cos(angle)
    s = np.sin(angle) if isinstance(angle, np.ndarray) else torch.sin(angle)
    kx, ky, kz = axis[..., 0], axis[..., 1], axis[..., 2]
    z = kx * 0
    k = _mat3([[z, -kz, ky], [kz, z, -kx], [-ky, kx, z]])  # (..., 3, 3) cross-product matrix
    eye = (np.eye(3) if isinstance(k, np.ndarray) else torch.eye(3, dtype=k.dtype, device=k.device)) + k * 0
    return eye + s[..., None, None] * k + (1 - c)[..., None, None] * (k @ k)


class Chain(NamedTuple):
    """Frames and points of the five finger chains; everything (..., 5, ...) in the canonical frame."""

    twist_axis: Array  # (..., 5, 3) unit wrist -> base
    r_base: Array  # (..., 5, 3, 3)
    r_abd1: Array  # R_base Rot_x(-abd1)
    r_1: Array
    r_abd2: Array  # R_1 Rot_x(-abd2)
    r_2: Array
    r_3: Array
    points: Array  # (..., 5, 4, 3) base, p1, p2, p3


def finger_chain(
    slots: Array, palm_offsets_m: Array, bone_lengths_m: Array, pronation_rad: Array | None = None
) -> Chain:
    """Run the five chains: slots (..., 5, 6) rad, offsets/bones (..., 5, 3) m (broadcastable).

    pronation_rad: (..., 5) fixed axial rotations; None = AXIAL_PRONATION_RAD (finger axis of size 5).
    """
    pronation_rad = _like(AXIAL_PRONATION_RAD, slots) if pronation_rad is None else pronation_rad
    twist, abd1, flex1, abd2, flex2, flex3 = (slots[..., i] for i in range(6))  # each (..., 5)
    axis = palm_offsets_m / _norm(palm_offsets_m)  # (..., 5, 3)
    r_base = rodrigues(axis, twist)  # (..., 5, 3, 3)
    r_abd1 = r_base @ _rot_x_neg(abd1)
    r_1 = r_abd1 @ _rot_y(flex1) @ _rot_z(pronation_rad + flex1 * 0)  # (..., 5, 3, 3)
    r_abd2 = r_1 @ _rot_x_neg(abd2)
    r_2 = r_abd2 @ _rot_y(flex2)
    r_3 = r_2 @ _rot_y(flex3)
    p_1 = palm_offsets_m + r_1[..., :, 2] * bone_lengths_m[..., 0:1]  # (..., 5, 3)
    p_2 = p_1 + r_2[..., :, 2] * bone_lengths_m[..., 1:2]
    p_3 = p_2 + r_3[..., :, 2] * bone_lengths_m[..., 2:3]
    p_0 = palm_offsets_m + p_1 * 0  # broadcast the base to the batch shape
    return Chain(axis, r_base, r_abd1, r_1, r_abd2, r_2, r_3, _stack([p_0, p_1, p_2, p_3], -2))


def angles_to_slots(angles_rad: Array) -> Array:
    """(..., 22) -> (..., 5, 6) chain slots (fixed slots are 0)."""
    if isinstance(angles_rad, torch.Tensor):
        padded = torch.cat([angles_rad, torch.zeros_like(angles_rad[..., :1])], dim=-1)
        return padded[..., torch.as_tensor(CHAIN_SLOTS, device=angles_rad.device)]
    padded = np.concatenate([angles_rad, np.zeros_like(angles_rad[..., :1])], axis=-1)
    return padded[..., CHAIN_SLOTS]


def slots_to_angles(slots: np.ndarray) -> np.ndarray:
    """(..., 5, 6) -> (..., 22) (inverse of `angles_to_slots` on active slots)."""
    out = np.empty((*slots.shape[:-2], UDHM_DIM), dtype=slots.dtype)
    out[..., CHAIN_SLOTS[CHAIN_ACTIVE]] = slots[..., CHAIN_ACTIVE]
    return out


def chain_to_keypoints(points: Array) -> Array:
    """(..., 5, 4, 3) chain points -> (..., 21, 3) MANO-order keypoints with the wrist at 0."""
    flat = points.reshape(*points.shape[:-3], 20, 3)
    if isinstance(flat, torch.Tensor):
        return torch.cat([torch.zeros_like(flat[..., :1, :]), flat], dim=-2)
    return np.concatenate([np.zeros_like(flat[..., :1, :]), flat], axis=-2)


# ---------------------------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------------------------
def forward_kinematics(
    angles_rad: Array,
    skeleton: Skeleton | None = None,
    wrist_pose: tuple[Array, Array] | None = None,
    side: str = "right",
) -> Array:
    """UDHM angles (..., 22) rad -> keypoints (..., 21, 3) m, MANO-21 order.

    skeleton: `Skeleton` (leading dims broadcast against the angles); None = `Skeleton.default()`.
    wrist_pose: (rotation (..., 3, 3), position_m (..., 3)) mapping the canonical hand frame into the
        output frame (p_out = R p + t); None = canonical frame (wrist at the origin).
    side: "left" mirrors the right-hand result in y before the wrist pose (see module docstring).
    numpy in -> numpy float64 out; torch in -> torch out (same dtype/device, differentiable).
    """
    check_side(side)
    is_torch = isinstance(angles_rad, torch.Tensor)
    if not is_torch:
        angles_rad = np.asarray(angles_rad, dtype=np.float64)
    if tuple(angles_rad.shape[-1:]) != (UDHM_DIM,):
        raise ValueError(f"angles_rad must have shape (..., {UDHM_DIM}), got {tuple(angles_rad.shape)}")
    skeleton = Skeleton.default() if skeleton is None else skeleton
    if not isinstance(skeleton, Skeleton):
        raise ValueError(f"skeleton must be a udhm.Skeleton or None, got {type(skeleton).__name__}")
    offsets, bones = _like(skeleton.palm_offsets_m, angles_rad), _like(skeleton.bone_lengths_m, angles_rad)
    chain = finger_chain(angles_to_slots(angles_rad), offsets, bones)
    kp = chain_to_keypoints(chain.points)  # (..., 21, 3)
    if side == "left":
        kp = kp * _like(np.diag(MIRROR_Y), angles_rad)
    if wrist_pose is not None:
        if not (isinstance(wrist_pose, tuple | list) and len(wrist_pose) == 2):
            raise ValueError("wrist_pose must be a (rotation (..., 3, 3), position_m (..., 3)) pair or None")
        rot, pos = _like(wrist_pose[0], angles_rad), _like(wrist_pose[1], angles_rad)
        if tuple(rot.shape[-2:]) != (3, 3) or tuple(pos.shape[-1:]) != (3,):
            raise ValueError(
                f"wrist_pose shapes must be (..., 3, 3) and (..., 3), got {tuple(rot.shape)} and {tuple(pos.shape)}"
            )
        kp = kp @ rot.swapaxes(-1, -2) + pos[..., None, :]
    return kp


def _like(x: Array, ref: Array) -> Array:
    """`x` as the backend / dtype / device of `ref`."""
    if isinstance(ref, torch.Tensor):
        if isinstance(x, np.ndarray) and not x.flags.writeable:
            x = x.copy()  # torch refuses read-only numpy buffers
        return torch.as_tensor(x, dtype=ref.dtype, device=ref.device)
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype=np.float64)
