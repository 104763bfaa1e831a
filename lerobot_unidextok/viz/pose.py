"""The hand the viewer draws, as 21 keypoints (m) in the wrist frame of its own side.

Two ways, per hand:
- from the spec (default): UDHM forward kinematics of the state with the spec's skeleton, after bending the
  slots of its coupled joints (``coupled:`` entries with a ``slot``, ratios from the URDF mimic tags): an
  Inspire finger's PIP follows its MCP as on the robot, where the UDHM state holds the MCP only;
- from a URDF (``--urdf``): the robot's own forward kinematics of the native values (mimic joints follow
  their leaders), through the spec's map of URDF links to the 21 keypoints (``urdf:`` block).

Frames: canonical wrist frame of `udhm/frames.py` (x palmar, z distal); a right hand's thumb is on +y, a
left hand is the mirror image (thumb on -y), as `udhm.forward_kinematics(..., side="left")` returns it.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_unidextok import udhm
from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.hands.spec import HandSpec
from lerobot_unidextok.udhm.frames import palm_frame


def coupled_state(spec: HandSpec, states_rad: np.ndarray, side: str) -> np.ndarray:
    """(..., 22) -> (..., 22): ``states_rad`` with every drawn coupling's slot set to
    ``ratio * angle(follows) + offset_rad`` (the leader's native joint angle in radians)."""
    drawn = [c for c in spec.coupled if c.slot is not None]
    states_rad = np.asarray(states_rad, dtype=np.float64)
    if spec.kind != "joints" or not drawn:
        return states_rad
    angles_rad = spec.to_radians(spec.from_udhm(states_rad, side), side)  # (..., J) native joint angles
    out = states_rad.copy()
    for c in drawn:
        out[..., UDHM_INDEX[c.slot]] = c.ratio * angles_rad[..., spec.joint_names.index(c.follows)] + c.offset_rad
    return out


def spec_keypoints_m(spec: HandSpec, states_rad: np.ndarray, side: str) -> np.ndarray:
    """(T, 22) UDHM radians -> (T, 21, 3) keypoints: FK with the spec's skeleton and couplings."""
    return udhm.forward_kinematics(coupled_state(spec, states_rad, side), spec.skeleton(), side=side)


def find_urdf(urdf: str | Path, spec: HandSpec, side: str) -> Path:
    """The URDF file for ``spec``'s ``side`` hand: ``urdf`` itself when it is a file, else the spec's
    ``urdf.file`` under the folder ``urdf`` (as laid out upstream), else that file's name in the folder."""
    path = Path(urdf)
    if spec.urdf is None:
        raise InvalidInputError(
            f"hand {spec.name!r} has no `urdf:` keypoint map in its spec, so --urdf cannot draw it; drop --urdf "
            "or add the map (docs/hands.md)"
        )
    if path.is_file():
        return path
    if not path.is_dir():
        raise MissingInputError(f"--urdf {urdf} is neither a URDF file nor a folder")
    tried = [path / spec.urdf.files[side], path / Path(spec.urdf.files[side]).name]
    for candidate in tried:
        if candidate.is_file():
            return candidate
    raise MissingInputError(
        f"no URDF for the {side} {spec.name} hand under {urdf}: tried {', '.join(str(t) for t in tried)}; "
        "pass the file itself or a folder holding it"
    )


def urdf_keypoints_m(spec: HandSpec, native: np.ndarray, side: str, urdf_path: str | Path) -> np.ndarray:
    """(T, J) native values -> (T, 21, 3) keypoints from the URDF's forward kinematics (mimics followed)."""
    from lerobot_unidextok.hands.check import urdf_cfg, urdf_joint_names
    from lerobot_unidextok.hands.urdf import UrdfHand

    try:
        hand = UrdfHand.load(urdf_path, spec.urdf.keypoints[side])
    except ValueError as err:
        raise ValueError(f"{side} {spec.name} hand: {err}; give the {side} hand's URDF or a folder of both") from err
    names = urdf_joint_names(spec, side, hand)
    angles_rad = spec.to_radians(native, side, on_out_of_range="clip")  # (T, J)
    unique, inverse = np.unique(angles_rad, axis=0, return_inverse=True)  # held poses are posed once
    base = hand.keypoints_m([urdf_cfg(names, q) for q in unique])[inverse.reshape(-1)]  # (T, 21, 3) URDF base frame
    rotation = palm_frame(base[0], side)  # (3, 3) the palm is one rigid link
    return (base - base[:, :1]) @ rotation  # (T, 21, 3) wrist frame of this side
