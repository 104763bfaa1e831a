"""URDF files for retargeting: find the user's file, read its joints, make mimic chains one level deep.

dex-retargeting's mimic adaptor (`kinematics_adaptor.MimicJointKinematicAdaptor`) needs every mimic joint to
follow an optimised joint; some vendor URDFs chain mimics (LinkerHand L10: thumb_ip mimics thumb_mcp, which
mimics thumb_cmc_pitch). `flatten_mimic_chains` rewrites such a chain to follow its root
(`hands.urdf.resolve_mimic_chains`: multiplier m2*m1, offset m2*o1 + o2); the kinematics are unchanged.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.urdf import resolve_mimic_chains


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
