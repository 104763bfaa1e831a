"""Resampling time-stamped streams onto one fixed frame grid (LeRobot stores one integer fps).

Shared by every reader of time-stamped data: the ROS bag readers (`_rosbag`: LET, LinkerHand; jittered
topic stamps) and the keypoints reader (tracker files at 29.97 Hz or 54-115 Hz). A stream is
(stamps, values); `grid_for` lays frames every 1/fps over the span all given streams cover; `resample`
takes the **nearest** sample (commands: a command holds) or interpolates **linearly** (measured states,
keypoints). Linear interpolation keeps NaN: a grid frame between a sample and a NaN sample is NaN (an
absent hand stays absent, never bridged).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.errors import SourceFormatError

INTERPOLATIONS = ("linear", "nearest")


class ResampleError(SourceFormatError):
    """Streams cannot be put on one grid (no common time span); the message names the file."""


def resampling_options(fps: float, interpolation: str) -> tuple[int, str]:
    """(fps, interpolation) of a bag reader's fixed output grid, checked: fps a positive integer."""
    if int(fps) != fps or fps <= 0:
        raise ValueError(f"fps must be a positive integer, got {fps!r}")
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
    return int(fps), interpolation


@dataclass
class Stream:
    """One time series: a bag topic (log-time stamps) or a tracker file's hand; stamps (s) and per-sample
    values (and names, e.g. JointState.name)."""

    topic: str
    stamps_s: np.ndarray  # (N,) float64, strictly increasing after `read_streams`
    values: np.ndarray  # (N, D) float64
    names: tuple[str, ...] | None = None


def grid_for(streams: list[Stream], fps: int, path: Path) -> np.ndarray:
    """Frame times (s) every 1/fps over the span every stream covers."""
    start = max(s.stamps_s[0] for s in streams)
    stop = min(s.stamps_s[-1] for s in streams)
    if stop <= start:
        raise ResampleError(f"{path}: topics {[s.topic for s in streams]} do not overlap in time")
    num = int(np.floor((stop - start) * fps + 1e-9)) + 1
    return start + np.arange(num) / fps


def resample(stream: Stream, grid_s: np.ndarray, method: str) -> np.ndarray:
    """(len(grid), D) values of `stream` at the grid times: "nearest" sample or "linear" interpolation."""
    if method not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {method!r}")
    t, v = stream.stamps_s, stream.values
    if len(t) == 1:
        return np.repeat(v, len(grid_s), axis=0)
    if method == "nearest":
        right = np.clip(np.searchsorted(t, grid_s), 1, len(t) - 1)
        left = right - 1
        pick = np.where(np.abs(grid_s - t[left]) <= np.abs(t[right] - grid_s), left, right)
        return v[pick]
    out = np.empty((len(grid_s), v.shape[1]), dtype=np.float64)
    for d in range(v.shape[1]):
        out[:, d] = np.interp(grid_s, t, v[:, d])
    return out


def measured_rate_hz(stream: Stream) -> float:
    """Mean message rate of a stream (for reports: jittered stamps are expected)."""
    span = stream.stamps_s[-1] - stream.stamps_s[0]
    return (len(stream.stamps_s) - 1) / span if span > 0 else float("nan")
