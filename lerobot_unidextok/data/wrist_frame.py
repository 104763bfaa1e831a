"""A dataset's wrist frame: where each hand's fingers close, relative to the wrist pose its state and action hold.

A robot's wrist command says where its wrist goes; each hand's fingers close at another point relative to that
wrist. A policy that learns "wrist to object" from a few hands puts a new hand's wrist where theirs went, and
its fingers close elsewhere. Expressing the wrist position of state and action as the position of the hand's
grasp centre instead (`processor/wrist_frame.py`) lets it learn "grasp centre to object"; each robot's own
offset turns the prediction back into its wrist command. What that needs, recorded with the data:

    {"columns": ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw"],
     "rotation": "Rz(yaw) Ry(pitch) Rx(roll)",
     "grasp_centre_in_wrist_m": {"<hand spec>": [x, y, z]}}

- `columns`: the 6 wrist-pose columns of `observation.state` and `action` (position in m, then roll, pitch, yaw
  in rad), by name;
- `rotation`: how roll, pitch, yaw make the wrist's rotation in the world (`ROTATION`, the only one read);
- `grasp_centre_in_wrist_m`: per hand, the grasp centre in the wrist frame of those columns (m).

The simulator's recorder (`lerobot_env_unidextok/record.py`) writes it as `meta/unidextok_wrist_frame.json` into
the LeRobot dataset it records; `unidextok-convert --source=lerobot` carries it into the conversion record
(`ConversionRecord.wrist_frame`), `unidextok-mix` gathers it per input hand. A dataset without it has no frame.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.utils.number_checks import NumberError, checked_numbers

ROTATION = "Rz(yaw) Ry(pitch) Rx(roll)"  # world <- wrist, from the columns' roll, pitch, yaw
WRIST_FRAME_PATH = "meta/unidextok_wrist_frame.json"  # in a recorded (not converted) LeRobot dataset
NUM_COLUMNS = 6
MAX_CENTRE_M = 0.3  # a hand's fingers close within this distance of its wrist (the largest hands: ~0.15 m)


class WristFrameError(InvalidInputError):
    """A wrist frame that cannot be used; the message names the field and the fix."""


def check_centre(hand: str, value: Any, where: str) -> list[float]:
    """`value` as a grasp centre (3 finite numbers, m, within MAX_CENTRE_M of the wrist), or a WristFrameError
    naming `where` and the hand (`utils/number_checks.py`)."""
    fix = "give x, y, z in m in the wrist frame (a value typed in mm is 1000x)"
    try:
        return checked_numbers(value, f"{where}: the grasp centre of {hand!r}", length=3, max_abs=MAX_CENTRE_M,
                               unit="m", fix=fix)  # fmt: skip
    except NumberError as err:
        raise WristFrameError(str(err)) from None


@dataclass
class WristFrame:
    """The wrist columns, their rotation convention and the grasp centre per hand (module docstring)."""

    columns: list[str]
    rotation: str = ROTATION
    grasp_centre_in_wrist_m: dict[str, list[float]] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: dict[str, Any], where: str) -> WristFrame:
        """A checked frame from its JSON form; `where` names the file or record in errors."""
        if not isinstance(data, dict):
            raise WristFrameError(f"{where}: a wrist frame is a mapping, got {type(data).__name__}")
        columns = data.get("columns")
        if not isinstance(columns, list) or len(columns) != NUM_COLUMNS or len(set(columns)) != NUM_COLUMNS:
            raise WristFrameError(
                f"{where}: 'columns' must name the {NUM_COLUMNS} wrist-pose columns (x, y, z, roll, pitch, yaw), "
                f"got {columns!r}"
            )
        rotation = data.get("rotation", ROTATION)
        if rotation != ROTATION:
            raise WristFrameError(f"{where}: rotation {rotation!r} is not read; only {ROTATION!r} is")
        centres = data.get("grasp_centre_in_wrist_m") or {}
        if not isinstance(centres, dict):
            raise WristFrameError(f"{where}: 'grasp_centre_in_wrist_m' maps hand spec -> [x, y, z], got {centres!r}")
        return cls([str(c) for c in columns], rotation,
                   {str(h): check_centre(h, v, where) for h, v in centres.items()})  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        return {"columns": list(self.columns), "rotation": self.rotation,
                "grasp_centre_in_wrist_m": {h: list(v) for h, v in self.grasp_centre_in_wrist_m.items()}}  # fmt: skip

    def missing_columns(self, *name_lists: list[str]) -> list[str]:
        """The wrist columns absent from any of `name_lists`."""
        return [c for c in self.columns if any(c not in names for names in name_lists)]

    def renamed(self, rename: dict[str, str]) -> WristFrame:
        return WristFrame([rename.get(c, c) for c in self.columns], self.rotation, dict(self.grasp_centre_in_wrist_m))


def read_recorded(root: str | Path) -> WristFrame | None:
    """The frame a recorder wrote into the LeRobot dataset at `root` (None: it wrote none)."""
    path = Path(root) / WRIST_FRAME_PATH
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise WristFrameError(f"{path} is not valid JSON ({err}); record the dataset again, or delete it") from err
    return WristFrame.from_dict(data, str(path))


def write_recorded(root: str | Path, frame: WristFrame) -> Path:
    """Write `frame` into the LeRobot dataset at `root`, checked as `read_recorded` will read it."""
    path = Path(root) / WRIST_FRAME_PATH
    WristFrame.from_dict(frame.to_dict(), f"the wrist frame for {path}")
    path.write_text(json.dumps(frame.to_dict(), indent=1))
    return path


def merge_frames(frames: list[WristFrame], where: str) -> WristFrame | None:
    """One frame of several inputs' (same columns and rotation; one centre per hand), or None for none."""
    if not frames:
        return None
    first = frames[0]
    centres: dict[str, list[float]] = {}
    for f in frames:
        if f.columns != first.columns or f.rotation != first.rotation:
            raise WristFrameError(
                f"{where}: the inputs name their wrist columns differently ({first.columns} vs {f.columns}): map "
                "them to common names with --name_map"
            )
        for hand, centre in f.grasp_centre_in_wrist_m.items():
            if hand in centres and not np.allclose(centres[hand], centre, atol=1e-6):
                raise WristFrameError(
                    f"{where}: hand {hand!r} has two grasp centres ({centres[hand]} and {centre}): its inputs were "
                    "recorded with different hand models; record them again with one"
                )
            centres[hand] = list(centre)
    return WristFrame(list(first.columns), first.rotation, centres)


__all__ = ["ROTATION", "WRIST_FRAME_PATH", "WristFrame", "WristFrameError", "check_centre", "merge_frames",
           "read_recorded", "write_recorded"]  # fmt: skip
