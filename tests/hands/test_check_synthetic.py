"""The kinematic check on a small URDF written here (no ../shared needed): right answers pass, wrong ones are named.

The toy hand is built so the answers follow from its geometry, not from the check: fingers along +z, palm
normal +x (palmar), thumb side +y. A rotation about -x swings a finger toward +y (UDHM abduction > 0), about
+y bends it toward +x (flexion > 0). The thumb's metacarpal points along (0, 1, 1)/sqrt(2) in the palm plane,
i.e. a UDHM CMC spread of 45 deg at rest: its joint about -z (the finger axis) swings it out of the palm
plane to the palm side (thumb_cmc_flex, +1); its joint about +x turns it inside the palm plane toward the
fingers (thumb_cmc_spread, sign -1, rest_rad +pi/4 so that rest reads 45 deg).
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.hands.__main__ import main as hands_cli

pytest.importorskip("yourdfpy")

from lerobot_unidextok.hands.check import check_spec  # noqa: E402
from lerobot_unidextok.hands.urdf import UrdfHand, measure_skeleton  # noqa: E402

FINGER_Y = {"index": 0.03, "middle": 0.0, "ring": -0.02, "pinky": -0.04}
BONES = (0.04, 0.025, 0.02)  # MCP->PIP, PIP->DIP, DIP->tip (m)


def _joint(name, parent, child, xyz, axis, lower=-1.5, upper=1.5, mimic=""):
    return f"""
  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>
    <limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/>{mimic}
  </joint>"""


def _fixed(name, parent, child, xyz):
    return f"""
  <joint name="{name}" type="fixed">
    <parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}" rpy="0 0 0"/>
  </joint>"""


def toy_urdf(joints_reversed: bool = False, ring_dip_multiplier: float = 0.5) -> str:
    links, joints = ["base"], []
    for f, y in FINGER_Y.items():
        links += [f"{f}_knuckle", f"{f}_proximal", f"{f}_middle", f"{f}_distal", f"{f}_tip"]
        joints.append(_joint(f"{f}_abd", "base", f"{f}_knuckle", f"0 {y} 0.095", "-1 0 0", -0.3, 0.3))
        joints.append(_joint(f"{f}_mcp", f"{f}_knuckle", f"{f}_proximal", "0 0 0", "0 1 0", 0.0, 1.5))
        pip_mimic = '\n    <mimic joint="ring_mcp" multiplier="1.0"/>' if f == "ring" else ""
        dip_mimic = {"middle": '\n    <mimic joint="middle_pip" multiplier="0.8"/>',
                     "ring": f'\n    <mimic joint="ring_pip" multiplier="{ring_dip_multiplier}"/>'}.get(f, "")  # fmt: skip
        joints.append(
            _joint(f"{f}_pip", f"{f}_proximal", f"{f}_middle", f"0 0 {BONES[0]}", "0 1 0", 0.0, 1.5, pip_mimic)
        )
        joints.append(_joint(f"{f}_dip", f"{f}_middle", f"{f}_distal", f"0 0 {BONES[1]}", "0 1 0", 0.0, 1.5, dip_mimic))
        joints.append(_fixed(f"{f}_tip_fixed", f"{f}_distal", f"{f}_tip", f"0 0 {BONES[2]}"))
    s = 0.04 / math.sqrt(2)
    links += ["thumb_base", "thumb_metacarpal", "thumb_tip"]
    joints.append(_joint("thumb_swing", "base", "thumb_base", "0.01 0.025 0.03", "0 0 -1", 0.0, 1.2))
    joints.append(_joint("thumb_turn", "thumb_base", "thumb_metacarpal", "0 0 0", "1 0 0", -0.5, 0.7))
    joints.append(_fixed("thumb_tip_fixed", "thumb_metacarpal", "thumb_tip", f"0 {3 * s} {3 * s}"))
    body = "".join(f'\n  <link name="{n}"/>' for n in links) + "".join(joints[::-1] if joints_reversed else joints)
    return f'<?xml version="1.0"?>\n<robot name="toy_hand">{body}\n</robot>\n'


def toy_spec(*, thumb_swapped=False, index_abd_sign=1, spread_rest=math.pi / 4) -> str:
    s = 0.04 / math.sqrt(2)
    fingers = "\n".join(
        f"""    {f}_mcp: {f}_knuckle
    {f}_pip: {f}_middle
    {f}_dip: {f}_distal
    {f}_tip: {f}_tip"""
        for f in FINGER_Y
    )
    joints = []
    for f in FINGER_Y:
        sign = index_abd_sign if f == "index" else 1
        joints.append(
            f"  - {{name: {f}_abd, slot: {f}_mcp_abd, sign: {sign}, raw_range: [-0.3, 0.3], rad_at_raw_range: [-0.3, 0.3]}}"
        )
        joints.append(f"  - {{name: {f}_mcp, slot: {f}_mcp_flex, raw_range: [0, 1.5], rad_at_raw_range: [0, 1.5]}}")
        if f != "ring":  # ring PIP is a mimic of its MCP in the URDF: not a native joint
            joints.append(f"  - {{name: {f}_pip, slot: {f}_pip_flex, raw_range: [0, 1.5], rad_at_raw_range: [0, 1.5]}}")
        if f not in ("middle", "ring"):
            joints.append(f"  - {{name: {f}_dip, slot: {f}_dip_flex, raw_range: [0, 1.5], rad_at_raw_range: [0, 1.5]}}")
    swing, turn = ("thumb_cmc_spread", "thumb_cmc_flex") if thumb_swapped else ("thumb_cmc_flex", "thumb_cmc_spread")
    joints.append(f"  - {{name: thumb_swing, slot: {swing}, raw_range: [0, 1.2], rad_at_raw_range: [0, 1.2]}}")
    joints.append(
        f"  - {{name: thumb_turn, slot: {turn}, sign: -1, rest_rad: {spread_rest}, raw_range: [-0.5, 0.7],"
        " rad_at_raw_range: [-0.5, 0.7]}"
    )
    return (
        textwrap.dedent(
            f"""\
        name: toy_hand
        embodiment: toy_hand
        kind: joints
        sides: [right]
        native_units: URDF radians
        urdf:
          source: written by tests/hands/test_check_synthetic.py
          file: toy_hand.urdf
          keypoints:
            wrist: base
            thumb_cmc: thumb_base
            thumb_mcp: [thumb_metacarpal, [0, {s}, {s}]]
            thumb_ip: [thumb_metacarpal, [0, {2 * s}, {2 * s}]]
            thumb_tip: thumb_tip
        """
        )
        + fingers
        + "\njoints:\n"
        + "\n".join(joints)
        + "\n"
    )


@pytest.fixture()
def toy(tmp_path):
    urdf = tmp_path / "toy_hand.urdf"
    urdf.write_text(toy_urdf())

    def write(**kw):
        path = tmp_path / "toy_hand.yaml"
        path.write_text(toy_spec(**kw))
        return hands.load_spec(path), urdf

    return write


def test_right_spec_agrees_everywhere(toy):
    spec, urdf = toy()
    report = check_spec(spec, urdf, "right")
    verdicts = {j.joint: j.verdict for j in report.joints}
    assert set(verdicts.values()) == {"ok"}, report.table()
    assert len(report.mapped) == spec.num_active == 15
    by_name = {j.joint: j for j in report.joints}
    assert by_name["thumb_swing"].found_slot == "thumb_cmc_flex" and by_name["thumb_swing"].found_sign == 1
    assert by_name["thumb_turn"].found_slot == "thumb_cmc_spread" and by_name["thumb_turn"].found_sign == -1
    assert abs(by_name["thumb_turn"].rest_error_deg) < 2.0  # rest_rad pi/4 reproduces the 45 deg spread
    assert "15/15 mapped joints agree" in report.summary()


def test_wrong_spec_is_flagged_with_the_fix(toy):
    """A deliberately wrong spec: thumb base joints swapped, index abduction sign
    flipped, and the thumb spread's rest offset missing on an otherwise right spec."""
    spec, urdf = toy(thumb_swapped=True, index_abd_sign=-1)
    verdicts = {j.joint: j for j in check_spec(spec, urdf, "right").joints}
    assert verdicts["thumb_swing"].verdict == "wrong slot" and verdicts["thumb_swing"].found_slot == "thumb_cmc_flex"
    assert verdicts["thumb_turn"].verdict == "wrong slot" and verdicts["thumb_turn"].found_slot == "thumb_cmc_spread"
    assert verdicts["index_abd"].verdict == "wrong sign"
    assert verdicts["middle_abd"].verdict == "ok"

    spec, urdf = toy(spread_rest=0.0)
    turn = next(j for j in check_spec(spec, urdf, "right").joints if j.joint == "thumb_turn")
    assert turn.verdict == "rest off"
    assert turn.rest_error_deg == pytest.approx(-45.0, abs=2.0)
    assert turn.suggested_rest_rad == pytest.approx(math.pi / 4, abs=0.04)


