"""The morphology vector: what a hand's spec says about it, the same for the hand in any dataset or side."""

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.hands.morphology import MORPHOLOGY_WIDTH, morphology_vector, nearest_hand
from lerobot_unidextok.udhm import JOINT_LIMITS_RAD


@pytest.mark.parametrize("name", hands.names())
def test_every_registered_hand_has_one_finite_vector_of_its_slots_and_ranges(name):
    spec = hands.get(name)
    v = morphology_vector(name, spec.sides[0])
    assert v.shape == (MORPHOLOGY_WIDTH,) == (3 * UDHM_DIM,) and v.dtype == np.float32 and np.isfinite(v).all()
    present, lo, hi = v[:UDHM_DIM], v[UDHM_DIM : 2 * UDHM_DIM], v[2 * UDHM_DIM :]
    np.testing.assert_array_equal(present, spec.active_mask.astype(np.float32))
    assert (lo <= hi).all() and not lo[present == 0].any() and not hi[present == 0].any()
    assert (hi - lo)[present == 1].max() > 0.1  # half turns: a real joint moves by more than 18 degrees
    np.testing.assert_array_equal(v, morphology_vector(name, spec.sides[0]))  # a pure function of the spec


def test_numbers_of_two_hands_against_their_specs():
    leap = morphology_vector("leap")
    lo, hi = hands.get("leap").udhm_limits_rad("right")
    np.testing.assert_allclose(leap[UDHM_DIM:], np.concatenate([lo, hi]) / np.pi, rtol=1e-6)
    assert leap[:UDHM_DIM].sum() == 16
    human = morphology_vector("human")  # keypoints: every slot, the UDHM model's own ranges
    assert human[:UDHM_DIM].all()
    np.testing.assert_allclose(human[UDHM_DIM:], JOINT_LIMITS_RAD.T.reshape(-1) / np.pi, rtol=1e-6)


def test_hands_of_different_kinematics_get_different_vectors():
    vectors = {n: morphology_vector(n).tobytes() for n in ("inspire_rh56_unitree", "shadow", "allegro", "leap",
                                                          "xhand1", "linkerhand_l10", "unitree_dex3_1")}  # fmt: skip
    assert len(set(vectors.values())) == len(vectors)


SIX = ["inspire_rh56_unitree", "shadow", "allegro", "leap", "xhand1", "linkerhand_l10"]


@pytest.mark.parametrize("name", SIX)
def test_the_nearest_hand_is_the_least_distant_morphology(name):
    others = [h for h in SIX if h != name]
    near = nearest_hand(name, others)
    distance = {h: float(np.linalg.norm(morphology_vector(h) - morphology_vector(name))) for h in others}
    assert near in others and distance[near] == min(distance.values())
    assert nearest_hand(name, [*others, name]) == name  # a hand is nearest itself


def test_nearest_hands_of_the_pool_follow_their_slots():
    """The four-fingered Shadow is nearest the four-fingered LEAP, the L10 the Inspire (both five fingers with a
    two-joint thumb and one flexion per finger)."""
    assert nearest_hand("shadow", [h for h in SIX if h != "shadow"]) == "leap"
    assert nearest_hand("linkerhand_l10", [h for h in SIX if h != "linkerhand_l10"]) == "inspire_rh56_unitree"
    with pytest.raises(ValueError, match="no hands to compare"):
        nearest_hand("shadow", [])
