"""Hand-tracking keypoints as a source: the files MediaPipe / HaMeR / WiLoR / ARKit pipelines leave behind.

One episode per file under `--input`:

- `.npy`: one hand, `(T, 21, 3)` keypoints in MANO-21 / MediaPipe order (the same order). Side and fps
  from a sidecar `<stem>.json` (`{"side": "right", "fps": 30}`), else (side) a `left` / `right` token in
  the file name, else the options `side` / `fps`.
- `.npz`: one key per hand, `(T, 21, 3)`, named with its side (`right`, `left_hand`, `kp_left`, ...) or
  mapped by the option `keys={"hand_r": "right"}`; optional scalar keys `fps` and `side` (for a single hand).
- `.json`: MediaPipe HandLandmarker results, one entry per frame, as the Python API names them
  (`handedness` / `hand_world_landmarks`, google-ai-edge/mediapipe `tasks/python/vision/hand_landmarker.py`
  `HandLandmarkerResult`) or as the web API does (`handednesses` / `worldLandmarks`), each landmark
  `{"x", "y", "z"}`; a list of frames, or `{"fps": 30, "frames": [...]}`. World landmarks are metres;
  normalised image landmarks are refused (no metric scale). MediaPipe's handedness labels assume a
  mirrored selfie image in older versions (the label swap of August 2023): `swap_handedness=true` flips them.

Frame rate: the file's own (sidecar / npz `fps` / JSON `fps`), else the option `fps`. LeRobot stores one
integer fps, and trackers record at 29.97 Hz or 54-115 Hz: a file whose rate differs from the output
rate is resampled onto it by linear interpolation (`_resample`, the mechanism the ROS bag readers use;
frames next to an undetected frame stay absent). The output rate is `fps` (`--fps`) when given, else the
file's rate rounded to an integer (29.97 -> 30). Each episode records `source_fps` and `resampled_fps`.

Trackers disagree on where the wrist landmark sits (MediaPipe's is annotated on images, MANO's is its root
joint, OpenXR / WebXR put it on the forearm's twist axis); UDHM's abductions do not depend on it
(`udhm/frames.py`, docs/conversion.md "Human keypoints"), so any of them can be given as keypoint 0.

Checks, per file: units (the wrist -> middle-knuckle length of an adult hand is 6-14 cm; millimetre or
centimetre files need `units="mm"` / `"cm"`), handedness (the UDHM inverse kinematics of a sample of
frames must fit the stated side better than the mirrored one, else the file says which side it looks
like; `check_handedness=false` skips it), and frames with NaN or no detection become absent frames.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import json
import logging
import re
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.converters import _resample
from lerobot_unidextok.errors import SourceFormatError

logger = logging.getLogger(__name__)

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
PALM_M = (0.06, 0.14)  # plausible wrist -> middle MCP length (m), adult hands (MediaPipe medians ~97 mm)
SIDE_TOKEN = re.compile(r"(?:^|[^a-z])(left|right)(?:[^a-z]|$)")
HANDEDNESS_FRAMES = 24  # frames fitted with both sides for the handedness check


class KeypointsFormatError(SourceFormatError):
    """A keypoint file is unreadable, has the wrong shape, units or handedness; the message names it."""


def side_from_name(name: str) -> str | None:
    found = {m.group(1) for m in SIDE_TOKEN.finditer(name.lower().replace("_", " "))}
    return found.pop() if len(found) == 1 else None


def _mediapipe_frames(data, path: Path) -> tuple[list, float | None]:
    if isinstance(data, dict) and "frames" in data:
        return list(data["frames"]), data.get("fps")
    if isinstance(data, list):
        return data, None
    raise KeypointsFormatError(f"{path}: expected a list of MediaPipe results or {{'fps', 'frames'}}")


def _landmarks(entry) -> np.ndarray:
    return np.array([[p["x"], p["y"], p["z"]] for p in entry], dtype=np.float64)


def read_mediapipe_json(path: Path, swap: bool) -> tuple[dict[str, np.ndarray], float | None]:
    """{side: (T, 21, 3) world landmarks, NaN where that hand is not detected} and the file's fps."""
    try:
        frames, fps = _mediapipe_frames(json.loads(path.read_text()), path)
    except json.JSONDecodeError as exc:
        raise KeypointsFormatError(f"{path}: not valid JSON, truncated? ({exc})") from exc
    out = {s: np.full((len(frames), 21, 3), np.nan) for s in ("left", "right")}
    for t, frame in enumerate(frames):
        world = frame.get("hand_world_landmarks", frame.get("worldLandmarks"))
        labels = frame.get("handedness", frame.get("handednesses"))
        if world is None:
            if frame.get("hand_landmarks") or frame.get("landmarks"):
                raise KeypointsFormatError(
                    f"{path}: frame {t} has only normalised image landmarks; the keypoints source needs "
                    "hand_world_landmarks (metres)"
                )
            continue
        if labels is None or len(labels) != len(world):
            raise KeypointsFormatError(f"{path}: frame {t} has {len(world)} hands but no matching handedness")
        for hand, label in zip(world, labels, strict=True):
            category = (label[0] if isinstance(label, list) else label) or {}
            name = str(category.get("category_name", category.get("categoryName", ""))).lower()
            if name not in ("left", "right"):
                raise KeypointsFormatError(f"{path}: frame {t} handedness {category!r} is not Left/Right")
            side = {"left": "right", "right": "left"}[name] if swap else name
            points = _landmarks(hand)
            if points.shape != (21, 3):
                raise KeypointsFormatError(f"{path}: frame {t} has {points.shape[0]} landmarks, expected 21")
            out[side][t] = points
    return {s: v for s, v in out.items() if np.isfinite(v).any()}, fps


