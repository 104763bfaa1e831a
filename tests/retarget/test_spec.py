"""Retargeting reads the hand's own spec: links and joint maps come from `hands/specs/<hand>.yaml` (no URDF needed
for these checks), the same YAML the registry and the kinematic check read."""

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.retarget import get_retarget_spec, retarget_hands


@pytest.mark.parametrize("hand", retarget_hands())
def test_every_hand_with_a_urdf_map_has_palm_and_targets(hand):
    spec = hands.get(hand)
    for side in spec.sides:
        s = get_retarget_spec(hand, side)
        assert [j.native for j in s.joints] == list(spec.joint_names)
        assert set(s.palm_links) == {"index_mcp", "middle_mcp", "pinky_mcp"} and s.wrist_link
        assert any(9 <= kp <= 12 for kp in s.target_keypoints)  # a middle-finger target fixes the scale
        assert len(s.target_links) == len(s.target_keypoints) >= 2


def test_the_paper_hands_and_the_targets_the_specs_define():
    """The four hands the retarget YAMLs used to hold, read from the hand specs: the right L10 file has no
    fingertip links, so its targets are the distal links' origins (the IP / DIP keypoints); the Inspire's are
    its tip links; a rigid stand-in finger (Allegro's little finger, offsets only) is no target."""
    assert {"linkerhand_l10", "linkerhand_l20", "xhand1", "inspire_rh56_unitree"} <= set(retarget_hands())
    l10 = get_retarget_spec("linkerhand_l10", "right")
    assert l10.urdf == "linkerhand_l10_right.urdf" and l10.wrist_link == "hand_base_link"
    assert list(zip(l10.target_links, l10.target_keypoints, strict=True)) == [
        ("thumb_distal", 3), ("index_distal", 7), ("middle_distal", 11), ("ring_distal", 15), ("pinky_distal", 19)]
    inspire = get_retarget_spec("inspire_rh56_unitree", "left")
    assert inspire.target_links == ("L_thumb_tip", "L_index_tip", "L_middle_tip", "L_ring_tip", "L_pinky_tip")
    assert inspire.palm_links == {"index_mcp": "L_index_proximal", "middle_mcp": "L_middle_proximal",
                                  "pinky_mcp": "L_pinky_proximal"}  # fmt: skip
    assert get_retarget_spec("xhand1", "left").joints[0].urdf == "left_hand_thumb_bend_joint"
    assert 19 not in get_retarget_spec("allegro", "right").target_keypoints
    assert "linkerhand_l6" not in retarget_hands()  # no URDF map


def test_urdf_angles_become_the_native_values_the_spec_defines():
    """Through the spec's own radians (Inspire: 1 = open at the URDF's 0 rad, 0 at 1.7 rad; XHand: radians as
    they are), and where a URDF's angles are not the spec's radians (the rewritten right L10 file) linearly
    over that URDF joint's limits (`raw_at_urdf_limits`)."""
    little = get_retarget_spec("inspire_rh56_unitree", "right").joints[0]
    np.testing.assert_allclose(little.to_native(np.array([0.0, 0.85, 1.7]), (0.0, 1.7)), [1.0, 0.5, 0.0])
    xhand = get_retarget_spec("xhand1", "right").joints[4]
    np.testing.assert_allclose(xhand.to_native(np.array([0.3, 1.2]), (0.0, 1.92)), [0.3, 1.2])
    ring_roll = get_retarget_spec("linkerhand_l10", "right").joints[7]
    assert ring_roll.raw_at_urdf_limits == (0.0, 255.0)
    np.testing.assert_allclose(ring_roll.to_native(np.array([-0.1, 0.0, 0.1]), (-0.1, 0.1)), [0.0, 127.5, 255.0])
    assert get_retarget_spec("linkerhand_l10", "left").joints[7].raw_at_urdf_limits is None


def test_a_hand_without_a_urdf_map_or_side_is_named():
    with pytest.raises(InvalidInputError, match=r"no URDF map for hand 'linkerhand_l6'.*'Add your own hand'"):
        get_retarget_spec("linkerhand_l6", "right")
    with pytest.raises(InvalidInputError, match="no URDF map for hand 'shadowy'"):
        get_retarget_spec("shadowy", "right")
