"""A robot hand's URDF: its joints and links read by `yourdfpy` (optional extra ``urdf``), and its MANO-21
keypoints by forward kinematics along its joint chains, every configuration at once (numpy).

    hand = UrdfHand.load("allegro_hand_right.urdf", spec.urdf.keypoints["right"])
    keypoints_m = hand.keypoints_m([{"joint_1.0": 0.5}, ...])   # (N, 21, 3) in the URDF base frame

Each keypoint is a link frame plus a fixed offset in that frame (``UrdfKeypoint``), so the map from a
robot to the 21 anatomical points is data in the hand's YAML. Joints not given in a configuration stay at
0 clipped into their limits. Mimic joints follow their leader (``full_cfg``; chains of mimics are resolved
to the root leader); they are posed explicitly, so a check can also move a leader with its followers held.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import KEYPOINT_NAMES
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.spec import UrdfKeypoint
from lerobot_unidextok.utils.imports import require_package

logger = logging.getLogger(__name__)


@dataclass
class UrdfHand:
    """A loaded URDF (no meshes) and the 21 keypoints defined on its links."""

    path: Path
    model: object  # yourdfpy.URDF with a scene graph, every movable joint actuated (mimic tags removed)
    keypoints: tuple[UrdfKeypoint, ...]  # 21, MANO-21 order
    mimics: dict[str, tuple[str, float, float]]  # follower -> (root leader, multiplier, offset)

    @classmethod
    def load(cls, path: str | Path, keypoints: tuple[UrdfKeypoint, ...]) -> UrdfHand:
        """Parse ``path`` (meshes are not loaded: kinematics only) and check that every keypoint link exists."""
        yourdfpy = require_package(
            "yourdfpy", "urdf", purpose="the URDF kinematic check", hint=" (or pip install yourdfpy)"
        )
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"URDF not found: {path}")
        if len(keypoints) != len(KEYPOINT_NAMES):
            raise ValueError(f"need {len(KEYPOINT_NAMES)} keypoints in MANO-21 order, got {len(keypoints)}")
        logging.getLogger("yourdfpy").setLevel(logging.ERROR)  # dangling mesh paths are expected
        parsed = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
        tags = {
            j.name: (j.mimic.joint, _or(j.mimic.multiplier, 1.0), _or(j.mimic.offset, 0.0))
            for j in parsed.robot.joints
            if j.mimic is not None
        }
        try:
            mimics = resolve_mimic_chains(tags, [j.name for j in parsed.robot.joints])
        except ValueError as err:
            raise ValueError(f"{path.name}: {err}") from None
        for joint in parsed.robot.joints:
            joint.mimic = None  # followers are posed explicitly by full_cfg
        model = yourdfpy.URDF(robot=parsed.robot, build_scene_graph=True, load_meshes=False)
        missing = [(n, k.link) for n, k in zip(KEYPOINT_NAMES, keypoints, strict=True) if k.link not in model.link_map]
        if missing:
            raise ValueError(
                f"{path.name}: keypoint link(s) not in the URDF: "
                + ", ".join(f"{n} -> {link!r}" for n, link in missing)
                + f"; links are {sorted(model.link_map)}"
            )
        return cls(path, model, tuple(keypoints), mimics)

    # -- joints ------------------------------------------------------------------------------------
    @property
    def joint_names(self) -> tuple[str, ...]:
        """Independent (non-mimic) movable joints, URDF order."""
        return tuple(n for n in self.model.actuated_joint_names if n not in self.mimics)

    def limits_rad(self, joint: str) -> tuple[float, float]:
        """(lower, upper) of an actuated joint; (-inf, inf) when the URDF gives none."""
        j = self.model.joint_map[joint]
        lim = j.limit
        lo = lim.lower if lim is not None and lim.lower is not None else -np.inf
        hi = lim.upper if lim is not None and lim.upper is not None else np.inf
        return float(lo), float(hi)

    def rest_cfg(self) -> dict[str, float]:
        """Every independent joint at 0 clipped into its limits."""
        return {n: float(np.clip(0.0, *self.limits_rad(n))) for n in self.joint_names}

    def full_cfg(self, cfg: dict[str, float]) -> dict[str, float]:
        """Independent joints (missing ones at rest) plus every mimic joint from its leader."""
        unknown = sorted(set(cfg) - set(self.joint_names))
        if unknown:
            raise ValueError(
                f"{self.path.name}: not independent joints of this URDF: {unknown}; joints: {self.joint_names}"
            )
        full = self.rest_cfg() | cfg
        for follower, (leader, mult, offset) in self.mimics.items():
            full[follower] = mult * full[leader] + offset
        return full

    # -- forward kinematics ------------------------------------------------------------------------
    def keypoints_m(self, cfgs: list[dict[str, float]], followers: bool = True) -> np.ndarray:
        """(N, 21, 3) keypoints in metres in the URDF base frame, one row per configuration.

        A configuration maps independent joint names to radians; missing joints take ``rest_cfg()`` and
        mimic joints follow (``followers=True``). With ``followers=False`` each configuration must give
        every movable joint (e.g. ``full_cfg`` of another pose with one leader changed).
        """
        if followers:
            cfgs = [self.full_cfg(c) for c in cfgs]
        links = self.link_transforms(cfgs, sorted({k.link for k in self.keypoints}))  # link -> (N, 4, 4)
        out = np.empty((len(cfgs), len(self.keypoints), 3))
        for k, kp in enumerate(self.keypoints):
            tf = links[kp.link]  # (N, 4, 4) link -> base
            out[:, k] = tf[:, :3, :3] @ np.asarray(kp.offset_m, dtype=float) + tf[:, :3, 3]
        return out

    def link_origins_m(self, cfg: dict[str, float] | None = None) -> dict[str, np.ndarray]:
        """Every link origin (m, base frame) at ``cfg`` (default: rest): for writing a keypoint map."""
        links = self.link_transforms([self.full_cfg(cfg or {})], list(self.model.link_map))
        return {name: tf[0, :3, 3].copy() for name, tf in links.items()}

    def link_transforms(self, cfgs: list[dict[str, float]], links: Collection[str]) -> dict[str, np.ndarray]:
        """Each of ``links``' (N, 4, 4) transform to the base frame at N configurations that give every movable
        joint (radians, or metres for a prismatic one): the URDF's joint chain, all configurations at once.
        What yourdfpy's `update_cfg` + `get_transform` give one configuration at a time, 10-20x slower."""
        by_child = {j.child: j for j in self.model.robot.joints}
        done: dict[str, np.ndarray] = {self.model.base_link: np.broadcast_to(np.eye(4), (len(cfgs), 4, 4))}

        def pose(link: str) -> np.ndarray:
            if link not in done:
                joint = by_child[link]
                done[link] = pose(joint.parent) @ _joint_transforms(joint, cfgs, self.path.name)
            return done[link]

        return {link: pose(link) for link in links}


