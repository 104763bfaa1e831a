"""A simulated hand from a hand spec and its URDF alone: the built MJCF (`urdf_model`) and everything the scene and
the experts need, read from the kinematic chain, with no number tuned per hand.

- Drives: each native joint drives its URDF joint (`urdf_joint`, else its own name) through the spec's radians,
  or linearly over the URDF limits where the spec says the URDF's angles are not its radians
  (`raw_at_urdf_limits`); mimic followers move through the model's constraints. A URDF joint no native joint
  drives is held at 0 (clipped into its range); a native joint with no URDF joint reads back its open value.
- Open pose: the URDF's zero pose (every joint at 0, clipped into its limits). Postures: `hand_model.POSTURES`,
  UDHM slot angles over the open pose, the same for every hand.
- Mount (where the hand sits on the wrist): forward kinematics at the open pose of the spec's keypoints, the
  wrist keypoint at the wrist, the fingers (wrist to the MCPs' centre) along the wrist's x, the index side
  (the thumb side of a right hand) along its y (`urdf_model.hand_axes`).
- Fingertips: each finger's tip keypoint (link and offset); a finger counts when a joint moves its tip (the
  LEAP's and Allegro's stand-in little fingers, keypoints on the palm, do not).
- Grasp postures and offsets, by forward kinematics (`fit_postures`, `grasp_offsets`), in the wrist frame: the
  thumb's slots of the closed postures moved to bring its tip onto the centre of the index's and the middle's
  tips (a pinch is a tripod of the three); a pinch puts the point halfway between the thumb's tip and that centre
  on the object's centre, a power grasp the centre of the closed fingers' and thumb's keypoints past their bases
  (the hand closes around it), the palm's underside no lower than the object's top, the tips (pre-shaped and
  closed) no lower than 15 mm over the table.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import POSTURES, Drive, SimHand
from lerobot_env_unidextok.objects import SHAPES
from lerobot_env_unidextok.urdf_model import FINGER_KEYPOINTS, capsule_radius_m, hand_axes, model_xml
from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_JOINT_NAMES

SIDE = "right"


def sim_hand(spec: hands.HandSpec) -> SimHand:
    """The simulated hand of `spec` (right side), built from its URDF."""
    xml = model_xml(spec, SIDE)
    model = mujoco.MjModel.from_xml_string(xml)
    root = model.body(1).name
    drives, held = _drives(spec, model)
    keypoints = spec.urdf.keypoints[SIDE]
    fingertips, finger_bodies = {}, {}
    for finger, ids in FINGER_KEYPOINTS.items():
        tip = keypoints[ids[-1]]
        body = model.body(tip.link).id
        if model.body_weldid[body] == model.body_weldid[1]:
            continue  # rigid with the palm: a stand-in finger
        fingertips[finger] = (tip.link, tuple(float(x) for x in tip.offset_m))
    tip_bodies = {f: model.body(b).id for f, (b, _) in fingertips.items()}
    for finger, body in tip_bodies.items():
        others = [b for f, b in tip_bodies.items() if f != finger]
        base = body  # the finger: the highest ancestor of its tip that carries no other finger
        while model.body_parentid[base] > 1:
            parent = int(model.body_parentid[base])
            if any(_descends(model, o, parent) for o in others):
                break
            base = parent
        finger_bodies[finger] = tuple(model.body(b).name for b in range(model.nbody) if _descends(model, b, base))
    open_raw = _open_raw(spec, model, drives)
    hand = SimHand(spec=spec, side=SIDE, model_xml=xml, root=root, mount_pos_m=(0.0, 0.0, 0.0),
                   mount_matrix=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), drives=drives, held=held,
                   fingertips=fingertips, finger_bodies=finger_bodies, open_raw=open_raw, postures=dict(POSTURES),
                   grasp={}, source=f"built from {spec.urdf.source} by lerobot_env_unidextok/urdf_model.py")  # fmt: skip
    fk = HandFK(hand, model)
    axes = hand_axes(fk.keypoints(open_raw))
    mount_pos = -axes @ fk.keypoints(open_raw)[0]
    hand = replace(hand, mount_pos_m=tuple(float(x) for x in mount_pos),
                   mount_matrix=tuple(tuple(float(x) for x in row) for row in axes))  # fmt: skip
    fk = HandFK(hand, model)
    postures, pinch_fingers = fit_postures(hand, fk)
    hand = replace(hand, postures=postures)
    return replace(hand, grasp=grasp_offsets(hand, fk, pinch_fingers))


def _descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False


def _drives(spec: hands.HandSpec, model: mujoco.MjModel) -> tuple[tuple[Drive, ...], dict[str, float]]:
    actuated = {model.actuator(a).name.removesuffix("_drive") for a in range(model.nu)}
    drives = []
    for joint in spec.joints:
        side = joint.sides[SIDE]
        urdf = side.urdf_joint or joint.name
        if urdf not in actuated or side.scale == 0:
            continue
        lo, hi = (float(x) for x in model.jnt_range[model.joint(urdf).id])
        if side.raw_at_urdf_limits is not None:
            a, b = (side.offset + side.scale * r for r in side.raw_at_urdf_limits)
            native_rad, joint_rad = (a, b), (lo, hi)
        else:
            native_rad = joint_rad = tuple(float(x) for x in side.limits_rad)
        drives.append(Drive(joint=urdf, native=joint.name, native_rad=native_rad, joint_rad=joint_rad,
                            actuator=f"{urdf}_drive", measures=True))  # fmt: skip
    driven = {d.joint for d in drives}
    held = {f"{j}_drive": float(np.clip(0.0, *model.jnt_range[model.joint(j).id])) for j in sorted(actuated - driven)}
    return tuple(drives), held


def _open_raw(spec: hands.HandSpec, model: mujoco.MjModel, drives: tuple[Drive, ...]) -> np.ndarray:
    """Native values of the URDF's zero pose (undriven native joints: their default)."""
    rad = np.asarray(spec.to_radians(np.array([j.sides[SIDE].default_raw for j in spec.joints]), SIDE, "clip"))
    for d in drives:
        q0 = float(np.clip(0.0, *model.jnt_range[model.joint(d.joint).id]))
        rad[spec.joint_names.index(d.native)] = d.to_native(np.float64(q0))
    lo, hi = spec.limits_rad(SIDE).T
    return np.asarray(spec.from_radians(np.clip(rad, lo, hi), SIDE, "clip"), dtype=np.float64)


