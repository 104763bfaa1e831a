"""UDHM inverse kinematics: 21 keypoints (m) -> 22 angles, skeleton and wrist pose.

Steps, all vectorised over frames (no per-frame Python loop), in bounded-memory chunks:
1. wrist position = keypoint 0; wrist rotation = the palm frame of `frames.py` (or, with a given
   skeleton, the rotation that best aligns its palm to the observed palm, Kabsch about the wrist);
2. skeleton: palm offsets and bone lengths measured on each frame (default) or the one given;
3. analytic initialisation: each segment direction read off in its parent's frame;
4. Levenberg-Marquardt refinement with the analytic (geometric) Jacobian, batched over frames and
   fingers: the fingers are independent given the palm, so each step solves (N*5) 6x6 systems.
Joint limits are soft: a residual `limit_weight_m_per_rad * distance outside the limit` joins the
keypoint residuals (zero inside the limits, so in-limit poses are recovered exactly). At the
default 1 m/rad a 1 deg excess costs as much as 17 mm of keypoint error, so the limits act almost
hard (largest excess on the real 621-frame clip: 0.07 deg). Angles that still end up more than
1e-3 rad outside are reported in `IKResult.limit_violations`.
Left hands: solved as their mirror-image right hand; `IKResult.side` makes FK mirror back, so
`result.keypoints_m()` reproduces the input in its own frame.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from lerobot_unidextok.udhm.fk import (
    AXIAL_PRONATION_RAD,
    CHAIN_ACTIVE,
    CHAIN_SLOTS,
    chain_to_keypoints,
    finger_chain,
    forward_kinematics,
    rodrigues,
    slots_to_angles,
)
from lerobot_unidextok.udhm.frames import BASE_INDICES, MIRROR_Y, check_side, palm_frame, to_canonical
from lerobot_unidextok.udhm.joints import JOINT_LIMITS_RAD, limit_violations
from lerobot_unidextok.udhm.skeleton import MIN_BONE_LENGTH_M, Skeleton

logger = logging.getLogger(__name__)

# Limits per chain slot (5, 6, 2); fixed slots unbounded.
_LIMITS_PAD = np.concatenate([JOINT_LIMITS_RAD, [[-np.inf, np.inf]]], axis=0)
SLOT_LIMITS_RAD = _LIMITS_PAD[CHAIN_SLOTS]  # (5, 6, 2)


class KeypointFramesError(ValueError):
    """Frames the inverse kinematics cannot solve. `frames`: their flat indices in the input, so a caller that
    passed a subset of its frames can name its own frame numbers; `problem` and `hint` are the message's parts."""

    def __init__(self, problem: str, frames: np.ndarray, lead: tuple[int, ...] | None, hint: str = ""):
        self.problem, self.frames, self.hint = problem, np.asarray(frames), hint
        super().__init__(f"{problem} in frames {_frame_list(self.frames, lead)}{hint}")


@dataclass
class IKResult:
    """Output of `inverse_kinematics`; leading dims (...) are those of the input keypoints."""

    angles_rad: np.ndarray  # (..., 22) UDHM angles; NaN rows for frames masked missing
    skeleton: Skeleton  # (..., 5, 3) per frame, or the skeleton passed in
    wrist_rotation: np.ndarray  # (..., 3, 3) canonical hand frame -> input frame (proper rotation)
    wrist_position_m: np.ndarray  # (..., 3) = keypoint 0
    residual_m: np.ndarray  # (...,) mean Euclidean keypoint error of FK(IK(x)) vs x over the 21 keypoints
    limit_violations: np.ndarray  # (..., 22) bool, angle > 1e-3 rad outside JOINT_LIMITS_RAD
    side: str = "right"

    @property
    def wrist_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self.wrist_rotation, self.wrist_position_m

    def keypoints_m(self) -> np.ndarray:
        """FK of the solution in the input's frame, (..., 21, 3)."""
        return forward_kinematics(self.angles_rad, self.skeleton, self.wrist_pose, side=self.side)


