"""Checks the processor step runs before tokenising: units, normalisation, and hands the tokenizer never saw.

No lerobot import. A UDHM block is radians inside its hand's joint range (human: UDHM joint limits; robot
hand: the range its native joints reach, zero on slots it lacks). Two common mistakes leave that range:
degrees fed as radians (90 instead of 1.57) and states already normalised by LeRobot's normalizer
(mean/std z-scores or min-max [-1, 1]: negative flexion, -1 on empty slots), i.e. a step placed after
`normalizer_processor`. The check is a heuristic with a margin: it cannot see a normalised value that
happens to lie inside the range, but one frame of a real batch almost always leaves it.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import torch

from lerobot_unidextok import hands as hand_registry
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import UDHM_JOINT_NAMES
from lerobot_unidextok.udhm import JOINT_LIMITS_RAD

logger = logging.getLogger(__name__)

RANGE_CHECKS = ("raise", "warn", "off")
_HAND_COLUMNS = frozenset(udhm_state_names(["right", "left"]))
RANGE_MARGIN_RAD = 0.1  # slack beyond a hand's range before a value counts as out of range (5.7 deg)


def hand_bounds_rad(hand: str, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
    """(22,) lower and upper UDHM values `hand` can produce on `side` (0 on slots the hand does not have)."""
    spec = hand_registry.get(hand)
    if spec.kind == "keypoints":  # the human hand: UDHM IK output lies within the UDHM joint limits
        return JOINT_LIMITS_RAD[:, 0].copy(), JOINT_LIMITS_RAD[:, 1].copy()
    return spec.udhm_limits_rad(side)


def layout_bounds(hands: list[str], sides: list[str]) -> tuple[torch.Tensor, torch.Tensor]:
    """(H, 22) float32 lower / upper bounds of each block, margin included; unknown sides ([]) get the
    union of both sides' ranges (a left hand's abduction range is not the right hand's)."""
    lo, hi = [], []
    for k, hand in enumerate(hands):
        candidates = [sides[k]] if sides else [s for s in ("right", "left") if s in hand_registry.get(hand).sides]
        ranges = [hand_bounds_rad(hand, s) for s in candidates or ["right"]]
        lo.append(np.min([r[0] for r in ranges], axis=0))
        hi.append(np.max([r[1] for r in ranges], axis=0))
    lo_t = torch.as_tensor(np.stack(lo) - RANGE_MARGIN_RAD, dtype=torch.float32)
    hi_t = torch.as_tensor(np.stack(hi) + RANGE_MARGIN_RAD, dtype=torch.float32)
    return lo_t, hi_t


def check_batch(states: torch.Tensor, names: list[str], key: str) -> None:
    """A (B, D) batch the step can tokenise: at least one row, every value finite. `names`: the D column
    names (whole-robot states name their arm columns), [] when the state is the UDHM blocks only."""
    if states.shape[0] == 0:
        raise ValueError(f"{key} is an empty batch (shape {tuple(states.shape)}): feed at least one frame")
    finite = torch.isfinite(states)
    if bool(finite.all()):
        return
    b, d = (int(i) for i in (~finite).nonzero()[0])
    rows = sorted({int(i) for i in (~finite).any(dim=1).nonzero().flatten().tolist()})[:6]
    name = names[d] if d < len(names) else None
    in_hand = name is None or name in _HAND_COLUMNS  # no names: the state is the blocks only
    where = f"{key} holds NaN/inf (batch rows {rows}; first at column {d}{f' ({name})' if name else ''})"
    if in_hand:
        raise ValueError(
            f"{where}, in a hand block: a hand the robot lost track of. A converted dataset records an absent hand "
            "as zeros with a zero udhm_mask (unidextok-convert does this); fill or drop those frames before the "
            "policy"
        )
    raise ValueError(
        f"{where}: a column outside the hand blocks (an arm, a gripper), which the robot did not report. The "
        "tokenizer does not read it, but the policy would turn it into NaN actions: fill or drop those frames"
    )


def range_problem(
    rows: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor, hands: list[str] | list[list[str]], key: str
) -> str | None:
    """None when every block of `rows` (B, H, 22) lies inside [lo, hi] ((H, 22), or (B, H, 22) with per-row
    hands `hands[b][h]`); else what is wrong and the fix."""
    bad = (rows < lo) | (rows > hi)  # (B, H, 22)
    if not bool(bad.any()):
        return None
    b, h, j = (int(i) for i in bad.nonzero()[0])
    value = float(rows[b, h, j])
    low, high = (float(t[b, h, j]) if t.ndim == 3 else float(t[h, j]) for t in (lo, hi))
    hand = hands[b][h] if lo.ndim == 3 else hands[h]
    where = (
        f"{key} block {h} ({hand}) joint {UDHM_JOINT_NAMES[j]} = {value:.3f} at batch row {b}, outside "
        f"[{low + RANGE_MARGIN_RAD:.3f}, {high - RANGE_MARGIN_RAD:.3f}] rad"
    )
    fraction = float(bad.float().mean())
    if not bool(rows[b, h].any()):
        return (
            f"{where}: block {h} is all zeros, a pose the {hand} hand cannot take. An absent hand, or a robot that "
            "has not reported its state yet: feed its real state (a converted dataset marks an absent hand with a "
            "zero udhm_mask, which the policies' mixed step reads as no hand)"
        )
    if float(rows.abs().max()) > 2 * math.pi:
        return (
            f"{where}: the values look like degrees (max |x| = {float(rows.abs().max()):.1f}). UDHM states are "
            "radians: convert with numpy.deg2rad / torch.deg2rad, or re-convert the dataset with unidextok-convert"
        )
    return (
        f"{where} ({fraction:.0%} of values out of range): the state looks normalised (z-scores or min-max "
        "[-1, 1]). The tokenizer step must see raw radians: place it before `normalizer_processor` (after "
        "`to_batch_processor`), as the <type>_udt policies do; otherwise check hand_layout and the sides"
    )


def check_ranges(
    rows: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor, hands: list[str] | list[list[str]], key: str, mode: str
) -> None:
    """Apply `mode` ("raise" | "warn" | "off") to `range_problem`."""
    if mode == "off":
        return
    problem = range_problem(rows, lo, hi, hands, key)
    if problem is None:
        return
    if mode == "raise":
        raise ValueError(problem + " (range_check='warn' or 'off' to go on anyway)")
    logger.warning(problem)


def untrained_hands(layout_hands: list[str], vocabulary: list[str], trained: list[str] | None) -> list[str]:
    """Hands of the layout the tokenizer has no trained embedding for (outside its vocabulary, or in it but
    not among the hands it was trained on when the checkpoint records them)."""
    known = set(trained) if trained else set(vocabulary)
    return sorted({h for h in layout_hands if h not in known})


def check_registry(layout_hands: list[str]) -> None:
    """Every hand of the layout must have a spec: the step needs its active slots and ranges."""
    missing = sorted({h for h in layout_hands if h not in hand_registry.names()})
    if missing:
        raise ValueError(
            f"hands {missing} have no hand spec, so their UDHM slots and ranges are unknown; known hands: "
            f"{', '.join(hand_registry.names())}. Add a YAML spec (docs/hands.md) or fix hand_layout"
        )


__all__ = [
    "RANGE_CHECKS",
    "check_batch",
    "RANGE_MARGIN_RAD",
    "check_ranges",
    "check_registry",
    "hand_bounds_rad",
    "layout_bounds",
    "range_problem",
    "untrained_hands",
]