@register_source("keypoints")
class KeypointsSource:
    license = "as the keypoint files' own source (tracker outputs of your recordings)"
    description = "hand-tracking keypoints: .npy / .npz (T, 21, 3) or MediaPipe JSON landmark results (human)"
    sides = ("right", "left")  # single-hand files are left or right: both blocks exist, the absent one masked

    def __init__(
        self,
        side: str | None = None,
        fps: int | None = None,
        units: str = "m",
        keys: dict[str, str] | None = None,
        swap_handedness: bool = False,
        check_handedness: bool = True,
    ) -> None:
        if side not in (None, "left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        if units not in UNITS:
            raise ValueError(f"units must be one of {sorted(UNITS)}, got {units!r}")
        if fps is not None and (int(fps) != fps or fps <= 0):
            raise ValueError(f"fps must be a positive integer, got {fps!r}")
        bad = {k: v for k, v in (keys or {}).items() if v not in ("left", "right")}
        if bad:
            raise ValueError(f"keys must map npz keys to 'left' or 'right', got {bad}")
        self.side, self.fps, self.units, self.keys = side, fps, units, dict(keys or {})
        self.swap, self.check = swap_handedness, check_handedness

    def list_episodes(self, input_path: str | Path) -> list[str]:
        root = Path(input_path)
        files = (
            [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.suffix in (".npy", ".npz", ".json"))
        )
        stems = {p.with_suffix("") for p in files if p.suffix in (".npy", ".npz")}
        episodes = [str(p) for p in files if not (p.suffix == ".json" and p.with_suffix("") in stems)]
        episodes = [e for e in episodes if Path(e).name not in ("gestures.json",)]
        if not episodes:
            raise KeypointsFormatError(f"{root}: no .npy, .npz or MediaPipe .json keypoint files found")
        return episodes

    def read_episode(self, ref: str) -> RawEpisode:
        path = Path(ref)
        meta = self._sidecar(path)
        fps = meta.get("fps")
        if path.suffix == ".json":
            by_side, fps_file = read_mediapipe_json(path, self.swap)
            fps = fps or fps_file
        elif path.suffix == ".npz":
            by_side, fps_file = self._npz(path, meta)
            fps = fps or fps_file
        else:
            try:
                values = np.load(path, allow_pickle=False)
            except (OSError, ValueError, EOFError) as exc:  # numpy: "cannot reshape array" for a cut-short file
                raise KeypointsFormatError(
                    f"{path}: not a readable .npy file ({exc}): truncated (a copy cut short?) or another format; "
                    "write it again with numpy.save"
                ) from exc
            by_side = {self._side(path, meta): self._array(values, path, "array")}
        by_side = {side: _constant_frames_missing(kp, path, side) for side, kp in by_side.items()}
        by_side = {side: kp for side, kp in by_side.items() if np.isfinite(kp).any()}
        fps = float(fps or self.fps or 0)
        if not fps > 0:
            raise KeypointsFormatError(f"{path}: no frame rate: add {{'fps': ...}} to {path.stem}.json or pass fps=")
        if not by_side:
            raise KeypointsFormatError(f"{path}: no hand detected in any frame")
        out_fps = int(self.fps or round(fps))
        record = {}
        if out_fps != fps:
            by_side = {side: resample_keypoints(kp, fps, out_fps, path) for side, kp in by_side.items()}
            record = {"source_fps": fps, "resampled_fps": out_fps}
        hands = []
        for side, kp in by_side.items():
            kp = kp * UNITS[self.units]
            valid = np.isfinite(kp).all(axis=(1, 2))
            _check_units(kp[valid], path, side, self.units)
            if self.check:
                _check_handedness(kp[valid], path, side)
            hands.append(
                HandStream(side=side, hand="human", state_native=np.where(valid[:, None, None], kp, 0.0), valid=valid)
            )
        task = str(meta.get("task", ""))
        return RawEpisode(source_file=str(path), fps=float(out_fps), hands=hands, task=task, source_episode=record)

    # ----------------------------------------------------------------------------------------- #
    def _sidecar(self, path: Path) -> dict:
        sidecar = path.with_suffix(".json")
        if path.suffix == ".json" or not sidecar.is_file():
            return {}
        try:
            return json.loads(sidecar.read_text())
        except json.JSONDecodeError as exc:
            raise KeypointsFormatError(f"{sidecar}: not valid JSON ({exc})") from exc

    def _side(self, path: Path, meta: dict) -> str:
        side = meta.get("side") or side_from_name(path.stem) or self.side  # the file says it first
        if side not in ("left", "right"):
            raise KeypointsFormatError(
                f"{path}: which hand? add {{'side': 'left'|'right'}} to {path.stem}.json, pass side=, or name the file *_left / *_right"
            )
        return side

    def _array(self, values: np.ndarray, path: Path, what: str) -> np.ndarray:
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 3 or values.shape[1:] != (21, 3) or len(values) == 0:
            raise KeypointsFormatError(
                f"{path}: {what} has shape {values.shape}, expected (T, 21, 3) MANO-21 keypoints"
            )
        return values

    def _npz(self, path: Path, meta: dict) -> tuple[dict[str, np.ndarray], float | None]:
        try:
            npz = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise KeypointsFormatError(f"{path}: unreadable npz ({exc})") from exc
        with npz:
            fps = float(npz["fps"]) if "fps" in npz.files else None
            arrays = {k: npz[k] for k in npz.files if npz[k].ndim == 3}
            file_side = str(npz["side"]) if "side" in npz.files else None
        out = {}
        for key, values in arrays.items():
            side = (
                self.keys.get(key)
                or side_from_name(key)
                or (file_side or meta.get("side") or self.side if len(arrays) == 1 else None)
            )
            if side is None:
                raise KeypointsFormatError(
                    f"{path}: key {key!r}: which hand? name it *left* / *right* or pass keys={{{key!r}: 'right'}}"
                )
            if side in out:
                raise KeypointsFormatError(f"{path}: two keys hold the {side} hand")
            out[side] = self._array(values, path, f"key {key!r}")
        return out, fps


def _constant_frames_missing(kp: np.ndarray, path: Path, side: str) -> np.ndarray:
    """`kp` with frames whose 21 keypoints all coincide (a constant fill such as DexYCB's -1, or zeros, where
    the tracker saw no hand) set to NaN, the keypoint files' mark of a missing frame; said once per file."""
    flat = kp.reshape(len(kp), -1)
    filled = np.isfinite(flat).all(axis=1) & (np.ptp(flat, axis=1) == 0)
    if not filled.any():
        return kp
    values = sorted({float(v) for v in flat[filled, 0]})[:3]
    logger.warning(
        "%s: %s hand: %d of %d frames hold 21 coincident keypoints (value %s: a fill where no hand was seen, as "
        "DexYCB's -1) and are read as missing frames; NaN marks a missing frame in keypoint files", path, side,
        int(filled.sum()), len(kp), ", ".join(f"{v:g}" for v in values),
    )  # fmt: skip
    out = kp.astype(np.float64, copy=True)
    out[filled] = np.nan
    return out


def resample_keypoints(kp: np.ndarray, fps: float, out_fps: int, path: Path) -> np.ndarray:
    """(T, 21, 3) keypoints sampled at `fps` -> (T', 21, 3) on a grid of `out_fps` over the same span,
    linear; NaN (undetected) frames stay NaN and make the grid frames next to them NaN."""
    if len(kp) < 2:
        return kp
    stream = _resample.Stream(f"keypoints@{fps:g}Hz", np.arange(len(kp)) / fps, kp.reshape(len(kp), -1))
    grid = _resample.grid_for([stream], out_fps, path)
    return _resample.resample(stream, grid, "linear").reshape(len(grid), 21, 3)


def _check_units(kp: np.ndarray, path: Path, side: str, units: str) -> None:
    if not len(kp):
        return
    palm = float(np.median(np.linalg.norm(kp[:, 9] - kp[:, 0], axis=-1)))
    if PALM_M[0] <= palm <= PALM_M[1]:
        return
    for name, scale in UNITS.items():
        if PALM_M[0] <= palm * scale / UNITS[units] <= PALM_M[1] and name != units:
            raise KeypointsFormatError(
                f"{path}: {side} hand wrist -> middle knuckle is {palm:.4g} {units}-scaled units, a hand in {name}: "
                f"pass units={name!r}"
            )
    raise KeypointsFormatError(
        f"{path}: {side} hand wrist -> middle knuckle is {palm:.4g} m, not an adult hand (6-14 cm): not metric "
        "keypoints (normalised image coordinates?) or not MANO-21 / MediaPipe order"
    )


def _check_handedness(kp: np.ndarray, path: Path, side: str) -> None:
    """The stated side must fit the UDHM inverse kinematics better than the mirrored hand."""
    if len(kp) == 0:
        return
    from lerobot_unidextok import udhm

    sample = kp[np.linspace(0, len(kp) - 1, min(HANDEDNESS_FRAMES, len(kp))).round().astype(int)]
    other = "left" if side == "right" else "right"
    errors = {}
    try:
        for s in (side, other):
            errors[s] = float(np.nanmean(udhm.inverse_kinematics(sample, side=s).residual_m))
    except udhm.KeypointFramesError:
        return  # frames no hand can take: the conversion's inverse kinematics names each by its frame number

    if errors[other] < 0.5 * errors[side]:
        raise KeypointsFormatError(
            f"{path}: labelled {side} but the keypoints fit a {other} hand ({errors[other] * 1000:.1f} mm vs "
            f"{errors[side] * 1000:.1f} mm): fix the side, pass swap_handedness=true for MediaPipe's mirrored "
            "labels, or check_handedness=false"
        )
