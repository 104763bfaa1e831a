"""EgoDex reader: one HDF5 per episode, ARKit `transforms/<joint>` (N,4,4) -> 21 keypoints (m) per hand.

Follows apple/ml-egodex `simple_dataset.py` (`SimpleDataset.__getitem__`): transforms in the ARKit world
frame, optional `confidences/`, and the task text chosen as Apple's loader chooses it: for
`llm_type == 'reversible'` tasks (recorded both ways) `llm_description` when `which_llm_description` is
'1', else `llm_description2`; otherwise `llm_description`. (Attributes are compared as text, so an integer
1 counts as '1'.) 30 Hz pose.

Both hands per file. Keypoints are the translations of the 21 hand joints in the ARKit world frame
(joint angles do not depend on the frame). `confidences/<joint>` are optional: when present, frames
whose lowest hand-joint confidence is <= `min_confidence` are `valid=False`. Needs `h5py` (egodex extra).

The joints are visionOS ARKit's `HandSkeleton` joints under EgoDex's names (apple/ml-egodex `skeleton_tfs.py`:
`<side>Hand` is the wrist, `<side><Finger>Metacarpal` / `Knuckle` / `IntermediateBase` / `IntermediateTip` /
`Tip`, the thumb without a metacarpal). The `*Metacarpal` joints (the bases of the metacarpals) are not read:
UDHM's zero of abduction is the knuckle row (`udhm/frames.py`), which every tracker has, so an EgoDex hand and
the same hand from MediaPipe or MANO give one UDHM reading wherever ARKit puts its wrist point.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.errors import SourceFormatError
from lerobot_unidextok.utils.imports import require_package

EGODEX_FPS = 30.0
FINGERS = ("Index", "Middle", "Ring", "Little")
# MANO-21 order -> EgoDex joint name without the side prefix (thumb: Knuckle ~ CMC, no metacarpal).
KEYPOINT_JOINTS: tuple[str, ...] = (
    "Hand",
    "ThumbKnuckle", "ThumbIntermediateBase", "ThumbIntermediateTip", "ThumbTip",
    *(f"{f}Finger{p}" for f in FINGERS for p in ("Knuckle", "IntermediateBase", "IntermediateTip", "Tip")),
)  # fmt: skip


def task_text(attrs) -> str:
    """The episode's instruction as Apple's loader picks it (module docstring); `task` when no description."""
    if _text(attrs.get("llm_type")) == "reversible":
        key = "llm_description" if _text(attrs.get("which_llm_description")).strip() == "1" else "llm_description2"
    else:
        key = "llm_description"
    return _text(attrs.get(key)).strip() or _text(attrs.get("task")).strip()


def _text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        value = value.item()
    return str(value)


class EgoDexFormatError(SourceFormatError):
    """An EgoDex file is truncated or lacks a dataset/attribute; the message names both."""


@register_source("egodex")
class EgoDexSource:
    license = "CC BY-NC-ND 4.0 (EgoDex; research use)"
    description = "EgoDex egocentric manipulation: ARKit hand skeletons -> MANO-21 keypoints (human, both hands)"

    def __init__(self, min_confidence: float = 0.0, sides: tuple[str, ...] = ("left", "right")) -> None:
        self.min_confidence = float(min_confidence)
        bad = [s for s in sides if s not in ("left", "right")]
        if bad or not sides:
            raise ValueError(f"sides must be a non-empty subset of ('left', 'right'), got {sides!r}")
        self.sides = tuple(sides)

    def list_episodes(self, input_path: str | Path) -> list[str]:
        root = Path(input_path)
        if root.is_file() and root.suffix == ".hdf5":
            return [str(root)]
        if not root.is_dir():
            raise FileNotFoundError(f"EgoDex input {root} is not a directory or .hdf5 file")
        files = sorted(str(p) for p in root.rglob("*.hdf5"))
        if not files:
            raise EgoDexFormatError(f"{root}: no *.hdf5 episodes found (expected <part>/<task>/<i>.hdf5)")
        return files

    def read_episode(self, ref: str) -> RawEpisode:
        h5py = require_package("h5py", "egodex", purpose="the egodex source (HDF5 files)")
        path = Path(ref)
        try:
            f = h5py.File(path, "r")
        except FileNotFoundError as exc:
            raise EgoDexFormatError(f"{path}: missing") from exc
        except OSError as exc:
            raise EgoDexFormatError(f"{path}: unreadable or truncated HDF5 ({exc})") from exc
        with f:
            if "transforms" not in f:
                raise EgoDexFormatError(f"{path}: missing group 'transforms'")
            hands = [self._read_hand(f, path, side) for side in self.sides]
            lengths = {h.state_native.shape[0] for h in hands}
            if len(lengths) != 1:
                raise EgoDexFormatError(f"{path}: hands have different frame counts {sorted(lengths)}")
            task = task_text(f.attrs)
            extra = {
                k: _attr(f.attrs[k])
                for k in ("task", "llm_type", "which_llm_description", "environment", "object", "session_name")
                if k in f.attrs
            }
        return RawEpisode(source_file=str(path), fps=EGODEX_FPS, hands=hands, task=task, extra=extra)

    def _read_hand(self, f, path: Path, side: str) -> HandStream:
        keypoints, confidences = [], []
        for joint in KEYPOINT_JOINTS:
            name = f"{side}{joint}"
            field = f"transforms/{name}"
            if name not in f["transforms"]:
                raise EgoDexFormatError(f"{path}: missing dataset {field!r}")
            pose = _read(f, path, field)
            if pose.ndim != 3 or pose.shape[1:] != (4, 4):
                raise EgoDexFormatError(f"{path}: {field!r} has shape {pose.shape}, expected (N, 4, 4)")
            keypoints.append(pose[:, :3, 3])
            if "confidences" in f and name in f["confidences"]:
                confidences.append(_read(f, path, f"confidences/{name}").reshape(-1))
        state = np.stack(keypoints, axis=1).astype(np.float64)  # (T, 21, 3)
        valid = None
        if confidences:  # optional in EgoDex; all-or-nothing per hand
            if len(confidences) != len(KEYPOINT_JOINTS):
                raise EgoDexFormatError(
                    f"{path}: confidences/ holds {len(confidences)} of the {len(KEYPOINT_JOINTS)} {side} hand joints"
                )
            conf = np.stack(confidences, axis=1)  # (T, 21)
            if conf.shape[0] != state.shape[0]:
                raise EgoDexFormatError(
                    f"{path}: confidences/{side}* have {conf.shape[0]} frames, transforms {state.shape[0]}"
                )
            valid = conf.min(axis=1) > self.min_confidence
        return HandStream(side=side, hand="human", state_native=state, valid=valid)


def _read(f, path: Path, field: str) -> np.ndarray:
    try:
        return np.asarray(f[field][()], dtype=np.float64)
    except (OSError, KeyError, ValueError) as exc:
        raise EgoDexFormatError(f"{path}: cannot read {field!r} (truncated file?) ({exc})") from exc


def _attr(value: object) -> object:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value if isinstance(value, (str, int, float, bool)) else str(value)
