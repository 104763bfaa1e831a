"""Bad input gives clear errors; a new hand is one YAML file loaded with hands.load_spec."""

from __future__ import annotations

import logging
import textwrap

import numpy as np
import pytest
import torch

from lerobot_unidextok import hands
from lerobot_unidextok.udhm import Skeleton

MINIMAL = textwrap.dedent(
    """\
    name: {name}
    embodiment: toy_gripper_hand
    kind: joints
    sides: [right]
    native_units: degrees
    joints:
      - name: finger_a
        slot: index_mcp_flex
        raw_range: [0, 90]
        rad_at_raw_range: [0.0, 1.5707963267948966]
      - name: finger_b
        slot: thumb_cmc_flex
        raw_range: [0, 90]
        rad_at_raw_range: [1.5707963267948966, 0.0]  # 90 = open
      - name: wrist
        slot: null
        raw_range: [-10, 10]
        rad_at_raw_range: [0.0, 0.0]
        note: not a finger joint
    """
)


def _write(tmp_path, text: str, name: str = "toy_hand"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


# ---------------------------------------------------------------------------------------------
# adding a hand = adding one YAML
# ---------------------------------------------------------------------------------------------
def test_new_hand_from_one_yaml(tmp_path):
    spec = hands.load_spec(_write(tmp_path, MINIMAL.format(name="toy_hand")))
    assert spec.name == "toy_hand" and spec.embodiment == "toy_gripper_hand"
    assert spec.joint_names == ("finger_a", "finger_b", "wrist")
    state = spec.to_udhm(np.array([[45.0, 90.0, 3.0]]))
    assert state.shape == (1, 22)
    assert state[0, 6] == pytest.approx(np.pi / 4)  # index_mcp_flex
    assert state[0, 0] == pytest.approx(0.0)  # thumb open at 90
    assert spec.active_mask.sum() == 2 and spec.dropped_joints == ("wrist",)
    back = spec.from_udhm(state)
    np.testing.assert_allclose(back, [[45.0, 90.0, 10.0]], atol=1e-12)  # dropped, no angle: upper raw end
    # no `skeleton:` block: the default adult human skeleton, unscaled (as for the human hand itself)
    default = Skeleton.default()
    for skel in (spec.skeleton(), hands.get("human").skeleton()):
        np.testing.assert_allclose(skel.bone_lengths_m, default.bone_lengths_m, atol=1e-12)
        np.testing.assert_allclose(skel.palm_offsets_m, default.palm_offsets_m, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# invalid YAML: each problem names the file and the field
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("kind: joints", "kind: joints\ncolour: red", "<top level>"),  # unknown top-level key
        ("slot: index_mcp_flex", "slot: index_knuckle", "slot"),  # slot not in UDHM
        ("slot: thumb_cmc_flex", "slot: index_mcp_flex", "joints[].slot"),  # duplicate slot
        (
            "raw_range: [0, 90]\n    rad_at_raw_range: [0.0, 1.5",
            "raw_range: [90, 0]\n    rad_at_raw_range: [0.0, 1.5",
            "raw_range",
        ),  # min > max
        ("name: finger_b", "name: finger_a", "joints[].name"),  # duplicate joint
        ("sides: [right]", "sides: [up]", "sides"),
        ("sides: [right]", "sides: []", "sides"),  # each clause of the sides check on its own
        ("sides: [right]", "sides: right", "sides"),
        ("sides: [right]", "sides: [right, right]", "sides"),
        ("    note: not a finger joint", "    default_raw: 12", "default_raw"),  # outside [-10, 10]
        ("    note: not a finger joint", "    default_raw: open", "default_raw"),
        ("kind: joints", "kind: joints\nskeleton:\n  bone_lengths_m: [0.03, 0.02, 0.02]", "bone_lengths_m"),
        ("kind: joints", "kind: joints\nskeleton:\n  bone_lengths_m: {thumbs: [0.03, 0.02, 0.02]}", "bone_lengths_m"),
        ("    note: not a finger joint", "    tendon: 3", "unknown key"),
        ("slot: index_mcp_flex\n", "slot: index_mcp_flex\n    sign: 2\n", "sign"),
        ("embodiment: toy_gripper_hand\n", "", "embodiment"),
        *[
            ("    note: not a finger joint", f"    note: not a finger joint\ncoupled:\n  - {entry}", field)
            for entry, field in [  # a drawn coupling (with slot) must be usable by the viewer
                ("{joint: pip, follows: finger_a, ratio: 1.0, slot: index_pip}", "coupled[0].slot"),
                ("{joint: pip, follows: finger_a, ratio: 1.0, slot: thumb_cmc_flex}", "coupled[0].slot"),  # a joint's
                ("{joint: pip, follows: finger_z, ratio: 1.0, slot: index_pip_flex}", "coupled[0].follows"),
                ("{joint: pip, follows: wrist, ratio: 1.0, slot: index_pip_flex}", "coupled[0].follows"),  # dropped
            ]
        ],
    ],
)
def test_invalid_yaml_names_file_and_field(tmp_path, old, new, field):
    text = MINIMAL.format(name="toy_hand")
    assert old in text
    path = _write(tmp_path, text.replace(old, new, 1))
    with pytest.raises(ValueError) as err:
        hands.load_spec(path)
    msg = str(err.value)
    assert str(path) in msg and field in msg


