"""`PinchPlace-v0`: pick a small upright cylinder with the thumb and the named finger (index or middle) and set it
down, standing, inside a target circle on the table.

Per episode: the cylinder's radius (12-15 mm) and half height (14-18 mm), its place, the target 6-9 cm away from
it in a drawn direction, and the finger. Columns (the same for every hand): the object's centre, radius and half
height, the target's centre, and the finger as a one-hot (`pinch_index`, `pinch_middle`).

Success: the cylinder, lifted at least 15 mm on the way, stands on the table (within 3 mm of its resting height,
tilted under 20 degrees) with its centre inside the target (`TARGET_RADIUS_M`), and no finger touches it.
Failures end the episode: another finger than the thumb and the named one touches it ("other finger"), it lies
tilted past 30 degrees with no finger on it ("knocked over"), the hand lets it go more than 10 mm above the table
("dropped"), or lets it go on the table outside the target ("outside the target").

Each hand's two-finger pinch is found by forward kinematics in the scene (`pinch_of`, no number tuned per hand):
the thumb's UDHM slots and the finger's curl (MCP, PIP, DIP at 1 : 0.8 : 0.5) moved within the hand's range to
bring the thumb's tip onto the finger's tip (`closed`); the pre-shape the thumb's and the finger's slots each
opened until its tip clears the widest cylinder by `PRESHAPE_CLEAR_M`; along the closing path between them, the
closest points of the thumb's and the finger's collision geoms (`mj_geomDistance`), which say where a cylinder of
a given width sits when both touch it (`Pinch.point_m`) and how far to close to hold it (`Pinch.hold`). A hand
whose thumb's tip cannot come within `MAX_GAP_M` of the index's or the middle's tip (the Allegro's middle: 35 mm)
cannot take the task: refused when the env is made, in one line.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from lerobot_env_unidextok import sim_hands
from lerobot_env_unidextok.columns import TASK_COLUMNS, TASK_TEXT
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.gl import mujoco
from lerobot_env_unidextok.hand_model import SimHand
from lerobot_env_unidextok.objects import DENSITY
from lerobot_env_unidextok.scene import Scene, base_spec
from lerobot_env_unidextok.tasks import TABLE_Z, Task
from lerobot_unidextok.constants import UDHM_JOINT_NAMES

PINCH_FINGERS = ("index", "middle")
RADIUS_M = (0.012, 0.015)
HALF_HEIGHT_M = (0.014, 0.018)
TARGET_RADIUS_M = 0.02  # the object's centre this close to the target's (m)
MAX_GAP_M = 0.014  # the closest the thumb's tip comes to the finger's tip, at most (the smallest cylinder is 24 mm)
PRESHAPE_CLEAR_M = 0.02  # before closing, each tip this far (horizontally) beyond the widest cylinder's side
THUMB_SLOTS = ("thumb_cmc_flex", "thumb_cmc_spread", "thumb_mcp_flex", "thumb_mcp_abd", "thumb_ip_flex")
CURL = (1.0, 0.8, 0.5)  # a pinching finger's MCP, PIP and DIP flexion, as multiples of one curl angle
PATH_POINTS = 41  # samples of the closing path
SQUEEZE_M = 0.008  # a hold closes the fingers this much closer than the object is wide


@dataclass(frozen=True)
class Pinch:
    """A hand's pinch of the thumb and one finger, by forward kinematics at the zero wrist pose (wrist frame)."""

    closed: np.ndarray  # (J,) native command: the tips meet
    pre: np.ndarray  # (J,) native command: the same slots opened to clear the widest cylinder
    gap_m: float  # the closest the two tips come
    path_gap_m: np.ndarray  # (K,) the two fingers' surfaces' distance along the closing path (pre to closed)
    path_mid_m: np.ndarray  # (K, 3) the point halfway between their closest points there

    def _share(self, width_m: float) -> float:
        """How far along the closing path (0: pre, 1: closed) the fingers come to `width_m` apart."""
        k = int(np.argmax(self.path_gap_m <= width_m)) if np.any(self.path_gap_m <= width_m) else -1
        return float(np.linspace(0, 1, len(self.path_gap_m))[k])

    def point_m(self, width_m: float) -> np.ndarray:
        """(3,) where an object `width_m` wide goes between the fingers: halfway between their closest points where
        they close to that distance on the way from `pre` to `closed`, so both touch it at once, neither pushes it."""
        return self.path_mid_m[round(self._share(width_m) * (len(self.path_gap_m) - 1))]

    def hold(self, width_m: float) -> np.ndarray:
        """(J,) the command that holds an object `width_m` wide: the closing path where the fingers would be
        `SQUEEZE_M` closer than its width (a firm hold that does not keep turning it in the fingers)."""
        a = self._share(width_m - SQUEEZE_M)
        return (1 - a) * self.pre + a * self.closed


