"""Per-episode JSON dumps of ROS topics (LET, LinkerHand): loading and strict field access."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def load_json(path: Path, error: type[ValueError]) -> dict:
    """The JSON object in `path`; `error` names the file when it is missing or truncated."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError as exc:
        raise error(f"{path}: missing") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid JSON, truncated? ({exc})") from exc
    if not isinstance(data, dict):
        raise error(f"{path}: expected a JSON object, got {type(data).__name__}")
    return data


def field(data: dict, key: str, path: Path, error: type[ValueError], where: str = "") -> dict:
    """`data[key]`, or `error` naming the file and the field."""
    if not isinstance(data, dict) or key not in data:
        raise error(f"{path}: missing field {(where + '.' if where else '')}{key!r}")
    return data[key]


def array_field(
    error: type[ValueError], data: dict, key: str, path: Path, where: str, ndim: int, width: int | None = None
) -> np.ndarray:
    """`data[key]` as a float64 array of `ndim` dims (and `width` columns); strict."""
    if key not in data:
        raise error(f"{path}: missing field {where}.{key!r}")
    try:
        values = np.asarray(data[key], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise error(f"{path}: field {where}.{key!r} is not numeric or is ragged ({exc})") from exc
    if values.ndim != ndim or len(values) == 0 or (width is not None and values.shape[1] != width):
        shape = f"(T, {width})" if width else ("(T, D)" if ndim == 2 else "(T,)")
        raise error(f"{path}: field {where}.{key!r} has shape {values.shape}, expected {shape}")
    return values


def fps_from_stamps(stamps: np.ndarray, path: Path, error: type[ValueError]) -> float:
    """Frame rate from the median stamp step (s); stamps must increase."""
    dt = np.diff(stamps)
    if dt.size == 0 or not np.all(dt > 0):
        raise error(f"{path}: stamp_s must increase strictly to derive fps; pass fps= explicitly")
    return float(round(1.0 / float(np.median(dt)), 3))
