"""A hand's MJCF built from its URDF and its hand spec: any registered spec whose `urdf:` file is found.

    xml = urdf_model.model_xml(hands.get("leap"))   # built on first use, then read from the cache

MuJoCo's own URDF compiler reads the links, joints, limits and inertias (every link a body: `fusestatic` off;
mimic joints become MuJoCo's joint equality constraints, `follower = offset + multiplier * leader`). Then:
- meshes are not used (the shared URDFs come without them): collision primitives (box, cylinder, sphere) are
  kept; a link with a mesh collision gets capsules from its origin (its joint) to each child's origin, and a
  fingertip link a capsule from its origin to the spec's tip keypoint; a capsule ending at a tip keypoint ends
  there with its rounded end, radius included;
- the capsule radius comes from the chain: a tenth of the median finger's length (MCP-PIP-DIP-tip keypoints), at
  most 35 % of the closest two fingers' MCP spacing (neighbours do not touch), within 6-12 mm;
- a palm link (the URDF's root) without primitives gets a box over the finger bases' span: from the wrist
  keypoint to the MCPs along the fingers, across the MCPs (plus the radius), one radius each side of them;
- one `position` actuator per independent joint over its range (mimic followers move through their constraint),
  the same gains and torque limit for every hand, and the same joint dynamics: a small armature (URDF links of a
  few grams would need a smaller time step than the simulator's 4 ms), no URDF damping or friction (the
  actuator damps; a URDF's 1 N m of friction would hold a finger against a 3 N m/rad drive);
- contacts excluded between a body and its parent and grandparent, and between every pair of bodies that touch
  at the open pose (the URDF's zero pose, joints clipped into their limits): geometry that overlaps there is
  the approximation's, not a contact.

Built models ship with the package, written by `tools/sim/build_hand.py`, for every hand whose URDF's licence
permits it (`assets/<embodiment>/`, the licence beside each; a test rebuilds each bit for bit): they run without
the URDF. Which model a hand gets (`model_xml`): built from its URDF when `$UNIDEXTOK_URDF_DIR` is set and holds
it (how a hand is added or rebuilt); else the shipped model; else built from the URDF in ../shared/data/urdf.
Built models are cached outside the repository: `$UNIDEXTOK_SIM_CACHE`, else `$XDG_CACHE_HOME/unidextok/sim`
(`~/.cache/unidextok/sim`), one file per hand keyed by a fingerprint of the URDF's bytes, the spec's keypoints,
the builder's version and MuJoCo's; a changed input is a new file, never a stale one. A cached file's first line
holds the fingerprint of the rest: a file cut short, emptied, overwritten or edited by hand is rebuilt, with one
warning naming it. A URDF the builder cannot read (cut short, a joint without a parent, non-finite limits) is one
`SimBuildError` naming the file and the joint.
"""

from __future__ import annotations

import logging
import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from lerobot_env_unidextok.errors import SimBuildError, SimHandError
from lerobot_env_unidextok.gl import mujoco
from lerobot_unidextok import hands
from lerobot_unidextok.utils.files import fingerprint
from lerobot_unidextok.utils.shared_data import URDF_DIR_ENV, urdf_dir

BUILDER_VERSION = 1  # bump when the built MJCF changes for the same inputs
SHIPPED_DIR = Path(__file__).parent / "assets"
CACHE_ENV = "UNIDEXTOK_SIM_CACHE"
PRIMITIVES = ("box", "cylinder", "sphere")
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
RADIUS_SHARE = 0.1  # capsule radius: this share of the median finger's length (MCP to tip along the chain),
SPACING_SHARE = 0.35  # at most this share of the closest two fingers' MCP spacing (fingers 70 % as wide as
RADIUS_RANGE_M = (0.006, 0.012)  # their spacing, so neighbours do not touch), within this range
KP_NM_PER_RAD = 3.0  # position actuators: stiffness, damping, torque limit, joint armature (every hand)
KV_NMS_PER_RAD = 0.3
TORQUE_NM = 1.0
ARMATURE = 0.002
MIN_SEGMENT_M = 0.002  # shorter parent-child offsets get no capsule (a joint of two axes at one point)
CACHE_HEADER = "<!-- unidextok-sim-cache fingerprint={} -->\n"  # the first line of a cached model: of the rest
logger = logging.getLogger(__name__)
FINGER_KEYPOINTS = {  # MANO-21 indices: base (CMC / MCP), then to the tip
    "thumb": (1, 2, 3, 4), "index": (5, 6, 7, 8), "middle": (9, 10, 11, 12), "ring": (13, 14, 15, 16),
    "little": (17, 18, 19, 20),
}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# where the URDF is
# ---------------------------------------------------------------------------------------------
def urdf_path(spec: hands.HandSpec, side: str = "right") -> Path | None:
    """The spec's URDF file under the URDF folder (`$UNIDEXTOK_URDF_DIR`, else ../shared/data/urdf), or None
    when the spec maps none or the file is not there."""
    if spec.kind != "joints" or spec.urdf is None or side not in spec.urdf.files:
        return None
    path = urdf_dir() / spec.urdf.files[side]
    return path if path.is_file() else None