def test_mimic_chains_follow_their_root_leader(toy):
    """yourdfpy follows one mimic level; ring DIP mimics ring PIP which mimics ring MCP: DIP = 0.5 MCP."""
    spec, urdf = toy()
    hand = UrdfHand.load(urdf, spec.urdf.keypoints["right"])
    full = hand.full_cfg({"ring_mcp": 0.6})
    assert full["ring_pip"] == pytest.approx(0.6) and full["ring_dip"] == pytest.approx(0.3)
    assert "ring_pip" not in hand.joint_names and "ring_mcp" in hand.joint_names


def test_mimic_chains_resolve_whatever_the_joint_order(toy, tmp_path):
    """The same URDF with its joints listed in reverse (a follower before its leader): posing still follows
    the chain to its root. Catches chains left unflattened (`leader is None` -> `is not None`), which only
    works when every leader comes first in the file."""
    spec, urdf = toy()
    reordered = tmp_path / "reversed.urdf"
    reordered.write_text(toy_urdf(joints_reversed=True))
    hand = UrdfHand.load(reordered, spec.urdf.keypoints["right"])
    assert hand.mimics["ring_dip"] == ("ring_mcp", 0.5, 0.0)
    full = hand.full_cfg({"ring_mcp": 0.6})
    assert full["ring_pip"] == pytest.approx(0.6) and full["ring_dip"] == pytest.approx(0.3)
    np.testing.assert_allclose(
        hand.keypoints_m([{"ring_mcp": 0.6}]),
        UrdfHand.load(urdf, spec.urdf.keypoints["right"]).keypoints_m([{"ring_mcp": 0.6}]),
        atol=1e-12,
    )


