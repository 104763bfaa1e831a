"""Retarget specs are data: every shipped YAML loads and agrees with its hand spec (no URDF needed)."""

import pytest
import yaml

from lerobot_unidextok import hands
from lerobot_unidextok.retarget import RetargetSpecError, get_retarget_spec, load_retarget_spec, retarget_hands


@pytest.mark.parametrize("hand", retarget_hands())
def test_every_spec_names_real_native_joints(hand):
    spec = get_retarget_spec(hand)
    native = set(hands.get(hand).joint_names)
    for side, s in spec.sides.items():
        assert side in hands.get(hand).sides
        names = [j.native for j in s.joints]
        assert set(names) <= native, set(names) - native
        # every native joint that has a UDHM slot is driven by a URDF joint
        slotted = {j.name for j in hands.get(hand).joints if j.slot is not None}
        assert slotted <= set(names), slotted - set(names)
        assert any(kp in (12, 11) for kp in s.target_keypoints)  # a middle-finger target fixes the scale


def test_the_paper_hands_have_specs():
    assert {"linkerhand_l10", "linkerhand_l20", "xhand1", "inspire_rh56_unitree"} <= set(retarget_hands())


def test_same_as_renames_the_other_side():
    spec = get_retarget_spec("xhand1")
    assert spec.side("left").urdf == "xhand_left.urdf"
    assert all(j.urdf.startswith("left_hand_") for j in spec.side("left").joints)


def test_bad_specs_name_the_field(tmp_path):
    good = yaml.safe_load(get_retarget_spec("linkerhand_l10").path.read_text())
    bad = dict(good, sides={"right": dict(good["sides"]["right"], targets=[{"link": "x", "keypoint": "nose"}])})
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(RetargetSpecError, match="keypoint 'nose'"):
        load_retarget_spec(path)
    bad = dict(good, sides={"middle": good["sides"]["right"]})
    path.write_text(yaml.safe_dump(bad))
    with pytest.raises(RetargetSpecError, match="side 'middle'"):
        load_retarget_spec(path)
    with pytest.raises(ValueError, match="no retarget spec for hand 'shadowy'"):
        get_retarget_spec("shadowy")