def shipped_path(spec: hands.HandSpec, side: str = "right") -> Path | None:
    """A built model that ships with the package (`assets/<embodiment>/<embodiment>_<side>.xml`: the simulator
    runs it without the URDF), or None. `tools/sim/build_hand.py` writes it; a test rebuilds it."""
    path = SHIPPED_DIR / spec.embodiment / f"{spec.embodiment}_{side}.xml"
    return path if spec.kind == "joints" and spec.urdf is not None and path.is_file() else None


def buildable(spec: hands.HandSpec, side: str = "right") -> bool:
    """Whether the simulator can build (or ship) this spec's model: its URDF is found, or its model ships."""
    return urdf_path(spec, side) is not None or shipped_path(spec, side) is not None


# ---------------------------------------------------------------------------------------------
# the build
# ---------------------------------------------------------------------------------------------
def urdf_without_meshes(text: str) -> tuple[str, set[str], set[str]]:
    """The URDF without visuals and mesh collisions, MuJoCo's compiler options added; the links that had a mesh
    collision (they get capsules: the LEAP's soft fingertips are meshes beside its boxes); the links with
    primitives."""
    root = ET.fromstring(text)
    mesh_links = set()
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        for collision in link.findall("collision"):
            if collision.find("geometry/mesh") is not None:
                mesh_links.add(link.get("name"))
                link.remove(collision)
    for old in root.findall("mujoco"):
        root.remove(old)
    tag = ET.SubElement(root, "mujoco")
    ET.SubElement(tag, "compiler", discardvisual="false", fusestatic="false", balanceinertia="true",
                  boundmass="0.001", boundinertia="1e-8")  # fmt: skip
    primitive_links = {link.get("name") for link in root.iter("link") if link.find("collision") is not None}
    return ET.tostring(root, encoding="unicode"), mesh_links, primitive_links


def _open_qpos(model: mujoco.MjModel) -> np.ndarray:
    """Every joint at 0 clipped into its range: the URDF's zero pose, the simulator's open hand."""
    q = model.qpos0.copy()
    for j in range(model.njnt):
        if model.jnt_limited[j]:
            q[model.jnt_qposadr[j]] = np.clip(0.0, *model.jnt_range[j])
    return q


def _keypoints(model: mujoco.MjModel, data: mujoco.MjData, spec: hands.HandSpec, side: str) -> np.ndarray:
    """(21, 3) the spec's keypoints in the model's world frame at `data`'s pose."""
    out = np.empty((21, 3))
    for i, kp in enumerate(spec.urdf.keypoints[side]):
        b = model.body(kp.link).id
        out[i] = data.xpos[b] + data.xmat[b].reshape(3, 3) @ np.asarray(kp.offset_m)
    return out


def capsule_radius_m(keypoints_m: np.ndarray) -> float:
    """A tenth of the median finger's length (index to little, MCP-PIP-DIP-tip keypoints), at most 35 % of the
    closest two MCPs' spacing, within 6-12 mm."""
    lengths = [sum(np.linalg.norm(keypoints_m[a + 1] - keypoints_m[a]) for a in FINGER_KEYPOINTS[f][:3])
               for f in ("index", "middle", "ring", "little")]  # fmt: skip
    spacing = np.linalg.norm(np.diff(keypoints_m[[5, 9, 13, 17]], axis=0), axis=1).min()
    return float(np.clip(min(RADIUS_SHARE * np.median(lengths), SPACING_SHARE * spacing), *RADIUS_RANGE_M))