def test_a_drawn_coupling_loads_with_its_slot(tmp_path):
    """A coupled joint with a slot names the UDHM slot the viewer bends; two may not bend the same slot."""
    entry = "  - {joint: pip, follows: finger_a, ratio: 0.7, offset_rad: 0.1, slot: index_pip_flex}\n"
    text = MINIMAL.format(name="toy_hand") + "coupled:\n" + entry
    (coupling,) = hands.load_spec(_write(tmp_path, text)).coupled
    assert (coupling.slot, coupling.follows, coupling.ratio) == ("index_pip_flex", "finger_a", 0.7)
    assert coupling.offset_rad == 0.1
    with pytest.raises(hands.SpecError, match=r"coupled\[1\].slot.*already filled"):
        hands.load_spec(_write(tmp_path, text + entry))


def test_dropped_joints_decode_to_their_raw_value_at_zero_rad(tmp_path):
    """A dropped joint (slot null) has no UDHM angle; decoding gives the raw value where its angle is 0 rad
    (a wrist at -0.5..1.0 rad over raw 0..150: raw 50), or the upper raw end when its angle never changes.
    Catches the zero-span case taken for every joint (`rad[0] == rad[1]` -> `rad[1] == rad[1]`)."""
    text = MINIMAL.format(name="toy_hand").replace(
        "raw_range: [-10, 10]\n    rad_at_raw_range: [0.0, 0.0]",
        "raw_range: [0, 150]\n    rad_at_raw_range: [-0.5, 1.0]",
    )
    spec = hands.load_spec(_write(tmp_path, text))
    assert spec.dropped_joints == ("wrist",)
    back = spec.from_udhm(spec.to_udhm(np.array([[45.0, 90.0, 120.0]])))
    np.testing.assert_allclose(back, [[45.0, 90.0, 50.0]], atol=1e-9)


@pytest.mark.parametrize("joints", ["[]", "3"])
def test_a_joints_hand_needs_a_list_of_joints(tmp_path, joints):
    """Catches the two clauses of the check joined with `and` (an empty list, or a number, slipped through)."""
    text = MINIMAL.format(name="toy_hand").split("joints:\n")[0] + f"joints: {joints}\n"
    with pytest.raises(ValueError, match="field 'joints': a kind 'joints' hand needs a non-empty list of joints"):
        hands.load_spec(_write(tmp_path, text))


def test_file_name_must_match_spec_name(tmp_path):
    path = _write(tmp_path, MINIMAL.format(name="other_name"))
    with pytest.raises(hands.SpecError, match="file name stem"):
        hands.load_spec(path)


def test_unknown_hand_lists_known_names():
    with pytest.raises(KeyError) as err:
        hands.get("linkerhand_l99")
    assert isinstance(err.value, ValueError)
    for name in ("linkerhand_l10", "inspire_rh56", "shadow"):
        assert name in str(err.value)


