"""hands.urdf: URDF mimic chains made one level deep for dex-retargeting (no URDF library needed)."""

import pytest

from lerobot_unidextok.hands.urdf import URDFError, flatten_mimic_chains, read_joints

JOINT = '<joint name="{}" type="revolute"><limit lower="0" upper="1"/>{}</joint>'
MIMIC = '<mimic joint="{}" multiplier="{}" offset="{}"/>'


def test_flattened_urdf_follows_root_leaders(tmp_path):
    """flatten_mimic_chains rewrites a chain to its root in the XML dex-retargeting reads; a multiplier of 0 is
    kept, and a cycle is a URDFError naming the file."""
    joints = [
        JOINT.format("a", ""),
        JOINT.format("b", MIMIC.format("a", 0, 0.3)),
        JOINT.format("c", MIMIC.format("b", 2, 0.1)),
    ]
    src = tmp_path / "hand.urdf"
    src.write_text(f'<robot name="r">{"".join(joints)}</robot>')
    flat = read_joints(flatten_mimic_chains(src, tmp_path / "flat.urdf"))
    assert flat["b"].mimic == ("a", 0.0, 0.3)
    assert flat["c"].mimic[:2] == ("a", 0.0) and flat["c"].mimic[2] == pytest.approx(0.7)
    src.write_text(
        f'<robot name="r">{JOINT.format("a", MIMIC.format("b", 1, 0))}{JOINT.format("b", MIMIC.format("a", 1, 0))}</robot>'
    )
    with pytest.raises(URDFError, match=r"hand.urdf: mimic joints form a cycle"):
        flatten_mimic_chains(src, tmp_path / "flat.urdf")
