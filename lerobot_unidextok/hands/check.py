"""Kinematic check of a hand spec against the robot's URDF: which UDHM slot each native joint moves, which way.

For one side: pose the URDF (native joint angles -> URDF joints), read the 21 keypoints through the
spec's keypoint map, run this project's ``udhm.inverse_kinematics`` (geometry only: no joint-limit
penalty), and move one native joint at a time by a small step. The central difference of the 22 UDHM
angles says which slot the joint drives and with which sign. Poses: ``rest`` (every joint at the angle
closest to 0 inside its range), ``mid`` (middle of every range) and seeded random poses inside the ranges.

Verdict per mapped joint (table columns of ``CheckReport.table()``). The *primary* pose is ``rest``, or
the first later pose where the joint moves the hand at all (a finger's axial twist does nothing to a
straight finger):
- ``ok``: at the primary pose the spec's slot moves with at least half the strength of the strongest
  slot and with the spec's sign; over all poses the median derivative still moves the spec's slot with
  the spec's sign (at least a quarter of its strongest slot: robot thumbs are not UDHM thumbs, so away
  from rest their MCP motion spreads over UDHM's MCP flexion and abduction); and at rest the spec's UDHM
  value is within ``rest_tol_deg`` of what IK reads from the robot (the rest offset is right);
- ``wrong sign`` / ``wrong slot`` (with the slot and sign found at the primary pose) / ``pose-dependent``
  (right at the primary pose, not on the median) / ``rest off`` (with the ``rest_rad`` that would make
  the rest value agree) / ``no effect`` (the joint moves no keypoint) / ``no URDF joint``.
Dropped joints (``slot: null``) are listed with what they drive, for information.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import UDHM_INDEX, UDHM_JOINT_NAMES
from lerobot_unidextok.hands.spec import HandSpec
from lerobot_unidextok.hands.urdf import UrdfHand

STEP_RAD = 0.02  # finite-difference step of the native joint
REST_INSET = 0.25  # the rest pose keeps this fraction of each range from the range ends
MIN_GAIN = 0.1  # rad of UDHM per rad of joint below which a joint "does not move the hand" at a pose
MAX_GAIN = 3.0  # a larger reading means IK switched between solutions inside the step (e.g. the pinky twist of a near-straight finger): ignored
SHARE = 0.5  # at the primary pose the spec's slot moves at least this fraction of the strongest slot
MEDIAN_SHARE = 0.25  # and over all poses (median derivative) still this fraction, with the spec's sign
REST_TOL_DEG = 15.0  # spec UDHM value vs IK value at the rest pose


@dataclass
class PoseReading:
    """What one native joint does at one pose."""

    pose: str
    slot: str | None  # strongest slot (None = no effect)
    sign: int
    gain: float  # |d udhm[slot] / d rad|
    spec_share: float  # signed d udhm[spec slot] / d rad divided by gain, times the spec sign (1 = perfect)


@dataclass
class JointVerdict:
    joint: str
    urdf_joint: str | None
    spec_slot: str | None
    spec_sign: int
    verdict: str
    found_slot: str | None = None
    found_sign: int = 0
    gain: float = 0.0
    rest_error_deg: float = float("nan")  # spec - IK at the rest pose, on the spec slot
    suggested_rest_rad: float = float("nan")
    mode: str = "own"  # "own": followers held; "linkage": the joint's URDF mimic followers move with it
    primary_pose: str = ""
    median_share: float = float("nan")
    readings: list[PoseReading] = field(default_factory=list)

    @property
    def mapped(self) -> bool:
        return self.spec_slot is not None

    @property
    def agrees(self) -> bool:
        return self.verdict == "ok"


@dataclass
class CheckReport:
    hand: str
    side: str
    urdf: str
    poses: tuple[str, ...]
    joints: list[JointVerdict]

    @property
    def mapped(self) -> list[JointVerdict]:
        return [j for j in self.joints if j.mapped]

    @property
    def disagreements(self) -> list[JointVerdict]:
        return [j for j in self.mapped if not j.agrees]

    def summary(self) -> str:
        n, bad = len(self.mapped), len(self.disagreements)
        return f"{self.hand} ({self.side}, {self.urdf}): {n - bad}/{n} mapped joints agree with the URDF kinematics"

    def table(self) -> str:
        """Per-joint verdict table (one row per native joint)."""
        rows = [
            (
                "native joint",
                "URDF joint",
                "spec slot",
                "sign",
                "found (strongest)",
                "gain",
                "read",
                "rest err",
                "verdict",
            )
        ]
        for j in self.joints:
            found = f"{j.found_slot} {'+' if j.found_sign > 0 else '-'}" if j.found_slot else "-"
            verdict = j.verdict
            if j.verdict == "rest off":
                verdict += f" (rest_rad {j.suggested_rest_rad:+.3f})"
            elif j.verdict in ("wrong slot", "wrong sign"):
                verdict += f" (use {j.found_slot}, sign {j.found_sign:+d})"
            rows.append(
                (
                    j.joint,
                    j.urdf_joint or "-",
                    j.spec_slot or "- (dropped)",
                    f"{j.spec_sign:+d}" if j.mapped else "",
                    found,
                    f"{j.gain:.2f}" if j.found_slot else "",
                    f"{j.mode}@{j.primary_pose}" if j.found_slot else "",
                    "" if np.isnan(j.rest_error_deg) else f"{j.rest_error_deg:+.0f} deg",
                    verdict,
                )
            )
        widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
        lines = ["  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip() for r in rows]
        lines.insert(1, "  ".join("-" * w for w in widths))
        return "\n".join([self.summary(), f"poses: {', '.join(self.poses)}", *lines])


# ---------------------------------------------------------------------------------------------
# poses
# ---------------------------------------------------------------------------------------------
def check_poses(spec: HandSpec, side: str, num_random: int = 12, seed: int = 0) -> dict[str, np.ndarray]:
    """Native joint angles (J,) rad per named pose: rest, mid and seeded random poses inside the ranges.

    ``rest`` is every joint at the angle closest to 0, kept ``REST_INSET`` of its range away from the
    range ends: a finger a little flexed instead of dead straight, where IK cannot tell a finger's
    flexion plane (the pinky twist) from its abduction.
    """
    lim = spec.limits_rad(side)  # (J, 2)
    span = lim[:, 1] - lim[:, 0]
    rng = np.random.default_rng(seed)
    rest = np.clip(0.0, lim[:, 0] + REST_INSET * span, lim[:, 1] - REST_INSET * span)
    poses = {"rest": rest, "mid": lim.mean(axis=1)}
    for i in range(num_random):
        poses[f"random{i}"] = rng.uniform(lim[:, 0], lim[:, 1])
    return poses


# ---------------------------------------------------------------------------------------------
# the check
# ---------------------------------------------------------------------------------------------
def urdf_joint_names(spec: HandSpec, side: str, hand: UrdfHand) -> list[str | None]:
    """Per native joint: its URDF joint (explicit ``urdf_joint``, else the same name if the URDF has it)."""
    names = []
    for j in spec.joints:
        explicit = j.sides[side].urdf_joint
        if explicit is not None:
            if explicit not in hand.joint_names:
                raise ValueError(
                    f"hand {spec.name!r} ({side}): urdf_joint {explicit!r} of {j.name!r} is not an actuated joint "
                    f"of {hand.path.name}; actuated joints: {', '.join(hand.joint_names)}"
                )
            names.append(explicit)
        else:
            names.append(j.name if j.name in hand.joint_names else None)
    return names


def urdf_cfg(urdf_names: list[str | None], rad: np.ndarray) -> dict[str, float]:
    """Native joint angles (J,) -> {URDF joint: rad} for the joints that have a URDF joint."""
    return {u: float(q) for u, q in zip(urdf_names, rad, strict=True) if u is not None}


def udhm_from_keypoints(keypoints_m: np.ndarray, side: str) -> np.ndarray:
    """(N, 21, 3) robot keypoints -> (N, 22) UDHM angles: this project's IK, geometry only (no limit penalty)."""
    from lerobot_unidextok.udhm import inverse_kinematics

    return inverse_kinematics(keypoints_m, side=side, limit_weight_m_per_rad=0.0, iterations=300).angles_rad


