"""A hand's morphology as a fixed-width vector: what its spec knows about it, the same in any dataset.

A policy trained on a mix of hands is told which hand a row holds. A one-hot identity over the mix's vocabulary
says nothing about a hand the mix never had (it is all zero there), so a zero-shot hand has nothing to condition
on. The morphology vector describes the hand instead of naming it, so an unseen hand gets a description in the
same terms as the trained ones (as OHRA's morphology parameters and DexGrasp-Zero's joint limits do;
`../shared/notes/pooling.md`):

    [ slot present (22) | lower bound / pi (22) | upper bound / pi (22) ]     (66,) float32

per UDHM slot: 1 where the hand has a real joint there (semantic insertion), and the UDHM range its joint reaches
(`HandSpec.udhm_limits_rad`), in half turns so every entry is O(1). Slots the hand lacks are 0 in all three parts.
Link lengths and fingertip positions are not in it: the specs do not hold the hands' geometry (their URDFs do,
outside the package). Keypoint hands (the human hand) have every slot, with the UDHM model's own ranges.
"""

from __future__ import annotations

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.hands.registry import get
from lerobot_unidextok.udhm.joints import JOINT_LIMITS_RAD

MORPHOLOGY_WIDTH = 3 * UDHM_DIM  # presence, lower and upper bound per UDHM slot


def morphology_vector(hand: str, side: str = "right") -> np.ndarray:
    """(66,) float32 morphology of registered `hand` on `side` (a side the spec lacks: its first side's)."""
    spec = get(hand)
    side = side if side in spec.sides else spec.sides[0]
    active = spec.active_mask.astype(np.float32)  # (22,)
    if spec.kind == "keypoints":  # every slot, over the UDHM model's own ranges
        lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
    else:
        lo, hi = spec.udhm_limits_rad(side)  # (22,) each, 0 on slots it lacks
    return np.concatenate([active, lo / np.pi, hi / np.pi]).astype(np.float32)


def nearest_hand(hand: str, candidates: list[str], side: str = "right") -> str:
    """The hand of `candidates` whose morphology vector is nearest `hand`'s (Euclidean; a tie: the first).

    What a policy that never saw `hand` knows best: the trained hand that has the most of its slots over the most
    similar ranges (`unidextok-deploy --zero_shot_slots=nearest`)."""
    if not candidates:
        raise ValueError(f"no hands to compare {hand!r} with")
    own = morphology_vector(hand, side)
    distances = [float(np.linalg.norm(morphology_vector(h, side) - own)) for h in candidates]
    return candidates[int(np.argmin(distances))]


__all__ = ["MORPHOLOGY_WIDTH", "morphology_vector", "nearest_hand"]