# ---------------------------------------------------------------------------------------------
# bad arrays
# ---------------------------------------------------------------------------------------------
def test_wrong_width_names_hand_width_and_joints():
    spec = hands.get("linkerhand_l10")
    with pytest.raises(ValueError) as err:
        spec.to_udhm(np.zeros((4, 9)))
    msg = str(err.value)
    assert "linkerhand_l10" in msg and "10" in msg and "thumb_cmc_roll" in msg and "(4, 9)" in msg
    with pytest.raises(ValueError, match="last dimension 22"):
        spec.from_udhm(np.zeros((4, 21)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 21, 3\)"):
        hands.get("human").to_udhm(np.zeros((4, 20, 3)))


@pytest.mark.parametrize("as_torch", [False, True])
def test_nan_raises(as_torch):
    spec = hands.get("inspire_rh56_unitree")
    raw = np.full((3, 6), 0.5)
    raw[1, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        spec.to_udhm(torch.tensor(raw) if as_torch else raw)
    with pytest.raises(ValueError, match="NaN"):
        spec.from_udhm(np.full((2, 22), np.nan))


@pytest.mark.parametrize("as_torch", [False, True])
def test_out_of_range_raise_or_clip_with_counted_warning(caplog, as_torch):
    spec = hands.get("linkerhand_l6")
    raw = np.array([[255.0, 255, 300, 255, -5, 255], [0, 0, 0, 0, 0, 0]])
    x = torch.tensor(raw) if as_torch else raw
    with pytest.raises(ValueError) as err:
        spec.to_udhm(x)  # default: raise
    msg = str(err.value)
    assert "2 raw value(s) out of range" in msg and "index_mcp_pitch" in msg and "ring_mcp_pitch" in msg
    assert "on_out_of_range='clip'" in msg
    with caplog.at_level(logging.WARNING, logger="lerobot_unidextok.hands.spec"):
        state = spec.to_udhm(x, on_out_of_range="clip")
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "clipped 2 of 12" in warnings[0].getMessage()
    state = np.asarray(state)
    assert state[0, 6] == pytest.approx(0.0)  # 300 -> 255 = open, not wrapped
    assert state[0, 14] == pytest.approx(1.26)  # -5 -> 0 = fully flexed
    with pytest.raises(ValueError, match="on_out_of_range"):
        spec.to_udhm(raw, on_out_of_range="wrap")


def test_range_slack_is_relative_to_the_joint_range(tmp_path):
    """The round-off slack at a range end is 1e-6 of the range width (at least 1e-6): on the toy wrist's
    [-10, 10] range (width 20) 10 + 1e-5 is accepted and 10 + 1e-4 is not. Catches the width computed as
    `hi + lo` (0 here, so the slack falls to 1e-6 and float32 round-off at the end raises)."""
    spec = hands.load_spec(_write(tmp_path, MINIMAL.format(name="toy_hand")))
    np.testing.assert_allclose(spec.to_radians(np.array([45.0, 45.0, 10.0 + 1e-5])), [np.pi / 4, np.pi / 4, 0.0])
    with pytest.raises(ValueError, match=r"wrist in \[-10, 10\]"):
        spec.to_radians(np.array([45.0, 45.0, 10.0 + 1e-4]))


def test_specs_are_immutable():
    """Registered specs are cached and shared by every caller, so they and their parts are frozen: a caller
    that edits one cannot change another's hand. Catches a spec dataclass left mutable (`frozen=False`)."""
    import dataclasses

    spec = hands.get("linkerhand_l10")
    parts = [spec, spec.joints[0], spec.joints[0].sides["right"], spec.skeleton_spec, spec._side_table("right")]
    parts += [spec.urdf, spec.urdf.keypoints["right"][0]]
    parts += [c for hand in hands.all_specs() for c in hand.coupled][:1]
    for part in parts:
        field = dataclasses.fields(part)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(part, field, None)
    assert {type(p).__name__ for p in parts} >= {
        "HandSpec",
        "JointSpec",
        "JointSide",
        "SkeletonSpec",
        "_SideTable",
        "UrdfSpec",
        "UrdfKeypoint",
        "CoupledJoint",
    }


def test_bad_side_and_mapping():
    spec = hands.get("linkerhand_l10")
    with pytest.raises(ValueError, match="sides are"):
        spec.to_udhm(np.zeros(10), side="middle")
    with pytest.raises(ValueError, match="append_pad"):
        spec.to_udhm(np.zeros(10), mapping="interleave")


def test_human_has_no_joint_radians():
    with pytest.raises(ValueError, match="keypoints"):
        hands.get("human").to_radians(np.zeros(22))


# ---------------------------------------------------------------------------------------------
# the spec format's per-side slots and signs, rest offsets, URDF keypoint maps
# ---------------------------------------------------------------------------------------------
TWO_SIDED = textwrap.dedent(
    """\
    name: two_sided
    embodiment: two_sided
    kind: joints
    sides: [right, left]
    native_units: rad
    joints:
      - name: a
        slot: index_mcp_abd
        raw_range: [-0.5, 0.5]
        rad_at_raw_range: [-0.5, 0.5]
        sign: -1
        left: {slot: ring_mcp_abd, sign: 1}
      - name: b
        slot: ring_mcp_abd
        raw_range: [0.2, 1.4]
        rad_at_raw_range: [0.2, 1.4]
        rest_rad: 1.0
        left: {slot: index_mcp_abd, rest_rad: 0.5}
    """
)


def test_per_side_slot_sign_and_rest_offset(tmp_path):
    """udhm[slot(side)] = sign(side) * (rad - rest_rad(side)); from_udhm inverts it (caught the old format,
    which had one slot per joint for both sides and no rest offset)."""
    spec = hands.load_spec(_write(tmp_path, TWO_SIDED, "two_sided"))
    raw = np.array([[0.3, 1.2]])
    right, left = spec.to_udhm(raw, "right"), spec.to_udhm(raw, "left")
    assert right[0, 5] == pytest.approx(-0.3) and right[0, 13] == pytest.approx(0.2)  # index, ring abd
    assert left[0, 13] == pytest.approx(0.3) and left[0, 5] == pytest.approx(0.7)
    np.testing.assert_allclose(spec.from_udhm(right, "right"), raw)
    np.testing.assert_allclose(spec.from_udhm(left, "left"), raw)
    assert spec.slot_map("left") == {"a": "ring_mcp_abd", "b": "index_mcp_abd"}
    np.testing.assert_allclose(spec.rest_rad("left"), [0.0, 0.5])
    lo, hi = spec.udhm_limits_rad("right")
    assert (lo[13], hi[13]) == pytest.approx((-0.8, 0.4))


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("left: {slot: ring_mcp_abd, sign: 1}", "left: {slot: middle_mcp_abd, sign: 1}", "fill different UDHM slots"),
        ("left: {slot: ring_mcp_abd, sign: 1}", "left: {slot: null}", "dropped on one side only"),
        ("left: {slot: index_mcp_abd, rest_rad: 0.5}", "left: {slot: ring_mcp_abd}", "joints\\[\\].slot"),
        ("rest_rad: 1.0", "rest_rad: one", "rest_rad"),
    ],
)
def test_per_side_mistakes_are_named(tmp_path, old, new, match):
    with pytest.raises(hands.SpecError, match=match):
        hands.load_spec(_write(tmp_path, TWO_SIDED.replace(old, new), "two_sided"))


