"""Wrong native units caught before conversion: data using a tiny corner of a joint range, or overshooting it.

`check_units(spec, raw, side)` (`hands.check_units`) looks at a whole stream (an episode) of native values:
- values outside the native range (e.g. degrees where the spec expects radians) raise with the
  rescaling that would bring them inside it (``np.deg2rad``, ``/ 1000``, ...);
- values that all sit within ``TINY_FRACTION`` of one end of every joint's range while still moving
  (e.g. Unitree's normalised 0-1 Inspire values through the 0-1000 register spec ``inspire_rh56``, which
  would otherwise convert into a hand held closed and validate) raise with the rescaling, and the
  registered spec of the same embodiment whose native range fits the data as it is.
Both raise ``NativeUnitsError`` (a ValueError) naming the hand, the side, the joints and the likely fix.
The check sits above the registry because its advice names other registered specs.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.registry import all_specs
from lerobot_unidextok.hands.spec import HandSpec

TINY_FRACTION = 0.01  # all values within 1 % of one end of every joint's range = wrong units
GLITCH_SHARE = 0.05  # at most this share of frames outside the range, the rest inside: glitches, not units
# (rescaling, label): what a value times the factor would be if that were the mistake.
RESCALINGS: tuple[tuple[float, str], ...] = (
    (math.pi / 180.0, "degrees given where radians are expected: convert with np.deg2rad"),
    (180.0 / math.pi, "radians given where degrees are expected: convert with np.rad2deg"),
    (1000.0, "normalised 0-1 values given where the range is 0-1000: multiply by 1000"),
    (0.001, "0-1000 values given where the range is 0-1: divide by 1000"),
    (100.0, "normalised 0-1 values given where the range is 0-100: multiply by 100"),
    (0.01, "0-100 values given where the range is 0-1: divide by 100"),
    (0.1, "0-1000 values given where the range is 0-100: divide by 10"),
    (255.0, "normalised 0-1 values given where the range is 0-255: multiply by 255"),
    (1.0 / 255.0, "0-255 values given where the range is 0-1: divide by 255"),
)


class NativeUnitsError(InvalidInputError):
    """Native values that do not look like the spec's units."""


def _fits(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: np.ndarray) -> bool:
    return bool(((values >= lo - tol) & (values <= hi + tol)).all())


def _likely_fixes(spec: HandSpec, values: np.ndarray, lo: np.ndarray, hi: np.ndarray, tol: np.ndarray) -> list[str]:
    """The rescaling that puts (nearly) every value inside the range using most of it, and sibling specs."""
    span = hi - lo
    best, best_score = None, None
    for factor, label in RESCALINGS:
        scaled = values * factor
        inside = float(((scaled >= lo - 0.05 * span) & (scaled <= hi + 0.05 * span)).mean())
        used = float(((scaled.max(0) - scaled.min(0)) / span).max())
        if inside >= 0.99 and TINY_FRACTION < used <= 1.1:
            score = (inside, used)
            if best_score is None or score > best_score:
                best, best_score = label, score
    return ([best] if best else []) + _sibling_specs(spec, values)


def _sibling_specs(spec: HandSpec, values: np.ndarray) -> list[str]:
    """Registered specs of the same embodiment and width whose native range holds the values as they are."""
    out = []
    for other in all_specs():
        if other.name == spec.name or other.embodiment != spec.embodiment or other.num_native != spec.num_native:
            continue
        rr = other.raw_range(other.sides[0])
        a = other.active_joint_indices
        span = rr[a, 1] - rr[a, 0]
        if _fits(values, rr[a, 0], rr[a, 1], 1e-6 * span) and ((values.max(0) - values.min(0)) / span).max() > 0.05:
            out.append(f"use hand spec {other.name!r} ({other.native_units})")
    return out


def check_units(spec: HandSpec, raw, side: str = "right") -> None:
    """Raise ``NativeUnitsError`` when a stream of native values (..., J) does not look like the spec's units
    (outside the range, or all within 1 % of one end of it); the message gives the likely fix."""
    if side not in spec.sides:
        raise ValueError(f"hand {spec.name!r} has no side {side!r}; its sides are {list(spec.sides)}")
    if spec.kind != "joints":
        return
    raw = raw.detach().cpu().numpy() if isinstance(raw, torch.Tensor) else raw
    values = np.asarray(raw, dtype=np.float64).reshape(-1, spec.num_native)
    a = spec.active_joint_indices
    if values.size == 0 or len(a) == 0 or not np.isfinite(values).all():
        return  # NaN and shape problems are reported by the conversion itself
    values = values[:, a]  # (N, A)
    rr = spec.raw_range(side)[a]
    lo, hi = rr[:, 0], rr[:, 1]
    span = hi - lo
    tol = 1e-6 * np.maximum(span, 1.0)
    where = f"hand {spec.name!r} ({side}, native units: {spec.native_units})"
    names = [spec.joint_names[i] for i in a]

    outside = (values < lo - tol) | (values > hi + tol)
    if outside.any():
        cols = np.flatnonzero(outside.any(0))
        detail = ", ".join(
            f"{names[c]} reaches [{values[:, c].min():.4g}, {values[:, c].max():.4g}] of [{lo[c]:g}, {hi[c]:g}]"
            for c in cols[:6]
        )
        bad_frames = int(outside.any(1).sum())
        if bad_frames <= GLITCH_SHARE * len(values):  # the rest fits: a few bad frames, not other units
            raise NativeUnitsError(
                f"{where}: {bad_frames} of {len(values)} frames outside the native range ({detail}) while the "
                "others fit it: glitches in the recording, not other units. Fix or drop those frames in the "
                "source, or skip the episode (--on_error=skip)"
            )
        fixes = _likely_fixes(spec, values, lo, hi, tol)
        raise NativeUnitsError(
            f"{where}: {int(outside.sum())} value(s) outside the native range: {detail}. "
            + (f"Likely fix: {'; or '.join(fixes)}." if fixes else "Check the units and the hand spec.")
        )

    near_lo = (values - lo) <= TINY_FRACTION * span
    near_hi = (hi - values) <= TINY_FRACTION * span
    moving = float(np.ptp(values, axis=0).max()) > 0.0
    if moving and (near_lo.all() or near_hi.all()):
        end = "lower" if near_lo.all() else "upper"
        fixes = _likely_fixes(spec, values, lo, hi, tol)
        raise NativeUnitsError(
            f"{where}: every value of {len(a)} joints over {len(values)} frames stays within "
            f"{TINY_FRACTION:.0%} of the {end} end of the native range "
            f"(e.g. {names[0]} in [{values[:, 0].min():.4g}, {values[:, 0].max():.4g}] of [{lo[0]:g}, {hi[0]:g}]), "
            "so the hand would convert to one fixed pose. "
            + (f"Likely fix: {'; or '.join(fixes)}." if fixes else "Check the units and the hand spec.")
        )