def _joint_transforms(joint, cfgs: list[dict[str, float]], urdf: str) -> np.ndarray:
    """(N, 4, 4) parent -> child transform of a yourdfpy joint at each configuration: its origin, then its motion
    about (revolute, continuous) or along (prismatic) its axis; every other type is its origin alone."""
    origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
    n = len(cfgs)
    if joint.type not in ("revolute", "continuous", "prismatic"):
        return np.broadcast_to(origin, (n, 4, 4))
    try:
        q = np.array([c[joint.name] for c in cfgs], dtype=float)  # (N,)
    except KeyError:
        raise ValueError(f"{urdf}: a configuration does not give the movable joint {joint.name!r}") from None
    axis = np.array([1.0, 0.0, 0.0]) if joint.axis is None else np.asarray(joint.axis, dtype=float)
    motion = np.tile(np.eye(4), (n, 1, 1))  # (N, 4, 4)
    if joint.type == "prismatic":
        motion[:, :3, 3] = q[:, None] * axis
    else:  # Rodrigues: I + sin(q) K + (1 - cos(q)) K^2 about the unit axis
        x, y, z = axis / np.linalg.norm(axis)
        k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
        motion[:, :3, :3] += np.sin(q)[:, None, None] * k + (1.0 - np.cos(q))[:, None, None] * (k @ k)
    return origin @ motion