def hand_axes(keypoints_m: np.ndarray) -> np.ndarray:
    """(3, 3) rows: the wrist frame's axes in the keypoints' frame, x from the wrist to the MCPs' centre (along
    the fingers), y across the MCPs toward the index (the thumb side of a right hand), z = x cross y."""
    wrist, mcps = keypoints_m[0], keypoints_m[[5, 9, 13, 17]]
    x = mcps.mean(0) - wrist
    x /= np.linalg.norm(x)
    y = mcps[0] - mcps[3]
    y -= (y @ x) * x
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)])


def check_urdf(urdf_text: str, source: str) -> None:
    """Refuse a URDF the builder cannot read, naming `source` (its file) and the joint: not XML (cut short), no
    `<robot>`, a joint of no URDF type, a joint whose parent or child link is missing, a limit that is not a finite number or whose lower
    end is above its upper."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as err:
        raise SimBuildError(f"{source} is not a readable URDF ({err}): is the file cut short? Restore it from "
                            "its source") from None  # fmt: skip
    if root.tag != "robot":
        raise SimBuildError(f"{source} is not a URDF: its root element is <{root.tag}>, not <robot>")
    links = {link.get("name") for link in root.iter("link")}
    for joint in root.iter("joint"):
        name = joint.get("name")
        if joint.get("type") not in URDF_JOINT_TYPES:
            raise SimBuildError(f"{source}: joint {name!r} has type {joint.get('type')!r}; a URDF joint is one of "
                                f"{', '.join(URDF_JOINT_TYPES)}")  # fmt: skip
        for end in ("parent", "child"):
            tag = joint.find(end)
            if tag is None or tag.get("link") not in links:
                raise SimBuildError(f"{source}: joint {name!r} names {end} link "
                                    f"{None if tag is None else tag.get('link')!r}, which the file does not have")  # fmt: skip
        limit = joint.find("limit")
        if limit is None or joint.get("type") not in ("revolute", "prismatic"):
            continue
        try:
            lo, hi = (float(limit.get(k, "0")) for k in ("lower", "upper"))
        except ValueError:
            raise SimBuildError(f"{source}: joint {name!r} has limits {limit.get('lower')!r}, {limit.get('upper')!r}, "
                                "not numbers") from None  # fmt: skip
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise SimBuildError(f"{source}: joint {name!r} has limits [{lo}, {hi}] rad; a built joint needs finite "
                                "limits, lower <= upper")  # fmt: skip


def build_mjcf(urdf_text: str, spec: hands.HandSpec, side: str = "right", source: str = "the URDF") -> str:
    """The hand's MJCF (a complete document, no files) from its URDF text and spec (module docstring); a URDF it
    cannot read is one `SimBuildError` naming `source` (`check_urdf`)."""
    check_urdf(urdf_text, source)
    try:
        return _build(urdf_text, spec, side, source)
    except SimBuildError:
        raise
    except ValueError as err:  # MuJoCo's compiler: its message names the element
        raise SimBuildError(f"{source}: MuJoCo cannot compile it ({' '.join(str(err).split())})") from None


def _build(urdf_text: str, spec: hands.HandSpec, side: str, source: str) -> str:
    text, mesh_links, primitive_links = urdf_without_meshes(urdf_text)
    mj = mujoco.MjSpec.from_string(text)
    mj.modelname = f"{spec.embodiment}_{side}"
    model = mj.compile()
    missing = sorted({k.link for k in spec.urdf.keypoints[side]} - {model.body(b).name for b in range(model.nbody)})
    if missing:
        raise SimBuildError(f"{source} has no link {', '.join(missing)}, which hand spec {spec.name!r} places its "
                            "keypoints on: is it the spec's URDF?")  # fmt: skip
    data = mujoco.MjData(model)
    data.qpos[:] = _open_qpos(model)
    mujoco.mj_kinematics(model, data)
    kp = _keypoints(model, data, spec, side)
    radius = capsule_radius_m(kp)
    tips = {spec.urdf.keypoints[side][ids[-1]] for ids in FINGER_KEYPOINTS.values()}
    tip_offset = {k.link: np.asarray(k.offset_m, dtype=np.float64) for k in tips}
    root = model.body(1).name

    def add_capsule(body: mujoco.MjsBody, a: np.ndarray, b: np.ndarray) -> None:
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[*a, *b], size=[radius, 0, 0], mass=0.0,
                      rgba=[0.25, 0.3, 0.35, 1])  # fmt: skip

    for b in range(1, model.nbody):
        name = model.body(b).name
        if name not in mesh_links or name == root:
            continue
        body = mj.body(name)
        children = [c for c in range(model.nbody) if model.body_parentid[c] == b and c != b]
        segments = [(c, model.body_pos[c]) for c in children if np.linalg.norm(model.body_pos[c]) >= MIN_SEGMENT_M]
        for c, end in segments:
            at_tip = model.body(c).name in tip_offset and not np.any(tip_offset[model.body(c).name])
            add_capsule(body, np.zeros(3), end * (1 - radius / np.linalg.norm(end)) if at_tip else end)
        tip = tip_offset.get(name)
        if not segments and tip is not None and np.linalg.norm(tip) > radius:
            add_capsule(body, np.zeros(3), tip * (1 - radius / np.linalg.norm(tip)))
        elif not segments and tip is not None:
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, pos=list(tip), size=[radius, 0, 0], mass=0.0)
    if root not in primitive_links:
        _add_palm_box(mj.body(root), model, data, kp, radius)
    for j in range(model.njnt):  # the same joint dynamics for every hand: the actuator's damping, no friction
        joint = mj.joint(model.joint(j).name)
        joint.armature, joint.damping, joint.frictionloss = ARMATURE, [0.0, 0.0, 0.0], 0.0
        joint.actfrclimited, joint.actfrcrange = 0, [0, 0]
    followers = {model.joint(int(model.eq_obj1id[e])).name for e in range(model.neq)
                 if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT)}  # fmt: skip
    for j in range(model.njnt):
        name = model.joint(j).name
        movable = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        if name in followers or int(model.jnt_type[j]) not in movable:
            continue
        if not model.jnt_limited[j]:
            raise SimBuildError(f"{source}: joint {name!r} has no limits (a continuous joint, or no <limit>): each "
                                "driven joint needs its range (a revolute joint with lower and upper)")  # fmt: skip
        lo, hi = model.jnt_range[j]
        mj.add_actuator(name=f"{name}_drive", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
                        gaintype=mujoco.mjtGain.mjGAIN_FIXED, biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                        gainprm=[KP_NM_PER_RAD] + [0] * 9, biasprm=[0, -KP_NM_PER_RAD, -KV_NMS_PER_RAD] + [0] * 7,
                        ctrlrange=[lo, hi], forcerange=[-TORQUE_NM, TORQUE_NM], forcelimited=1, ctrllimited=1)  # fmt: skip
    _exclude_contacts(mj, spec, side)
    header = (f"<!-- {spec.embodiment} ({side}) built by lerobot_env_unidextok/urdf_model.py (version "
              f"{BUILDER_VERSION}) from {Path(spec.urdf.files[side]).name}; {spec.urdf.source} -->\n")  # fmt: skip
    return header + re.sub(r"^<\?xml[^>]*>\s*", "", mj.to_xml())


def _add_palm_box(body: mujoco.MjsBody, model: mujoco.MjModel, data: mujoco.MjData, kp: np.ndarray,
                  radius: float) -> None:  # fmt: skip
    """A box over the finger bases' span in the palm link's frame (`hand_axes` oriented)."""
    b = model.body(body.name).id
    rot, origin = data.xmat[b].reshape(3, 3), data.xpos[b]
    local = (kp - origin) @ rot  # (21, 3) in the palm link's frame
    axes = hand_axes(local)  # rows x, y, z
    pts = local[[0, 5, 9, 13, 17]] @ axes.T  # wrist and MCPs in the hand axes
    lo = np.array([pts[:, 0].min(), pts[1:, 1].min() - radius, pts[1:, 2].mean() - radius])
    hi = np.array([pts[:, 0].max(), pts[1:, 1].max() + radius, pts[1:, 2].mean() + radius])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.T.ravel())
    body.add_geom(name=f"{body.name}_palm", type=mujoco.mjtGeom.mjGEOM_BOX, size=list((hi - lo) / 2),
                  pos=list(axes.T @ ((hi + lo) / 2)), quat=list(quat), mass=0.0, rgba=[0.25, 0.3, 0.35, 1])  # fmt: skip


def _exclude_contacts(mj: mujoco.MjSpec, spec: hands.HandSpec, side: str) -> None:
    """Exclude body pairs: parent-child, grandparent-grandchild, and every pair touching at the open pose."""
    model = mj.compile()
    pairs = set()
    for b in range(1, model.nbody):
        p = int(model.body_parentid[b])
        if p > 0:
            pairs.add((p, b))
            g = int(model.body_parentid[p])
            if g > 0:
                pairs.add((g, b))
    data = mujoco.MjData(model)
    data.qpos[:] = _open_qpos(model)
    mujoco.mj_forward(model, data)
    for c in data.contact[: data.ncon]:
        a, b = sorted((int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])))
        pairs.add((a, b))
    for a, b in sorted(pairs):
        mj.add_exclude(bodyname1=model.body(a).name, bodyname2=model.body(b).name)


# ---------------------------------------------------------------------------------------------
# the cache
# ---------------------------------------------------------------------------------------------
def cache_dir() -> Path:
    explicit = os.environ.get(CACHE_ENV, "").strip()
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or "~/.cache"
    return Path(base).expanduser() / "unidextok" / "sim"


def model_key(spec: hands.HandSpec, urdf_bytes: bytes, side: str = "right") -> str:
    keypoints = [(k.link, list(k.offset_m)) for k in spec.urdf.keypoints[side]]
    return fingerprint(urdf_bytes, keypoints, BUILDER_VERSION, mujoco.__version__)


def model_xml(spec: hands.HandSpec, side: str = "right") -> str:
    """The spec's built MJCF: built from its URDF when `$UNIDEXTOK_URDF_DIR` holds it; else the model the package
    ships; else built from the URDF in ../shared/data/urdf. A build is read from the cache when made before from
    the same inputs and intact, else built and cached (module docstring)."""
    found, shipped = urdf_path(spec, side), shipped_path(spec, side)
    if shipped is not None and (found is None or not os.environ.get(URDF_DIR_ENV, "").strip()):
        return shipped.read_text()
    if found is None:
        raise SimHandError(f"hand {spec.name!r}: no URDF found under {urdf_dir()} (set {URDF_DIR_ENV}) and no "
                           "built model ships for it")  # fmt: skip
    urdf = found.read_bytes()
    path = cache_dir() / f"{spec.embodiment}_{side}_{model_key(spec, urdf, side)}.xml"
    if path.is_file():
        xml, problem = read_cached(path)
        if problem is None:
            return xml
        logger.warning("rebuilding the cached model %s: %s", path, problem)
    try:
        text = urdf.decode()
    except UnicodeDecodeError:
        raise SimBuildError(f"{found} is not a readable URDF (not UTF-8 text): restore it from its source") from None
    xml = build_mjcf(text, spec, side, source=str(found))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(CACHE_HEADER.format(fingerprint(xml.encode())) + xml)
        os.replace(tmp, path)  # readers see the whole file or none
    except OSError:
        pass  # a read-only cache costs a rebuild next time, nothing else
    return xml


def read_cached(path: Path) -> tuple[str, str | None]:
    """(the model, None) of an intact cached file, else ("", what is wrong with it)."""
    try:
        first, _, xml = path.read_text().partition("\n")
    except (OSError, UnicodeDecodeError) as err:
        return "", f"it cannot be read ({err})"
    expected = CACHE_HEADER.format(fingerprint(xml.encode())).rstrip("\n")
    if not first.startswith(CACHE_HEADER.split("{")[0]):
        return "", "it is not a model this builder wrote (empty, or overwritten)"
    if first != expected:
        return "", "its content does not match the fingerprint it was written with (cut short or edited)"
    return xml, None


__all__ = ["BUILDER_VERSION", "CACHE_ENV", "build_mjcf", "buildable", "cache_dir", "check_urdf", "model_xml",
           "read_cached", "shipped_path", "urdf_path"]  # fmt: skip