class HandFK:
    """Forward kinematics of a simulated hand's own model (no scene): native command -> points in the wrist
    frame. Joints are set as the drives map the command, mimic followers from their constraints."""

    def __init__(self, hand: SimHand, model: mujoco.MjModel | None = None) -> None:
        self.hand = hand
        self.model = model if model is not None else mujoco.MjModel.from_xml_string(hand.model_xml)
        self.data = mujoco.MjData(self.model)
        self.rot = np.asarray(hand.mount_matrix, dtype=np.float64)
        self.pos = np.asarray(hand.mount_pos_m, dtype=np.float64)

    def pose(self, native_raw: np.ndarray) -> None:
        m, d, hand = self.model, self.data, self.hand
        d.qpos[:] = m.qpos0
        for name, target in hand.command(native_raw).items():
            a = m.actuator(name).id
            d.qpos[m.jnt_qposadr[m.actuator_trnid[a, 0]]] = target
        set_mimic_followers(m, d)
        mujoco.mj_kinematics(m, d)

    def point(self, body: str, offset_m) -> np.ndarray:
        b = self.model.body(body).id
        p = self.data.xpos[b] + self.data.xmat[b].reshape(3, 3) @ np.asarray(offset_m, dtype=np.float64)
        return self.rot @ p + self.pos

    def keypoints(self, native_raw: np.ndarray) -> np.ndarray:
        """(21, 3) the spec's keypoints at `native_raw` (wrist frame; the model's frame before the mount is set)."""
        self.pose(native_raw)
        return np.stack([self.point(k.link, k.offset_m) for k in self.hand.spec.urdf.keypoints[SIDE]])

    def tips(self, native_raw: np.ndarray) -> dict[str, np.ndarray]:
        self.pose(native_raw)
        return {f: self.point(b, p) for f, (b, p) in self.hand.fingertips.items()}

    def palm_bottom_z(self) -> float:
        """The lowest point (wrist frame z) of the palm body's geoms at the open pose."""
        self.pose(self.hand.open_raw)
        m, d = self.model, self.data
        lows = []
        for g in np.flatnonzero(m.geom_bodyid == 1):
            centre = self.rot @ d.geom_xpos[g] + self.pos
            half = np.abs(self.rot @ d.geom_xmat[g].reshape(3, 3)) @ _half_extents(m, g)
            lows.append(centre[2] - half[2])
        return float(min(lows)) if lows else 0.0