def inverse_kinematics(
    keypoints_m: np.ndarray,
    side: str = "right",
    mask: np.ndarray | None = None,
    skeleton: Skeleton | None = None,
    iterations: int = 100,
    limit_weight_m_per_rad: float = 1.0,
    chunk_size: int = 4096,
    progress: bool | None = None,
) -> IKResult:
    """Fit UDHM to keypoints (..., 21, 3) m in MANO-21 order, in any frame (camera, world, wrist).

    side: "right" or "left" (left hands are mirrored into the right-hand model).
    mask: optional bool (...,), True = frame present, False = missing (NaN output rows). Without a
        mask, any NaN/inf keypoint raises ValueError naming the frames.
    skeleton: None = measured on each frame (exact palm, exact bone lengths); or a fixed `Skeleton`
        broadcastable to (..., 5, 3), e.g. `Skeleton.from_keypoints(kp, per_frame=False)`.
    iterations: maximum Levenberg-Marquardt iterations (stops earlier once converged).
    progress: show a tqdm bar over chunks (None = only for more than 4 chunks).
    chunk_size: frames per vectorised chunk; memory is bounded by it, not by the input length
        (4096 keeps the working set in cache: ~4x faster per frame than 65536 chunks on 2 cores).
    """
    check_side(side)
    kp = _checked_keypoints(keypoints_m)
    if iterations < 0 or chunk_size < 1:
        raise ValueError(f"iterations must be >= 0 and chunk_size >= 1, got {iterations} and {chunk_size}")
    lead = kp.shape[:-2]
    present = _present_frames(kp, mask)
    fixed = _broadcast_skeleton(skeleton, lead) if skeleton is not None else None
    fit = _solve_present(kp, present, side, fixed, iterations, limit_weight_m_per_rad, chunk_size, progress)
    angles = fit.angles_rad.reshape(*lead, 22)
    return IKResult(
        angles_rad=angles,
        skeleton=skeleton if fixed is not None else _measured_skeleton(fit, present),
        wrist_rotation=fit.rotation.reshape(*lead, 3, 3),
        wrist_position_m=np.where(present[..., None], kp[..., 0, :].astype(np.float64), np.nan),
        residual_m=fit.residual_m.reshape(lead),
        limit_violations=_logged_violations(angles),
        side=side,
    )


# ---------------------------------------------------------------------------------------------
# the steps of `inverse_kinematics`: checked input, the chunks, the measured skeleton
# ---------------------------------------------------------------------------------------------
class _Fit(NamedTuple):
    """Per-frame IK output over flat frames (N = frames): NaN rows where nothing was solved."""

    angles_rad: np.ndarray  # (N, 22)
    rotation: np.ndarray  # (N, 3, 3) canonical -> input frame
    palm_offsets_m: np.ndarray  # (N, 5, 3)
    bone_lengths_m: np.ndarray  # (N, 5, 3)
    residual_m: np.ndarray  # (N,)


def _checked_keypoints(keypoints_m: np.ndarray) -> np.ndarray:
    """Keypoints as a float array of shape (..., 21, 3); float32 stays float32 until its chunk is solved (memory)."""
    kp = np.asarray(keypoints_m)
    if not np.issubdtype(kp.dtype, np.floating):
        kp = kp.astype(np.float64)
    if kp.ndim < 2 or kp.shape[-2:] != (21, 3):
        raise ValueError(f"keypoints_m must have shape (..., 21, 3) in MANO-21 order, got {kp.shape}")
    return kp