def pinch_of(hand: SimHand, finger: str) -> Pinch:
    """The thumb-`finger` pinch of `hand` (module docstring); fitted once per hand and finger in a process."""
    return _pinch(hand.name, finger)


@functools.cache
def _pinch(hand_name: str, finger: str) -> Pinch:
    hand = sim_hands.load(hand_name)
    from scipy.optimize import minimize  # start-up: SciPy's optimiser, only when a pinch is fitted

    scene = Scene.compile(base_spec(hand), hand)
    m, d = scene.model, mujoco.MjData(scene.model)

    def tips(native: np.ndarray) -> dict[str, np.ndarray]:
        d.qpos[:] = m.qpos0
        d.qpos[scene.wrist_qpos] = 0.0
        scene.place_hand(d, native)
        mujoco.mj_kinematics(m, d)
        return {f: scene.fingertip(d, f) for f in ("thumb", finger)}

    lo, hi = hand.spec.udhm_limits_rad(hand.side)
    slots = [s for s in THUMB_SLOTS if hand.spec.active_mask[UDHM_JOINT_NAMES.index(s)]]
    idx = [UDHM_JOINT_NAMES.index(s) for s in slots]
    curl_slots = [f"{finger}_{j}_flex" for j in ("mcp", "pip", "dip")]  # index and middle: UDHM's names too

    def overrides(x: np.ndarray) -> dict[str, float]:
        return {**dict(zip(slots, map(float, x[:-1]), strict=True)),
                **{s: float(k * x[-1]) for s, k in zip(curl_slots, CURL, strict=True)}}  # fmt: skip

    def gap(x: np.ndarray) -> float:
        t = tips(hand.with_slots(overrides(x)))
        return float(np.sum((t["thumb"] - t[finger]) ** 2))

    start = np.array([hand.postures["pinch"].get(s, 0.5 * (lo[i] + hi[i])) for s, i in zip(slots, idx, strict=True)]
                     + [1.0])  # fmt: skip
    bounds = [*zip(lo[idx], hi[idx], strict=True), (0.2, 1.7)]
    best = minimize(gap, np.clip(start, *np.array(bounds).T), method="Powell", bounds=bounds,
                    options={"xtol": 1e-3, "ftol": 1e-9, "maxfev": 3000})  # fmt: skip
    closed_over = overrides(best.x)
    closed = hand.with_slots(closed_over)
    t = tips(closed)
    point = (t["thumb"] + t[finger]) / 2
    opened = {s: float(v) for s, v in zip(UDHM_JOINT_NAMES, hand.spec.to_udhm(hand.open_raw, hand.side), strict=True)}
    clear = RADIUS_M[1] + PRESHAPE_CLEAR_M
    pre_over = {}
    for group, tip in ((slots, "thumb"), (curl_slots, finger)):  # each opened just enough: they reach it together
        part = {}
        for share in np.linspace(1.0, 0.0, 21):
            part = {s: opened[s] + share * (closed_over[s] - opened[s]) for s in group}
            if np.linalg.norm((tips(hand.with_slots({**closed_over, **part}))[tip] - point)[:2]) >= clear:
                break
        pre_over.update(part)
    pre = hand.with_slots({**closed_over, **pre_over})
    # along the closing path (pre to closed, linear in native), the closest points of the thumb's and the finger's
    # surfaces (their collision geoms): an object as wide as their distance touches both there
    solid = lambda f: [g for g in scene.finger_geoms[f] if m.geom_contype[g] or m.geom_conaffinity[g]]  # noqa: E731
    pairs = [(a, b) for a in solid("thumb") for b in solid(finger)]
    gaps, mids, fromto = [], [], np.zeros(6)
    for a in np.linspace(0, 1, PATH_POINTS):
        tips((1 - a) * pre + a * closed)  # poses the hand
        mujoco.mj_forward(m, d)
        best_gap, mid = np.inf, np.zeros(3)
        for g1, g2 in pairs:
            dist = mujoco.mj_geomDistance(m, d, g1, g2, 0.2, fromto)
            if dist < best_gap:
                best_gap, mid = dist, (fromto[:3] + fromto[3:]) / 2
        gaps.append(best_gap)
        mids.append(mid)
    return Pinch(closed=closed, pre=pre, gap_m=float(np.sqrt(best.fun)), path_gap_m=np.array(gaps),
                 path_mid_m=np.array(mids))


