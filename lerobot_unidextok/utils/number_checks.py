"""Numbers checked where they enter: per-hand statistics, share weights, grasp centres, checkpoint tensors.

A number is trusted nowhere. Every reader and writer of one of these passes it through a check here, so a NaN
std in a mix's record, a weight of 1e-300, a grasp centre typed in mm or a NaN weight in a checkpoint is one
`NumberError` where it enters, naming the file or field, the hand or tensor, what is wrong and the fix, instead
of a policy that silently never moves a hand:

- `checked_numbers`: a list of numbers: its type, length, finiteness, sign and plausible range (with its unit);
- `checked_tensor`: a tensor of a step's saved state: finiteness and sign;
- `checked_hand_stats`: per-hand statistics `{key: {side: {hand: {stat: [22], "frames": n}}}}`
  (`conversion/hand_stats.py`), and that they cover exactly the hands and sides they are read for;
- `checked_shares`: share weights (`unidextok-mix --weights`) as shares, normalised without overflow;
- `nonfinite_tensors`: the tensors of a safetensors file that hold NaN or inf (what push and deploy ship).

Layer 0: numpy and the package's errors and constants only (torch and safetensors inside the function that
reads a file).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.errors import InvalidInputError

SIGNS = {"positive": "> 0", "non_negative": ">= 0"}
# a UDHM block holds joint angles in rad (a hand's range lies within [-pi, pi]): a statistic beyond this is not one
MAX_STAT_RAD = 4 * math.pi
STAT_SIGNS = {"std": "non_negative"}  # the other statistics (mean, min, max, quantiles) may take any sign
RANGE_PAIRS = (("min", "max"), ("q01", "q99"), ("q10", "q90"))  # low <= high
# an input's share of a mix's sampled training frames below this is in the mix in name only (one frame in 1000:
# a batch of 8 sees it once every 125 updates): refused, so that it is left out instead, or weighted up
MIN_SHARE = 1e-3
NAMED = 3  # positions / tensors named in a message; the rest are counted


class NumberError(InvalidInputError):
    """A number that cannot be right (not a number, NaN/inf, the wrong sign, length or magnitude); the message
    names the file or field, the hand or tensor, and the fix."""


def _problem(where: str, what: str, fix: str) -> NumberError:
    return NumberError(f"{where} {what}" + (f"; {fix}" if fix else ""))


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _as_array(value: Any) -> np.ndarray | None:
    """`value` (a list or tuple of numbers, a numeric array or tensor) as a float64 array, or None for anything
    else (a string, a mapping, a list holding a string or None)."""
    if hasattr(value, "detach"):  # a torch tensor
        value = value.detach().cpu().double().numpy()
    if isinstance(value, np.ndarray):
        return value.astype(np.float64) if value.dtype.kind in "fiu" else None
    if isinstance(value, (list, tuple)) and all(_is_number(x) for x in value):
        return np.asarray(value, dtype=np.float64)
    return None


def _positions(bad: np.ndarray) -> str:
    """'index 3' / 'indices [0, 4, 7] and 12 more' of the true entries of a flat bool array."""
    at = np.flatnonzero(bad).tolist()
    if len(at) == 1:
        return f"index {at[0]}"
    more = f" and {len(at) - NAMED} more" if len(at) > NAMED else ""
    return f"indices {at[:NAMED]}{more}"


def _check_values(arr: np.ndarray, where: str, sign: str | None, max_abs: float | None, unit: str, fix: str) -> None:
    """Finite, of `sign`, and within `max_abs` (unit `unit`); a NumberError naming the first kind of fault."""
    flat = arr.reshape(-1)
    finite = np.isfinite(flat)
    if not finite.all():
        nan = np.isnan(flat)
        kinds = "NaN" if nan[~finite].all() else "inf" if not nan.any() else "NaN/inf"
        raise _problem(where, f"holds {kinds} at {_positions(~finite)} ({int((~finite).sum())} of {flat.size} "
                              "values)", fix)  # fmt: skip
    u = f" {unit}" if unit else ""
    if sign is not None:
        bad = flat <= 0 if sign == "positive" else flat < 0
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise _problem(where, f"must be {SIGNS[sign]}, but holds {flat[i]:.6g}{u} at {_positions(bad)}", fix)
    if max_abs is not None:
        bad = np.abs(flat) > max_abs
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise _problem(where, f"holds {flat[i]:.6g}{u} at {_positions(bad)}, beyond the plausible "
                                  f"{max_abs:g}{u} in magnitude", fix)  # fmt: skip


def checked_numbers(value: Any, where: str, *, length: int | None = None, sign: str | None = None,
                    max_abs: float | None = None, unit: str = "", fix: str = "") -> list[float]:  # fmt: skip
    """`value` as a list of floats, or a NumberError naming `where` and `fix`: a list of numbers (a tuple, an
    array or a tensor of one dimension), `length` of them, every one finite, `sign` ("positive" | "non_negative"
    | None) and at most `max_abs` in magnitude (`unit` named)."""
    arr = _as_array(value)
    what = f"{length} numbers" if length is not None else "a list of numbers"
    u = f" in {unit}" if unit else ""
    if arr is None or arr.ndim != 1:
        shown = repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + "..."
        raise _problem(where, f"must be {what}{u}, got {shown} ({type(value).__name__})", fix)
    if length is not None and arr.size != length:
        raise _problem(where, f"must be {what}{u}, got {arr.size}", fix)
    _check_values(arr, where, sign, max_abs, unit, fix)
    return [float(x) for x in arr]


def checked_tensor(value: Any, where: str, *, sign: str | None = None, max_abs: float | None = None, unit: str = "",
                   fix: str = "") -> None:  # fmt: skip
    """A tensor (or array) of saved state whose values are all finite, `sign` and at most `max_abs` (`unit`) in
    magnitude; a NumberError naming `where`."""
    arr = _as_array(value)
    if arr is None:
        raise _problem(where, f"must be a numeric tensor, got {type(value).__name__}", fix)
    _check_values(arr, where, sign, max_abs, unit, fix)


def checked_hand_stats(stats: Any, where: str, *, hands: list[str] | None = None, others: bool = False,
                       sides: list[str] | None = None, required: tuple[str, ...] = (),
                       fix: str = "") -> dict[str, dict[str, dict[str, dict]]]:  # fmt: skip
    """Per-hand statistics `{key: {side: {hand: {stat: [22], "frames": n}}}}` checked whole, or a NumberError
    naming the key, side, hand and statistic: each statistic 22 finite numbers in rad within MAX_STAT_RAD, a std
    >= 0, a low statistic not above its high one (min/max, q01/q99, q10/q90), frames a whole number >= 1.
    `hands`: the hands they are read for, each of which must have statistics under every key and, unless
    `others`, no other hand may (a hand missing, or renamed, would silently be normalised with other hands'
    statistics); `sides`: the
    block sides they may name; `required`: the statistics every entry must have. Returns `stats`, its lists as
    floats."""
    if not isinstance(stats, dict):
        raise _problem(where, f"must map each key to {{side: {{hand: statistics}}}}, got {type(stats).__name__}", fix)
    out: dict[str, dict[str, dict[str, dict[str, Any]]]] = {}
    for key, per_side in stats.items():
        if not isinstance(per_side, dict):
            raise _problem(f"{where}[{key!r}]", f"must map each side to {{hand: statistics}}, got {per_side!r}", fix)
        bad_sides = sorted(set(per_side) - set(sides)) if sides is not None else []
        if bad_sides:
            raise _problem(f"{where}[{key!r}]", f"names sides {bad_sides}, but the blocks are {sides}", fix)
        out[key] = {}
        for side, per_hand in per_side.items():
            if not isinstance(per_hand, dict):
                raise _problem(f"{where}[{key!r}][{side!r}]", f"must map each hand to its statistics, got "
                                                              f"{per_hand!r}", fix)  # fmt: skip
            out[key][side] = {hand: _checked_entry(entry, f"{where}[{key!r}][{side!r}][{hand!r}]", required, fix)
                              for hand, entry in per_hand.items()}  # fmt: skip
        if hands is not None:
            _check_coverage(out[key], f"{where}[{key!r}]", hands, others, fix)
    return out


def _checked_entry(entry: Any, where: str, required: tuple[str, ...], fix: str) -> dict[str, Any]:
    if not isinstance(entry, dict):
        raise _problem(where, f"must map each statistic (mean, std, ...) to {UDHM_DIM} numbers, got {entry!r}", fix)
    lacking = [name for name in required if name not in entry]
    if lacking:
        raise _problem(where, f"has no {lacking} (it has {sorted(entry)})", fix)
    out: dict[str, Any] = {}
    for name, value in entry.items():
        if name == "frames":
            if not _is_number(value) or not math.isfinite(value) or value < 1 or value != int(value):
                raise _problem(f"{where}.frames", f"must be a whole number of frames >= 1, got {value!r}", fix)
            out[name] = int(value)
        else:
            out[name] = checked_numbers(value, f"{where}.{name}", length=UDHM_DIM, sign=STAT_SIGNS.get(name),
                                        max_abs=MAX_STAT_RAD, unit="rad", fix=fix)  # fmt: skip
    for lo, hi in RANGE_PAIRS:
        if lo in out and hi in out:
            above = np.asarray(out[lo]) > np.asarray(out[hi])
            if above.any():
                i = int(np.flatnonzero(above)[0])
                raise _problem(where, f"has {lo} {out[lo][i]:.6g} above {hi} {out[hi][i]:.6g} at {_positions(above)}",
                               fix)  # fmt: skip
    return out


def _check_coverage(per_side: dict[str, dict[str, Any]], where: str, hands: list[str], others: bool,
                    fix: str) -> None:  # fmt: skip
    present = {h for per_hand in per_side.values() for h in per_hand}
    unknown = [] if others else sorted(present - set(hands))
    if unknown:
        raise _problem(where, f"names hands {unknown}, which are not among the hands {list(hands)} it is read for "
                              "(renamed, or from another dataset)", fix)  # fmt: skip
    missing = [h for h in hands if h not in present]
    if missing:
        raise _problem(where, f"has no statistics for hands {missing} (of {list(hands)}): they would be "
                              "normalised with other hands' statistics", fix)  # fmt: skip


def checked_shares(weights: Any, where: str, count: int | None = None) -> list[float]:
    """Share weights (one positive, finite number per input; `count` inputs) as shares summing to 1, or a
    NumberError naming `where`. Divided by their largest first, so weights near the float limit (1e308) do not
    overflow; a share below MIN_SHARE is refused, naming the input and its share."""
    fix = "pass one positive number per input, e.g. --weights='[3, 1]'"
    w = np.asarray(checked_numbers(weights, where, length=count, sign="positive", fix=fix), dtype=np.float64)
    scaled = w / w.max()  # in (0, 1]: their sum cannot overflow
    shares = scaled / scaled.sum()
    low = shares < MIN_SHARE
    if low.any():
        i = int(np.flatnonzero(low)[0])
        raise _problem(where, f"{weights_text(list(w))} give input {i} a share of {shares[i]:.3g} of the training "
                              f"frames, below the {MIN_SHARE:g} an input needs to count in the mix: leave that input "
                              "out, or give it a larger weight", "")  # fmt: skip
    return [float(s) for s in shares]


def weights_text(weights: list[float]) -> str:
    """`[3, 1]`, `[1e-300, 1]`: weights as short numbers, never 300 digits."""
    return "[" + ", ".join(f"{w:.6g}" for w in weights) + "]"


def nonfinite_tensors(path: str | Path) -> list[tuple[str, int, int]]:
    """(name, non-finite values, values) of each floating tensor in the safetensors file at `path` that holds
    NaN or inf; [] when every value is finite. Reads one tensor at a time."""
    import torch  # with the file: a checkpoint check, never at import
    from safetensors import safe_open

    out = []
    with safe_open(str(path), framework="pt", device="cpu") as f:
        for name in f.keys():  # noqa: SIM118  (safe_open is no mapping)
            t = f.get_tensor(name)
            if not torch.is_floating_point(t) or t.numel() == 0:
                continue
            bad = int((~torch.isfinite(t)).sum())
            if bad:
                out.append((name, bad, t.numel()))
    return out


def nonfinite_text(found: list[tuple[str, int, int]]) -> str:
    """'tensor model.x.weight holds 3 NaN/inf values of 64; ...' for `nonfinite_tensors`' answer."""
    named = "; ".join(f"tensor {n} holds {bad} NaN/inf of {total} values" for n, bad, total in found[:NAMED])
    more = f" (and {len(found) - NAMED} more tensors)" if len(found) > NAMED else ""
    return named + more


__all__ = [
    "MAX_STAT_RAD",
    "MIN_SHARE",
    "NumberError",
    "checked_hand_stats",
    "checked_numbers",
    "checked_shares",
    "checked_tensor",
    "nonfinite_tensors",
    "nonfinite_text",
    "weights_text",
]