def _half_extents(model: mujoco.MjModel, g: int) -> np.ndarray:
    size, kind = model.geom_size[g], int(model.geom_type[g])
    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        return size.copy()
    if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        return np.full(3, size[0])
    return np.array([size[0], size[0], size[1] + (size[0] if kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE) else 0)])


def set_mimic_followers(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Each joint equality's follower from its leader (q1 = c0 + c1 q2, MuJoCo's polynomial to first order)."""
    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT):
            continue
        q1 = model.jnt_qposadr[model.eq_obj1id[e]]
        q2 = model.jnt_qposadr[model.eq_obj2id[e]]
        c = model.eq_data[e]
        data.qpos[q1] = c[0] + c[1] * data.qpos[q2]


THUMB_SLOTS = ("thumb_cmc_flex", "thumb_cmc_spread", "thumb_mcp_flex", "thumb_mcp_abd", "thumb_ip_flex")
# Before closing, each closing tip this far (horizontally) beyond the widest object of its grasp: one number for
# every hand, the best of 8, 15 and 22 mm on 100 seeded grasps of the Allegro, XHand, LEAP and L10 (22 mm: 95, 95,
# 100, 96 %; 15 mm: 94, 94, 100, 97 %; 8 mm: the LEAP's pre-curled fingers landed on boxes, 53 %)
PRESHAPE_CLEAR_M = 0.022
TABLE_CLEAR_M = 0.015  # the tips (pre-shaped and closed) of a power grasp at least this far over the table


def fit_postures(hand: SimHand, fk: HandFK) -> tuple[dict[str, dict[str, float]], tuple[str, ...]]:
    """The grasp postures, from the written ones by forward kinematics, and the pinch's fingers: the thumb's slots
    of `pinch` and `power` moved (within the hand's UDHM range) to bring the thumb's tip onto the centre of the
    index's and middle's tips; a pinch with the index alone where those two tips, closed, leave a gap the smallest
    pinch object passes through (the Dex3's two fingers); `pinch_pre` and `preshape` part of the way from the open
    pose to them, as far as keeps the closing tips clear of the widest object of their grasp (`PRESHAPE_CLEAR_M`
    past its half width), the thumb and the fingers each on their own (they then reach the object about
    together)."""
    from scipy.optimize import minimize  # start-up: SciPy's optimiser, only when a hand is built

    spec, side = hand.spec, hand.side
    lo, hi = spec.udhm_limits_rad(side)
    slots = [s for s in THUMB_SLOTS if spec.active_mask[UDHM_JOINT_NAMES.index(s)]]
    idx = [UDHM_JOINT_NAMES.index(s) for s in slots]
    postures = {k: dict(v) for k, v in hand.postures.items()}

    def tips_at(udhm_overrides: dict[str, float]) -> dict[str, np.ndarray]:
        return fk.tips(hand.with_slots(udhm_overrides))

    def fit_thumb(base: dict[str, float], target: list[int]) -> dict[str, float]:
        start = np.array([base.get(s, float(_open_udhm(hand)[i])) for s, i in zip(slots, idx, strict=True)])

        def gap(x) -> float:
            kp = fk.keypoints(hand.with_slots({**base, **dict(zip(slots, x, strict=True))}))
            return float(np.sum((kp[4] - kp[target].mean(0)) ** 2))

        best = minimize(gap, start, method="Powell", bounds=list(zip(lo[idx], hi[idx], strict=True)),
                        options={"xtol": 1e-3, "ftol": 1e-8, "maxfev": 2000})  # fmt: skip
        return {**base, **{s: float(v) for s, v in zip(slots, best.x, strict=True)}}

    tips = [FINGER_KEYPOINTS[f][-1] for f in ("index", "middle")]  # MANO-21 8, 12
    postures["power"] = fit_thumb(postures["power"], tips)
    postures["pinch"] = fit_thumb(postures["pinch"], tips)
    kp = fk.keypoints(hand.with_slots(postures["pinch"]))
    radius = capsule_radius_m(fk.keypoints(hand.open_raw))
    smallest = 2 * min(lo_m for shape in SHAPES if shape.grasp == "pinch" for lo_m, _ in shape.half_m[:1])
    pinch_fingers: tuple[str, ...] = ("index", "middle")
    if np.linalg.norm(kp[tips[0]] - kp[tips[1]]) - 2 * radius >= smallest:  # the object would pass between them
        pinch_fingers = ("index",)
        for pre in ("pinch", "pinch_pre"):
            postures[pre] = {k: v for k, v in postures[pre].items() if not k.startswith("middle_")}
        postures["pinch"] = fit_thumb(postures["pinch"], tips[:1])
    open_udhm = _open_udhm(hand)

    def _open(slot: str) -> float:
        return float(open_udhm[UDHM_JOINT_NAMES.index(slot)])

    fingers = [f for f in hand.fingers if f != "thumb"]
    for pre, name in (("pinch_pre", "pinch"), ("preshape", "power")):
        closed = postures[name]
        point = grasp_point(name, fk, hand.with_slots(closed), pinch_fingers)
        clear = max(hi for shape in SHAPES if shape.grasp == name for _, hi in shape.half_m[:1]) + PRESHAPE_CLEAR_M
        chosen = {}
        # the thumb and the fingers each opened just enough: closing, they reach the object about together
        movers = list(pinch_fingers) if name == "pinch" else fingers
        groups = ((slots, ["thumb"]), ([k for k in closed if k not in slots], movers))
        for group, movers in groups:
            part = {}
            for share in np.linspace(1.0, 0.0, 21):
                part = {k: float(_open(k) + share * (closed[k] - _open(k))) for k in group if k in closed}
                tips = tips_at({**closed, **part})
                if all(np.linalg.norm((tips[f] - point)[:2]) >= clear for f in movers):
                    break
            chosen.update(part)
        postures[pre] = chosen
    return postures, pinch_fingers


def _open_udhm(hand: SimHand) -> np.ndarray:
    return np.asarray(hand.spec.to_udhm(hand.open_raw, hand.side), dtype=np.float64)


def grasp_point(kind: str, fk: HandFK, native_raw: np.ndarray, pinch_fingers=("index", "middle")) -> np.ndarray:
    """Where the object's centre goes (wrist frame) when the hand holds `native_raw`: a pinch, halfway between the
    thumb's tip and the centre of the pinching fingers' tips; a power grasp, the centre of the fingers' and
    thumb's keypoints past their bases (the space they close around)."""
    kp = fk.keypoints(native_raw)
    if kind == "pinch":
        fingers = kp[[FINGER_KEYPOINTS[f][-1] for f in pinch_fingers]].mean(0)
        return (kp[FINGER_KEYPOINTS["thumb"][-1]] + fingers) / 2
    return kp[[i for f in fk.hand.fingers for i in FINGER_KEYPOINTS[f][1:]]].mean(0)


def grasp_offsets(hand: SimHand, fk: HandFK, pinch_fingers=("index", "middle")) -> dict[str, dict]:
    """The experts' grasp entries: where the wrist goes relative to the object (module docstring)."""
    at = grasp_point("pinch", fk, hand.posture("pinch"), pinch_fingers)
    centre = grasp_point("power", fk, hand.posture("power"))
    lowest = min(p[2] for k in ("preshape", "power") for p in fk.tips(hand.posture(k)).values())
    below = fk.palm_bottom_z()
    return {
        "power": {"preshape": "preshape", "posture": "power", "offset_m": [float(-x) for x in centre],
                  "from": "centre", "palm_over_top_m": float(-below), "over_table_m": float(TABLE_CLEAR_M - lowest)},
        "pinch": {"preshape": "pinch_pre", "posture": "pinch", "offset_m": [float(-x) for x in at],
                  "fingers": list(pinch_fingers)},
    }  # fmt: skip


__all__ = ["HandFK", "grasp_offsets", "set_mimic_followers", "sim_hand"]
