"""DexYCB reader: per-frame `labels_%06d.npz` `joint_3d` of one camera view -> 21 keypoints (m), one hand.

Follows NVlabs/dex-ycb-toolkit `dex_ycb_toolkit/dex_ycb.py` (layout, `meta.yml` fields, `labels_%06d.npz`
keys): `<root>/<subject>/<capture>/{meta.yml, <serial>/labels_%06d.npz}`; handedness from
`meta.yml: mano_sides`; frames whose `joint_3d` is all -1 (no hand) are `valid=False`.

Frame rate: the toolkit never states one. The same authors' NVlabs/handover-sim replays DexYCB captures
with `_TIME_STEP_RAW = 0.04` s between raw frames (`handover/dex_ycb.py`), i.e. **25 fps**, which is the
default here (`fps=` overrides it).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.errors import SourceFormatError

DEXYCB_FPS = 25.0  # NVlabs/handover-sim handover/dex_ycb.py: _TIME_STEP_RAW = 0.04 s per raw DexYCB frame
# DexYCB object ids 1..21 (dex-ycb-toolkit `_YCB_CLASSES`), for the task text.
YCB_CLASSES = (
    "002_master_chef_can", "003_cracker_box", "004_sugar_box", "005_tomato_soup_can", "006_mustard_bottle",
    "007_tuna_fish_can", "008_pudding_box", "009_gelatin_box", "010_potted_meat_can", "011_banana",
    "019_pitcher_base", "021_bleach_cleanser", "024_bowl", "025_mug", "035_power_drill", "036_wood_block",
    "037_scissors", "040_large_marker", "051_large_clamp", "052_extra_large_clamp", "061_foam_brick",
)  # fmt: skip


class DexYCBFormatError(SourceFormatError):
    """A DexYCB file is missing, truncated or lacks a field; the message names both."""


def _object_name(ycb_id: int) -> str:
    if 1 <= ycb_id <= len(YCB_CLASSES):
        return YCB_CLASSES[ycb_id - 1].split("_", 1)[1].replace("_", " ")
    return f"object {ycb_id}"


@register_source("dexycb")
class DexYCBSource:
    license = "CC BY-NC 4.0 (DexYCB; non-commercial research use)"
    description = "DexYCB hand-object grasps: MANO-21 keypoints from labels_*.npz joint_3d (human, one hand)"
    sides = ("right", "left")  # block layout: sequences are right- or left-handed, so both blocks exist

    def __init__(self, view: int | str = 0, fps: float = DEXYCB_FPS) -> None:
        self.view = view  # camera index into meta.yml serials, or a serial string
        self.fps = float(fps)

    def list_episodes(self, input_path: str | Path) -> list[str]:
        root = Path(input_path)
        if not root.is_dir():
            raise FileNotFoundError(f"DexYCB input {root} is not a directory")
        captures = sorted(str(p.parent) for p in root.glob("*/*/meta.yml"))
        if not captures and (root / "meta.yml").is_file():
            captures = [str(root)]
        if not captures:
            raise DexYCBFormatError(
                f"{root}: no <subject>/<capture>/meta.yml found; point --input at the DexYCB root folder"
            )
        return captures

    def read_episode(self, ref: str) -> RawEpisode:
        capture = Path(ref)
        meta = _read_meta(capture / "meta.yml")
        serials = [str(s) for s in meta["serials"]]
        serial = self.view if isinstance(self.view, str) and not str(self.view).isdigit() else None
        if serial is None:
            idx = int(self.view)
            if not 0 <= idx < len(serials):
                raise DexYCBFormatError(f"{capture / 'meta.yml'}: view {idx} out of range for serials {serials}")
            serial = serials[idx]
        elif serial not in serials:
            raise DexYCBFormatError(f"{capture / 'meta.yml'}: view serial {serial!r} not in serials {serials}")
        num_frames = int(meta["num_frames"])
        keypoints = np.empty((num_frames, 21, 3), dtype=np.float64)
        for t in range(num_frames):
            keypoints[t] = _read_joint_3d(capture / serial / f"labels_{t:06d}.npz")
        valid = ~np.all(keypoints == -1.0, axis=(1, 2))
        sides = meta["mano_sides"]
        if not isinstance(sides, list) or len(sides) != 1 or sides[0] not in ("right", "left"):
            raise DexYCBFormatError(f"{capture / 'meta.yml'}: mano_sides must be ['right'] or ['left'], got {sides!r}")
        task = ""
        ycb_ids, grasp = meta.get("ycb_ids"), meta.get("ycb_grasp_ind")
        if isinstance(ycb_ids, list) and isinstance(grasp, int) and 0 <= grasp < len(ycb_ids):
            task = f"grasp the {_object_name(int(ycb_ids[grasp]))}"
        hand = HandStream(side=sides[0], hand="human", state_native=keypoints, valid=valid)
        return RawEpisode(
            source_file=str(capture),
            fps=self.fps,
            hands=[hand],
            task=task,
            extra={"serial": serial, "subject": capture.parent.name, "capture": capture.name},
        )


def _read_meta(path: Path) -> dict:
    import yaml

    try:
        meta = yaml.safe_load(path.read_text())
    except FileNotFoundError as exc:
        raise DexYCBFormatError(f"{path}: missing") from exc
    except yaml.YAMLError as exc:
        raise DexYCBFormatError(f"{path}: not valid YAML ({exc})") from exc
    if not isinstance(meta, dict):
        raise DexYCBFormatError(f"{path}: expected a mapping, got {type(meta).__name__}")
    for key in ("serials", "num_frames", "mano_sides"):
        if key not in meta:
            raise DexYCBFormatError(f"{path}: missing field {key!r}")
    return meta


def _read_joint_3d(path: Path) -> np.ndarray:
    try:
        with np.load(path) as npz:
            if "joint_3d" not in npz.files:
                raise DexYCBFormatError(f"{path}: missing field 'joint_3d' (fields: {npz.files})")
            joint_3d = npz["joint_3d"]
    except FileNotFoundError as exc:
        raise DexYCBFormatError(f"{path}: missing (meta.yml num_frames counts more frames)") from exc
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        if isinstance(exc, DexYCBFormatError):
            raise
        raise DexYCBFormatError(f"{path}: unreadable or truncated npz, field 'joint_3d' ({exc})") from exc
    if joint_3d.shape != (1, 21, 3):
        raise DexYCBFormatError(f"{path}: field 'joint_3d' has shape {joint_3d.shape}, expected (1, 21, 3)")
    return joint_3d[0]