def check_spec(
    spec: HandSpec,
    urdf_path: str | Path,
    side: str = "right",
    num_random: int = 12,
    seed: int = 0,
    rest_tol_deg: float = REST_TOL_DEG,
) -> CheckReport:
    """Check every native joint of ``spec`` on ``side`` against the URDF at ``urdf_path``."""
    if spec.kind != "joints":
        raise ValueError(f"hand {spec.name!r} is given as keypoints; there are no joints to check")
    spec.check_side(side)
    if spec.urdf is None:
        raise ValueError(
            f"hand {spec.name!r} has no `urdf:` block with the 21 keypoints on URDF links; add one to "
            f"{spec.path or 'its YAML'} (see docs/hands.md, 'Add your own hand')"
        )
    hand = UrdfHand.load(urdf_path, spec.urdf.keypoints[side])
    urdf_names = urdf_joint_names(spec, side, hand)
    poses = check_poses(spec, side, num_random, seed)
    lim = spec.limits_rad(side)
    num = spec.num_native

    # every pose, then +-step on each joint (one-sided at a limit), read two ways: the joint's own motion
    # (its URDF mimic followers held at the pose) and the whole linkage (followers move with it)
    leaders = {leader for leader, _, _ in hand.mimics.values()}
    cfgs, plan = [], []  # plan: (mode, pose, joint, index of +, index of -, step actually taken)
    for name, base in poses.items():
        full = hand.full_cfg(urdf_cfg(urdf_names, base))
        cfgs.append(full)
        for j in range(num):
            hi = min(base[j] + STEP_RAD, lim[j, 1])
            lo = max(base[j] - STEP_RAD, lim[j, 0])
            modes = ("own", "linkage") if urdf_names[j] in leaders else ("own",)
            for mode in modes:
                plan.append((mode, name, j, len(cfgs), len(cfgs) + 1, hi - lo))
                for q in (hi, lo):
                    moved = base.copy()
                    moved[j] = q
                    if mode == "own":
                        cfgs.append(full | ({urdf_names[j]: float(q)} if urdf_names[j] is not None else {}))
                    else:
                        cfgs.append(hand.full_cfg(urdf_cfg(urdf_names, moved)))
    udhm = udhm_from_keypoints(hand.keypoints_m(cfgs, followers=False), side)  # (M, 22)
    rest_udhm = udhm[0]  # the first configuration is the rest pose

    deriv: dict[tuple[str, int], dict[str, np.ndarray]] = {}
    for mode, name, j, iu, idn, span in plan:
        d = (udhm[iu] - udhm[idn]) / span if span > 0 else np.zeros(len(UDHM_JOINT_NAMES))
        deriv.setdefault((mode, j), {})[name] = d

    spec_rest_udhm = spec.to_udhm(spec.from_radians(poses["rest"], side), side)  # (22,)
    verdicts = []
    for j, joint in enumerate(spec.joints):
        js = joint.sides[side]
        modes = [m for m in ("own", "linkage") if (m, j) in deriv]
        others = [(UDHM_INDEX[o.sides[side].slot], deriv[("own", k)]) for k, o in enumerate(spec.joints)
                  if k != j and o.sides[side].slot is not None]  # fmt: skip
        by_mode = [_verdict(joint.name, urdf_names[j], js, deriv[(m, j)], m, others) for m in modes]
        v = next((x for x in by_mode if x.verdict == "ok"), by_mode[0])
        if v.verdict == "ok":
            i = UDHM_INDEX[js.slot]
            v.rest_error_deg = float(np.degrees(spec_rest_udhm[i] - rest_udhm[i]))
            v.suggested_rest_rad = float(poses["rest"][j] - js.sign * rest_udhm[i])
            if abs(v.rest_error_deg) > rest_tol_deg:
                v.verdict = "rest off"
        verdicts.append(v)
    return CheckReport(spec.name, side, Path(urdf_path).name, tuple(poses), verdicts)