class PinchPlace(Task):
    name = "PinchPlace-v0"
    grasps = True
    description = TASK_TEXT[name]
    AREA = ((0.03, 0.09), (-0.06, 0.06))  # x, y ranges of the object's centre (m)
    TARGET_AREA = ((0.0, 0.13), (-0.10, 0.10))  # x, y ranges of the target's centre (m)
    TARGET_DISTANCE_M = (0.06, 0.09)
    LIFTED_M = 0.015
    RESTING_M = 0.003
    DROPPED_M = 0.01
    UPRIGHT_RAD = np.deg2rad(20)
    FALLEN_RAD = np.deg2rad(30)

    def __init__(self, hand: SimHand) -> None:
        super().__init__(hand)
        missing = [f for f in PINCH_FINGERS if f not in hand.fingers]
        gaps = {f: pinch_of(hand, f).gap_m for f in PINCH_FINGERS if f not in missing}
        far = [f for f, g in gaps.items() if g > MAX_GAP_M]
        if missing or far:
            why = (f"it has no {' or '.join(missing)} finger" if missing else
                   "its thumb's tip comes no closer than " + ", ".join(f"{1000 * gaps[f]:.0f} mm to the {f}'s"
                                                                       for f in far))  # fmt: skip
            raise SimInputError(
                f"hand {hand.name!r} cannot pinch with the thumb and each of {' and '.join(PINCH_FINGERS)}, which "
                f"{self.name} asks for: {why} (at most {1000 * MAX_GAP_M:.0f} mm); choose another hand, or "
                f"GraspLift-v0 for this one"
            )
        self.finger = PINCH_FINGERS[0]
        self.radius, self.half_height = RADIUS_M[1], HALF_HEIGHT_M[1]
        self.target = np.zeros(2)
        self.lifted = self.touched = False
        self.failure = ""
        self.rest_z = 0.0

    def state_names(self) -> list[str]:
        return list(TASK_COLUMNS[self.name])

    def add_to_spec(self, spec: mujoco.MjSpec) -> None:
        self.add_cylinder(spec)
        target = spec.worldbody.add_body(name="target", pos=[0.06, 0.08, TABLE_Z])
        target.add_geom(name="target", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[TARGET_RADIUS_M, 0.0005, 0],
                        pos=[0, 0, 0.0005], rgba=[0.2, 0.75, 0.3, 0.6], contype=0, conaffinity=0)  # fmt: skip

    @staticmethod
    def add_cylinder(spec: mujoco.MjSpec) -> None:
        body = spec.worldbody.add_body(name="pinch_object", pos=[0.06, 0, HALF_HEIGHT_M[1]])
        body.add_freejoint(name="pinch_object")
        body.add_geom(name="pinch_object", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[RADIUS_M[1], HALF_HEIGHT_M[1], 0],
                      rgba=[0.85, 0.45, 0.1, 1], friction=[2.0, 0.05, 0.01], condim=6, density=DENSITY)  # fmt: skip

    def bind(self, scene: Scene) -> None:
        self.bind_cylinder(scene)
        self.target_body = scene.model.body("target").id

    def bind_cylinder(self, scene: Scene) -> None:
        m = scene.model
        self.scene = scene
        self.body, self.geom = m.body("pinch_object").id, m.geom("pinch_object").id
        self.qpos = int(m.jnt_qposadr[m.joint("pinch_object").id])
        self.qvel = int(m.jnt_dofadr[m.joint("pinch_object").id])

    def reset(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        xy = self.draw_cylinder(rng)
        m = self.scene.model
        while True:  # a direction that keeps the target in its area
            angle, distance = rng.uniform(-np.pi, np.pi), rng.uniform(*self.TARGET_DISTANCE_M)
            self.target = xy + distance * np.array([np.cos(angle), np.sin(angle)])
            if all(lo <= v <= hi for v, (lo, hi) in zip(self.target, self.TARGET_AREA, strict=True)):
                break
        m.body_pos[self.target_body] = [*self.target, TABLE_Z]
        self.place_cylinder(data, xy, rng)

    def draw_cylinder(self, rng: np.random.Generator) -> np.ndarray:
        """The episode's cylinder size (the model resized) and (2,) place on the table."""
        m = self.scene.model
        self.radius, self.half_height = rng.uniform(*RADIUS_M), rng.uniform(*HALF_HEIGHT_M)
        volume = np.pi * self.radius**2 * 2 * self.half_height
        mass = volume * DENSITY
        m.geom_size[self.geom] = [self.radius, self.half_height, 0]
        m.body_mass[self.body] = mass
        m.body_inertia[self.body] = [mass * (3 * self.radius**2 + (2 * self.half_height) ** 2) / 12] * 2 + [
            mass * self.radius**2 / 2]  # fmt: skip
        m.geom_rbound[self.geom] = float(np.hypot(self.radius, self.half_height))
        m.geom_aabb[self.geom] = [0, 0, 0, self.radius, self.radius, self.half_height]
        return np.array([rng.uniform(*self.AREA[0]), rng.uniform(*self.AREA[1])])

    def place_cylinder(self, data: mujoco.MjData, xy: np.ndarray, rng: np.random.Generator) -> None:
        """The finger drawn, the cylinder standing at `xy`, the episode's flags cleared."""
        self.finger = PINCH_FINGERS[rng.integers(len(PINCH_FINGERS))]
        self.rest_z = TABLE_Z + self.half_height
        data.qpos[self.qpos : self.qpos + 7] = [*xy, self.rest_z, 1, 0, 0, 0]
        data.qvel[self.qvel : self.qvel + 6] = 0
        self.lifted = self.touched = False
        self.failure = ""

    def observe(self, data: mujoco.MjData) -> np.ndarray:
        pos = data.qpos[self.qpos : self.qpos + 3]
        return np.array([*pos, self.radius, self.half_height, *self.target,
                         *(float(f == self.finger) for f in PINCH_FINGERS)])  # fmt: skip

    def tilt_rad(self, data: mujoco.MjData) -> float:
        """The angle between the cylinder's axis and the vertical."""
        w, x, y, z = data.qpos[self.qpos + 3 : self.qpos + 7]
        return float(np.arccos(np.clip(1 - 2 * (x * x + y * y), -1, 1)))

    def pinch_failure(self, data: mujoco.MjData, z: float, by: set[str]) -> str:
        """How a pinch of the cylinder failed now, at height `z` with the fingers `by` on it ("": it did not): another
        finger on it, knocked over (lying tilted with no finger on it) or dropped (let go over the table)."""
        if by - {"thumb", self.finger}:
            return "other finger"
        if not by and self.tilt_rad(data) > self.FALLEN_RAD:
            return "knocked over"
        if self.touched and not by and z > self.rest_z + self.DROPPED_M:
            return "dropped"
        return ""

    def evaluate(self, data: mujoco.MjData) -> tuple[bool, bool]:
        if self.failure:
            return False, True
        z = float(data.qpos[self.qpos + 2])
        by = self.scene.fingers_touching(data, self.geom)
        self.lifted |= z >= self.rest_z + self.LIFTED_M
        on_table = abs(z - self.rest_z) <= self.RESTING_M
        inside = np.linalg.norm(data.qpos[self.qpos : self.qpos + 2] - self.target) <= TARGET_RADIUS_M
        self.failure = self.pinch_failure(data, z, by) or (
            "outside the target" if self.lifted and self.touched and not by and on_table and not inside else "")
        self.touched = bool(by)
        if self.failure:
            return False, True
        success = self.lifted and not by and on_table and inside and self.tilt_rad(data) <= self.UPRIGHT_RAD
        return bool(success), False

    def failure_reason(self, terminated: bool) -> str:
        return self.failure or ("timeout" if self.lifted else "not lifted")


__all__ = ["MAX_GAP_M", "PINCH_FINGERS", "Pinch", "PinchPlace", "pinch_of"]