def test_rest_pose_is_zero_clipped_into_each_joints_limits(toy, tmp_path):
    """The URDF rest pose (where skeletons are measured and rest offsets read) is 0 rad for every independent
    joint, clipped into its limits. Catches a rest angle other than 0 (`0.0` -> `1.0`: every finger bent)."""
    spec, urdf = toy()
    assert set(UrdfHand.load(urdf, spec.urdf.keypoints["right"]).rest_cfg().values()) == {0.0}
    raised = tmp_path / "raised.urdf"  # index MCP limited to [0.2, 1.5]: its rest is 0.2
    raised.write_text(urdf.read_text().replace('<limit lower="0.0" upper="1.5"', '<limit lower="0.2" upper="1.5"', 1))
    rest = UrdfHand.load(raised, spec.urdf.keypoints["right"]).rest_cfg()
    assert rest["index_mcp"] == pytest.approx(0.2) and rest["middle_mcp"] == 0.0


def test_measured_skeleton_has_the_urdf_bone_lengths(toy):
    spec, urdf = toy()
    skel = measure_skeleton(UrdfHand.load(urdf, spec.urdf.keypoints["right"]))
    np.testing.assert_allclose(np.asarray(skel.bone_lengths_m)[1:], np.tile(BONES, (4, 1)), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(skel.palm_offsets_m)[2]), 0.095, atol=1e-9)


def test_cli_prints_a_verdict_table_and_fails_on_disagreement(toy, capsys):
    spec, urdf = toy()
    assert hands_cli(["check", str(spec.path), "--urdf", str(urdf), "--side", "right"]) == 0
    out = capsys.readouterr().out
    assert "15/15 mapped joints agree" in out and "thumb_turn" in out and "verdict" in out
    spec, urdf = toy(thumb_swapped=True)
    assert hands_cli(["check", str(spec.path), "--urdf", str(urdf), "--side", "right"]) == 1
    assert "wrong slot (use thumb_cmc_flex, sign +1)" in capsys.readouterr().out


def test_missing_keypoint_link_is_named(toy, tmp_path):
    spec, urdf = toy()
    text = spec.path.read_text().replace("wrist: base", "wrist: forearm")
    spec.path.write_text(text)
    with pytest.raises(ValueError, match="wrist -> 'forearm'"):
        check_spec(hands.load_spec(spec.path), urdf, "right")


def test_cli_skeleton_prints_and_writes_the_measured_block(toy, capsys):
    """`skeleton` prints the URDF-measured block; `--write` puts it into the YAML (before `joints:` the first
    time, replacing it the second) and the reloaded spec's skeleton is the measured one to the printed 0.1 mm.
    Catches a block that loses lines (e.g. the bone lengths) and a write that appends instead of replacing."""
    spec, urdf = toy()
    measured = measure_skeleton(UrdfHand.load(urdf, spec.urdf.keypoints["right"]), "right")
    assert hands_cli(["skeleton", str(spec.path), "--urdf", str(urdf)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("skeleton:\n") and printed.count("\n    ") == 10  # 5 offsets + 5 bone rows

    assert hands_cli(["skeleton", str(spec.path), "--urdf", str(urdf), "--write"]) == 0
    written = spec.path.read_text()
    assert printed in written and written.count("skeleton:") == 1 and written.index(printed) < written.index("joints:")
    again = hands.load_spec(spec.path).skeleton()
    np.testing.assert_allclose(np.asarray(again.bone_lengths_m), np.asarray(measured.bone_lengths_m), atol=5e-5)
    np.testing.assert_allclose(np.asarray(again.palm_offsets_m), np.asarray(measured.palm_offsets_m), atol=5e-5)

    assert hands_cli(["skeleton", str(spec.path), "--urdf", str(urdf), "--write"]) == 0
    assert spec.path.read_text() == written  # replaced in place, not appended


def test_a_mimic_multiplier_of_zero_holds_the_follower(toy, tmp_path):
    """A URDF mimic multiplier of 0 is legal: ring DIP (which mimics ring PIP, itself a mimic of ring MCP) stays
    at 0 whatever the MCP does. Catches a 0 multiplier read as a missing one (`multiplier or 1.0`)."""
    spec, _ = toy()
    urdf = tmp_path / "zero.urdf"
    urdf.write_text(toy_urdf(ring_dip_multiplier=0.0))
    hand = UrdfHand.load(urdf, spec.urdf.keypoints["right"])
    assert hand.mimics["ring_dip"] == ("ring_mcp", 0.0, 0.0)
    full = hand.full_cfg({"ring_mcp": 0.6})
    assert full["ring_pip"] == pytest.approx(0.6) and full["ring_dip"] == 0.0