def _competing(d: np.ndarray, pose: str | None, others: list[tuple[int, dict[str, np.ndarray]]]) -> np.ndarray:
    """|d| on the slots this joint competes for: a slot the spec gives to another joint that drives it at
    least as strongly is already explained by that joint and does not count against this one."""
    mag = np.abs(d)
    for slot, readings in others:
        other = readings[pose] if pose is not None else np.median(np.stack(list(readings.values())), axis=0)
        if abs(other[slot]) >= mag[slot]:
            mag[slot] = 0.0
    return mag


def _verdict(
    name: str,
    urdf_joint: str | None,
    js,
    readings: dict[str, np.ndarray],
    mode: str,
    others: list[tuple[int, dict[str, np.ndarray]]],
) -> JointVerdict:
    """Slot and sign verdict of one joint from its derivative (22,) at each pose (rest offset checked later).

    ``others``: (UDHM slot, derivatives per pose) of the spec's other mapped joints.
    """
    v = JointVerdict(name, urdf_joint, js.slot, int(js.sign), verdict="", mode=mode)
    kept = []
    for pose, d in readings.items():
        mag = _competing(d, pose, others)
        k = int(np.argmax(mag))
        gain = float(mag[k])
        share = float(d[UDHM_INDEX[js.slot]] * js.sign / gain) if js.slot and gain > 0 else 0.0
        moved = gain >= MIN_GAIN
        v.readings.append(PoseReading(pose, UDHM_JOINT_NAMES[k] if moved else None, int(np.sign(d[k])), gain, share))
        if gain <= MAX_GAIN:  # larger = IK jumped between twin solutions inside the step
            kept.append(d)
    median = np.median(np.stack(kept), axis=0) if kept else np.zeros(len(UDHM_JOINT_NAMES))
    primary = next((r for r in v.readings if r.slot is not None and r.gain <= MAX_GAIN), None)
    if primary is not None:
        v.primary_pose, v.found_slot, v.found_sign, v.gain = primary.pose, primary.slot, primary.sign, primary.gain
    if urdf_joint is None:
        v.verdict = "no URDF joint" if js.slot is not None else "dropped"
    elif js.slot is None:
        v.verdict = "dropped"
    elif primary is None:
        v.verdict = "no effect"
    else:
        top = float(_competing(median, None, others).max())
        v.median_share = float(median[UDHM_INDEX[js.slot]] * js.sign / top) if top > 0 else 0.0
        if primary.spec_share >= SHARE and v.median_share >= MEDIAN_SHARE:
            v.verdict = "ok"
        elif primary.spec_share >= SHARE:
            v.verdict = "pose-dependent"
        elif primary.spec_share <= -SHARE:
            v.verdict = "wrong sign"
        else:
            v.verdict = "wrong slot"
    return v