def test_urdf_block_expands_side_templates_and_needs_every_keypoint(tmp_path):
    from lerobot_unidextok.constants import KEYPOINT_NAMES

    kps = "".join(f"\n    {k}: <side>_{k}_link" for k in KEYPOINT_NAMES)
    block = f"urdf:\n  source: test\n  file: hands/<S>_hand.urdf\n  keypoints:{kps}\n  left:\n    keypoints:\n      wrist: [L_base, [0, 0, -0.01]]\n"
    text = TWO_SIDED.replace("joints:\n", block + "joints:\n").replace(
        "    sign: -1\n", "    sign: -1\n    urdf_joint: <s>_a\n", 1
    )
    spec = hands.load_spec(_write(tmp_path, text, "two_sided"))
    assert spec.urdf.files == {"right": "hands/R_hand.urdf", "left": "hands/L_hand.urdf"}
    assert spec.urdf.keypoints["right"][0].link == "right_wrist_link"
    assert spec.urdf.keypoints["left"][0] == hands.UrdfKeypoint("L_base", (0.0, 0.0, -0.01))
    assert spec.urdf.keypoints["left"][4].link == "left_thumb_tip_link"
    assert spec.joints[0].sides["left"].urdf_joint == "l_a"
    with pytest.raises(hands.SpecError, match="missing \\['pinky_tip'\\]"):
        hands.load_spec(_write(tmp_path, text.replace("\n    pinky_tip: <side>_pinky_tip_link", ""), "two_sided"))