def _present_frames(kp: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Bool (...) of the frames to solve: the mask (checked against the keypoints), else all (all finite)."""
    lead = kp.shape[:-2]
    finite = np.isfinite(kp).all(axis=(-1, -2))  # (...)
    if mask is None:
        if not finite.all():
            raise ValueError(
                f"keypoints_m has NaN/inf in frames {_frame_list(~finite)}; "
                "pass mask=<bool (...), False for missing frames> to get NaN rows for them"
            )
        return np.ones(lead, dtype=bool)
    present = np.asarray(mask)
    if present.dtype != bool or present.shape != lead:
        raise ValueError(
            f"mask must be a bool array of shape {lead} (True = frame present), got {present.dtype} {present.shape}"
        )
    if (present & ~finite).any():
        raise ValueError(f"keypoints_m has NaN/inf in frames {_frame_list(present & ~finite)} that mask marks present")
    return present


def _solve_present(kp, present, side, fixed, iterations, limit_weight, chunk_size, progress) -> _Fit:
    """Solve the present frames of kp (..., 21, 3) chunk by chunk, as flat frames (N, ...); missing ones stay NaN."""
    lead = kp.shape[:-2]
    flat = kp.reshape(-1, 21, 3)
    n = len(flat)
    fit = _Fit(np.full((n, 22), np.nan), np.full((n, 3, 3), np.nan), np.full((n, 5, 3), np.nan),
               np.full((n, 5, 3), np.nan), np.full(n, np.nan))  # fmt: skip
    idx_present = np.flatnonzero(present.reshape(n))
    starts = range(0, len(idx_present), chunk_size)
    if progress if progress is not None else len(starts) > 4:  # the bar's module is imported only when shown
        from lerobot_unidextok.utils.cli import progress_bar

        starts = progress_bar(starts, desc="UDHM IK", unit="chunk")
    for s in starts:
        idx = idx_present[s : s + chunk_size]
        sk = None if fixed is None else (fixed[0][idx], fixed[1][idx])
        chunk = _solve_chunk(flat[idx].astype(np.float64), side, sk, iterations, limit_weight, idx, lead)
        for whole, part in zip(fit, chunk, strict=True):
            whole[idx] = part
    return fit


def _measured_skeleton(fit: _Fit, present: np.ndarray) -> Skeleton:
    """The per-frame skeletons, shaped (..., 5, 3) like `present` (...); missing frames get the median of the
    present ones (the default skeleton when none is present), so the Skeleton stays valid."""
    offsets, bones = fit.palm_offsets_m, fit.bone_lengths_m
    flat_present = present.reshape(-1)
    if flat_present.any():
        fill = np.median(offsets[flat_present], 0), np.median(bones[flat_present], 0)
    else:
        fill = Skeleton.default().palm_offsets_m, Skeleton.default().bone_lengths_m
    offsets[~flat_present], bones[~flat_present] = fill
    return Skeleton(offsets.reshape(*present.shape, 5, 3), bones.reshape(*present.shape, 5, 3))


def _logged_violations(angles_rad: np.ndarray) -> np.ndarray:
    """`limit_violations` of the solution (NaN rows count as none), logged when there are any."""
    violations = limit_violations(np.nan_to_num(angles_rad, nan=0.0))
    if violations.any():
        logger.info(
            "UDHM IK: %d joint-limit violations in %d frames", int(violations.sum()), int(violations.any(-1).sum())
        )
    return violations


# ---------------------------------------------------------------------------------------------
# one chunk
# ---------------------------------------------------------------------------------------------
def _solve_chunk(kp, side, fixed, iterations, limit_weight, idx, lead) -> _Fit:
    """kp (N, 21, 3) finite -> angles (N, 22), rotations, offsets, bones, residual (N,).

    idx: the chunk's flat frame indices and lead the input's leading shape, for the error messages."""
    if fixed is None:
        rot = palm_frame(kp, side)  # (N, 3, 3)
        bad = ~np.isfinite(rot).all(axis=(-1, -2))
        if bad.any():
            raise KeypointFramesError(
                "degenerate palm (wrist and MCPs collinear or coincident)", idx[bad], lead,
                "; a frame without a hand must be NaN (or masked), not filled with a constant such as -1 or 0",
            )  # fmt: skip
        local = to_canonical(kp, rot, side)  # (N, 21, 3)
        offsets = local[:, BASE_INDICES, :]
        bones = np.linalg.norm(np.diff(local[:, 1:].reshape(-1, 5, 4, 3), axis=-2), axis=-1)  # (N, 5, 3)
        zero = (bones <= MIN_BONE_LENGTH_M).any(axis=(-1, -2))
        if zero.any():
            raise KeypointFramesError(
                "zero-length bones (two consecutive keypoints coincide)", idx[zero], lead,
                "; check the keypoint order/units or mask those frames",
            )  # fmt: skip
    else:
        offsets, bones = fixed
        rot = _kabsch_palm(kp, offsets, side)
        local = to_canonical(kp, rot, side)
    target = local[:, 1:].reshape(-1, 5, 4, 3)[:, :, 1:]  # (N, 5, 3, 3) p1..p3 per finger
    slots = _initial_slots(target, offsets, bones, limit_weight)
    slots = _levenberg_marquardt(slots, target, offsets, bones, iterations, limit_weight)
    chain = finger_chain(slots, offsets, bones)
    fit = chain_to_keypoints(chain.points)  # (N, 21, 3)
    resid = np.linalg.norm(fit - local, axis=-1).mean(-1)
    return _Fit(slots_to_angles(slots), rot, offsets, bones, resid)


def _kabsch_palm(kp: np.ndarray, offsets: np.ndarray, side: str) -> np.ndarray:
    """Rotation R (N, 3, 3) with R * model palm ~ observed palm (wrist fixed), model in side's frame."""
    model = offsets * np.diag(MIRROR_Y) if side == "left" else offsets  # (N, 5, 3)
    model = np.concatenate([model, _palm_anchor(model)], axis=1)
    obs = kp[:, BASE_INDICES, :] - kp[:, :1, :]
    obs = np.concatenate([obs, _palm_anchor(obs)], axis=1)
    h = np.swapaxes(model, 1, 2) @ obs  # (N, 3, 3)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, 1, 2) @ np.swapaxes(u, 1, 2)))
    fix = np.ones((len(kp), 3))
    fix[:, 2] = d
    return np.swapaxes(vt, 1, 2) @ (fix[:, :, None] * np.swapaxes(u, 1, 2))


def _palm_anchor(pts: np.ndarray) -> np.ndarray:
    """A point off the palm plane (index x pinky MCP) so the alignment is never ambiguous, (N, 1, 3)."""
    c = np.cross(pts[:, 1], pts[:, 4])
    return (c / np.linalg.norm(c, axis=-1, keepdims=True) * 0.05)[:, None, :]


# ---------------------------------------------------------------------------------------------
# analytic initialisation
# ---------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _abd_flex(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(abd, flex) with Rot_x(-abd) Rot_y(flex) e_z = d, |abd| <= pi/2 branch. d (..., 3) unit."""
    a = np.arctan2(d[..., 1], d[..., 2])
    a = np.where(a > np.pi / 2, a - np.pi, np.where(a < -np.pi / 2, a + np.pi, a))
    f = np.arctan2(d[..., 0], d[..., 1] * np.sin(a) + d[..., 2] * np.cos(a))
    return a, f


def _local(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R^T v for R (..., 3, 3), v (..., 3)."""
    return np.einsum("...ji,...j->...i", r, v)


def _initial_slots(target: np.ndarray, offsets: np.ndarray, bones: np.ndarray, limit_weight: float) -> np.ndarray:
    """Closed-form start (N, 5, 6): each segment direction read off in its parent's frame.

    The pinky twist is only identifiable from a flexed finger, so the pinky gets three starts (no
    twist, and the two twists that put the observed flexion plane's normal into the twisted palm
    plane); the one with the lowest LM cost (keypoint residual + limit penalty) wins.
    """
    slots = _best_branch(_slots_given_twist(target, offsets, np.zeros(target.shape[:2])), slice(None))
    p = slice(4, 5)  # the pinky, the only finger with a twist slot
    tgt, off, bon = target[:, p], offsets[:, p], bones[:, p]
    axis = _unit(off)  # (N, 1, 3) twist axis
    lateral = _unit(np.cross(tgt[:, :, 0] - off, tgt[:, :, 2] - tgt[:, :, 0]))
    # l . R(u, t) e_x = 0  <=>  (A - C) cos t + B sin t + C = 0
    a_c = lateral[..., 0]
    b_c = np.einsum("...i,...i->...", lateral, np.cross(axis, np.array([1.0, 0.0, 0.0])))
    c_c = axis[..., 0] * np.einsum("...i,...i->...", lateral, axis)
    amp, phase = np.hypot(a_c - c_c, b_c), np.arctan2(b_c, a_c - c_c)
    half = np.arccos(np.clip(np.divide(-c_c, amp, out=np.zeros_like(amp), where=amp > 1e-12), -1.0, 1.0))
    best, best_score = None, None
    for twist in (np.zeros_like(a_c), _wrap(phase + half), _wrap(phase - half)):
        cand = _best_branch(_slots_given_twist(tgt, off, twist, p), p)
        fit = finger_chain(cand, off, bon, AXIAL_PRONATION_RAD[p]).points[:, :, 1:]  # (N, 1, 3, 3)
        score = ((fit - tgt) ** 2).sum((-1, -2)) + (limit_weight * _limit_excess(cand, p)) ** 2 + 1e-12 * np.abs(twist)
        if best is None:
            best, best_score = cand, score
        else:
            take = score < best_score
            best, best_score = np.where(take[..., None], cand, best), np.where(take, score, best_score)
    slots[:, p] = best
    return slots


def _slots_given_twist(target, offsets, twist, fingers: slice = slice(None)) -> np.ndarray:
    """Analytic slots (N, k, 6) for the fingers `fingers` (k of them) given their twist (N, k)."""
    active, pron = CHAIN_ACTIVE[fingers], AXIAL_PRONATION_RAD[fingers]
    d1 = _unit(target[:, :, 0] - offsets)
    d2 = _unit(target[:, :, 1] - target[:, :, 0])
    d3 = _unit(target[:, :, 2] - target[:, :, 1])
    twist = np.where(active[:, 0], twist, 0.0)
    abd1, flex1 = _abd_flex(_local(rodrigues(_unit(offsets), twist), d1))
    slots = np.zeros((*target.shape[:2], 6))
    slots[..., 0], slots[..., 1], slots[..., 2] = twist, abd1, flex1
    ones = np.ones_like(offsets)
    d2l = _local(finger_chain(slots, offsets, ones, pron).r_1, d2)
    abd2, flex2 = _abd_flex(d2l)
    slots[..., 3] = np.where(active[:, 3], abd2, 0.0)
    slots[..., 4] = np.where(active[:, 3], flex2, np.arctan2(d2l[..., 0], d2l[..., 2]))
    d3l = _local(finger_chain(slots, offsets, ones, pron).r_2, d3)
    slots[..., 5] = np.arctan2(d3l[..., 0], d3l[..., 2])
    return slots


def _limit_excess(slots: np.ndarray, fingers: slice = slice(None)) -> np.ndarray:
    """Sum over slots of the distance outside the limits (rad), (N, k)."""
    lo, hi = SLOT_LIMITS_RAD[fingers, :, 0], SLOT_LIMITS_RAD[fingers, :, 1]
    return (np.clip(lo - slots, 0, None) + np.clip(slots - hi, 0, None)).sum(-1)


def _wrap(x: np.ndarray) -> np.ndarray:
    return (x + np.pi) % (2 * np.pi) - np.pi


def _best_branch(slots: np.ndarray, fingers: slice) -> np.ndarray:
    """Among the equivalent solutions, the one furthest inside the joint limits.

    Rot_x(-a) Rot_y(f) = Rot_x(-(a + pi)) Rot_y(pi - f) Rot_z(pi), and Rot_z(pi) flips the sign of every
    later abduction/flexion, so each 2-DoF joint has a twin giving identical keypoints.
    """
    cands = [slots]
    for j in (1, 3):  # the two 2-DoF joints (abd1, flex1) and (abd2, flex2)
        for c in list(cands):
            twin = c.copy()
            twin[..., j] = _wrap(c[..., j] + np.pi)
            twin[..., j + 1] = _wrap(np.pi - c[..., j + 1])
            twin[..., j + 2 :] = -c[..., j + 2 :]
            if j == 3:  # the twin of joint 2 exists only where abd2 is a real DoF (thumb MCP)
                twin = np.where(CHAIN_ACTIVE[fingers, 3, None], twin, c)
            cands.append(twin)
    best = np.argmin(np.stack([_limit_excess(c, fingers) for c in cands]), axis=0)  # (N, 5)
    return np.take_along_axis(np.stack(cands), best[None, ..., None], axis=0)[0]


# ---------------------------------------------------------------------------------------------
# batched Levenberg-Marquardt
# ---------------------------------------------------------------------------------------------
def _residuals(slots, target, offsets, bones, pron, active, lo, hi, limit_weight, with_jacobian: bool):
    """One block per (frame, finger), M blocks: slots (M, 6), target (M, 3, 3), offsets/bones (M, 3).

    Returns residual (M, 15) = 9 keypoint coordinates + 6 limit terms, and Jacobian (M, 15, 6).
    """
    chain = finger_chain(slots, offsets, bones, pron)
    pts = chain.points  # (M, 4, 3)
    below, above = slots < lo, slots > hi
    lim = limit_weight * (np.where(below, slots - lo, 0.0) + np.where(above, slots - hi, 0.0))
    res = np.concatenate([(pts[:, 1:] - target).reshape(-1, 9), lim], axis=-1)
    if not with_jacobian:
        return res, None
    # Geometric Jacobian: d p / d q_j = w_j x (p - o_j) for the points after joint j.
    p0, p1, p2 = pts[:, 0], pts[:, 1], pts[:, 2]
    axes_pivots = (
        (chain.twist_axis, np.zeros_like(p0), 0),
        (-chain.r_base[..., :, 0], p0, 0),
        (chain.r_abd1[..., :, 1], p0, 0),
        (-chain.r_1[..., :, 0], p1, 1),
        (chain.r_abd2[..., :, 1], p1, 1),
        (chain.r_2[..., :, 1], p2, 2),
    )
    jac = np.zeros((len(slots), 6, 15))  # built row-per-joint, transposed below
    for j, (w, o, first) in enumerate(axes_pivots):
        moved = np.cross(w[:, None, :], pts[:, 1 + first :] - o[:, None, :])  # (M, k, 3)
        jac[:, j, 3 * first : 9] = moved.reshape(len(slots), -1)
    jac[:, :, :9] *= active[..., None]
    jac[:, :, 9:] = np.eye(6) * (limit_weight * (below | above))[..., None]
    return res, np.swapaxes(jac, -1, -2)


def _levenberg_marquardt(slots, target, offsets, bones, iterations, limit_weight):
    """Refine (N, 5, 6) slots. Each (frame, finger) block has its own damping and stops on its own."""
    n = len(slots)
    shape = slots.shape
    q = slots.reshape(-1, 6).copy()
    tgt, off, bon = target.reshape(-1, 3, 3), offsets.reshape(-1, 3), bones.reshape(-1, 3)
    act = np.broadcast_to(CHAIN_ACTIVE, (n, 5, 6)).reshape(-1, 6)
    lo = np.broadcast_to(SLOT_LIMITS_RAD[..., 0], (n, 5, 6)).reshape(-1, 6)
    hi = np.broadcast_to(SLOT_LIMITS_RAD[..., 1], (n, 5, 6)).reshape(-1, 6)
    pron = np.broadcast_to(AXIAL_PRONATION_RAD, (n, 5)).reshape(-1)
    lam = np.full(len(q), 1e-3)
    res, jac = _residuals(q, tgt, off, bon, pron, act, lo, hi, limit_weight, True)
    cost = np.einsum("mi,mi->m", res, res)
    todo = np.arange(len(q))  # blocks still iterating
    for _ in range(iterations):
        if len(todo) == 0:
            break
        j, r, a_ = jac[todo], res[todo], act[todo]
        jtj = np.swapaxes(j, -1, -2) @ j  # (m, 6, 6)
        grad = np.einsum("mij,mi->mj", j, r) * a_
        diag = np.diagonal(jtj, axis1=-2, axis2=-1)
        lhs = jtj + (lam[todo, None] * (diag + 1e-9) + ~a_)[..., None] * np.eye(6)  # fixed slots: zero step
        step = -np.linalg.solve(lhs, grad[..., None])[..., 0]
        trial = q[todo] + step
        res_t, jac_t = _residuals(
            trial, tgt[todo], off[todo], bon[todo], pron[todo], a_, lo[todo], hi[todo], limit_weight, True
        )
        cost_t = np.einsum("mi,mi->m", res_t, res_t)
        before = cost[todo]
        ok = cost_t < before
        acc = todo[ok]
        q[acc], res[acc], jac[acc], cost[acc] = trial[ok], res_t[ok], jac_t[ok], cost_t[ok]
        lam[todo] = np.clip(np.where(ok, lam[todo] * 0.3, lam[todo] * 10.0), 1e-12, 1e10)
        small = np.abs(step).max(-1) < 1e-9  # rad; quadratic convergence leaves ~1e-15 after it
        # converged: tiny step, or relative cost decrease below 1e-10, or an exact fit (< 1e-12 m)
        flat = ok & (before - cost_t <= 1e-10 * before)
        done = small | flat | (cost_t < 1e-24) | (~ok & (before < 1e-24)) | (lam[todo] >= 1e10)
        todo = todo[~done]
    return _wrap(q).reshape(shape)


# ---------------------------------------------------------------------------------------------
# input helpers
# ---------------------------------------------------------------------------------------------
def _broadcast_skeleton(skeleton: Skeleton, lead: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(skeleton, Skeleton):
        raise ValueError(f"skeleton must be a udhm.Skeleton or None, got {type(skeleton).__name__}")
    try:
        o = np.broadcast_to(np.asarray(skeleton.palm_offsets_m, dtype=np.float64), (*lead, 5, 3))
        b = np.broadcast_to(np.asarray(skeleton.bone_lengths_m, dtype=np.float64), (*lead, 5, 3))
    except ValueError as err:
        raise ValueError(f"skeleton shape {skeleton.batch_shape} does not broadcast to the keypoints' {lead}") from err
    return o.reshape(-1, 5, 3), b.reshape(-1, 5, 3)


def _frame_list(bad: np.ndarray, lead: tuple[int, ...] | None = None, limit: int = 10) -> str:
    """Human-readable frame indices of a bool (...) array, or of flat indices given `lead`."""
    if lead is None:
        where = np.argwhere(bad)
    else:
        where = np.stack(np.unravel_index(np.asarray(bad), lead), axis=-1) if lead else np.zeros((len(bad), 0), int)
    if where.shape[-1] == 0:
        return "[the single input frame]"
    items = [str(tuple(int(i) for i in w)) if len(w) != 1 else str(int(w[0])) for w in where[:limit]]
    more = f" (+{len(where) - limit} more)" if len(where) > limit else ""
    return "[" + ", ".join(items) + "]" + more