def resolve_mimic_chains(
    mimics: dict[str, tuple[str, float, float]], joints: Collection[str]
) -> dict[str, tuple[str, float, float]]:
    """Each mimic joint's (root leader, multiplier, offset), following chains of mimics to a non-mimic joint.

    ``mimics`` maps a follower to its URDF ``<mimic>`` tag (leader, multiplier, offset): follower =
    multiplier * leader + offset. A chain b = m1 a + o1, c = m2 b + o2 gives c = (m2 m1) a + (m2 o1 + o2).
    A multiplier of 0 stays 0 (the follower sits at its offset). ValueError when a leader is not in
    ``joints`` or the mimics form a cycle.
    """

    def root_of(name: str, chain: tuple[str, ...]) -> tuple[str, float, float]:
        if name not in mimics:
            if name not in joints:
                raise ValueError(f"joint {chain[-1]!r} mimics unknown joint {name!r}")
            return name, 1.0, 0.0
        if name in chain:
            raise ValueError(f"mimic joints form a cycle: {' -> '.join((*chain, name))}")
        leader, mult_here, offset_here = mimics[name]
        root, mult, offset = root_of(leader, (*chain, name))
        return root, mult_here * mult, mult_here * offset + offset_here

    return {follower: root_of(follower, ()) for follower in mimics}


def _or(value: float | None, default: float) -> float:
    """yourdfpy leaves an attribute the URDF omits as None; 0 is a value, not a missing one."""
    return default if value is None else float(value)


def measure_skeleton(hand: UrdfHand, side: str = "right"):
    """The ``udhm.Skeleton`` (right-hand canonical frame) of the URDF at its rest configuration.

    Bone lengths are distances between consecutive keypoints (joint centres), palm offsets the base
    keypoints in the palm frame UDHM fits to wrist and index/middle/ring MCP; left hands are mirrored.
    """
    from lerobot_unidextok.udhm.skeleton import Skeleton

    keypoints_m = hand.keypoints_m([{}])  # (1, 21, 3)
    return Skeleton.from_keypoints(keypoints_m, per_frame=False, side=side)


# ---------------------------------------------------------------------------------------------
# the URDF as XML: find the user's file, read its joints and links, make mimic chains one level deep (retargeting:
# dex-retargeting's mimic adaptor needs every mimic joint to follow an optimised joint)
# ---------------------------------------------------------------------------------------------
class URDFError(InvalidInputError):
    """A URDF is missing or lacks a joint / link the retarget spec names."""


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    type: str
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None  # (followed joint, multiplier, offset)


def find_urdfs(urdf: str | Path, file_name: str) -> list[Path]:
    """`urdf` is the file itself, or a folder searched (recursively) for files named `file_name`."""
    path = Path(urdf)
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise URDFError(f"URDF path {path} does not exist; pass the robot's URDF file or a folder holding {file_name}")
    hits = sorted(path.rglob(file_name))
    if not hits:
        raise URDFError(
            f"no {file_name} under {path}; pass the URDF file or a folder that holds it (e.g. a clone of the "
            "vendor's URDF repository)"
        )
    return hits


def read_joints(path: Path) -> dict[str, UrdfJoint]:
    root = ET.parse(path).getroot()
    out = {}
    for j in root.findall("joint"):
        lim, mim = j.find("limit"), j.find("mimic")
        lower = float(lim.get("lower", 0.0)) if lim is not None else 0.0
        upper = float(lim.get("upper", 0.0)) if lim is not None else 0.0
        mimic = None
        if mim is not None:
            mimic = (mim.get("joint"), float(mim.get("multiplier", 1.0)), float(mim.get("offset", 0.0)))
        out[j.get("name")] = UrdfJoint(j.get("name"), j.get("type"), lower, upper, mimic)
    return out


def link_names(path: Path) -> set[str]:
    return {link.get("name") for link in ET.parse(path).getroot().findall("link")}


def flatten_mimic_chains(src: Path, dst: Path) -> Path:
    """Write `src` to `dst` with every mimic joint following a non-mimic joint (`hands.urdf.resolve_mimic_chains`)."""
    joints = read_joints(src)
    try:
        roots = resolve_mimic_chains({n: j.mimic for n, j in joints.items() if j.mimic is not None}, joints)
    except ValueError as err:
        raise URDFError(f"{src}: {err}") from None
    tree = ET.parse(src)
    for j in tree.getroot().findall("joint"):
        m = j.find("mimic")
        if m is not None:
            base, mul, off = roots[j.get("name")]
            m.set("joint", base)
            m.set("multiplier", repr(mul))
            m.set("offset", repr(off))
    tree.write(dst)
    return dst
