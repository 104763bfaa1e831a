"""hands.urdf.resolve_mimic_chains: mimic tags followed to their root leader (no URDF library needed)."""

from __future__ import annotations

import pytest

from lerobot_unidextok.hands.urdf import resolve_mimic_chains

JOINTS = ("a", "b", "c", "d", "e")


def test_a_chain_composes_multipliers_and_offsets():
    """b = 2a + 0.1, c = 3b + 0.2 -> c = 6a + 0.5; d = 0.5c - 1 -> d = 3a - 0.75. A direct follower is unchanged."""
    roots = resolve_mimic_chains({"d": ("c", 0.5, -1.0), "c": ("b", 3.0, 0.2), "b": ("a", 2.0, 0.1)}, JOINTS)
    assert roots["b"] == ("a", 2.0, 0.1)
    assert roots["c"][0] == "a" and roots["c"][1:] == pytest.approx((6.0, 0.5))
    assert roots["d"][0] == "a" and roots["d"][1:] == pytest.approx((3.0, -0.75))


def test_a_multiplier_of_zero_stays_zero():
    """A mimic multiplier of 0 is legal (the follower sits at its offset): it is not read as a missing 1.
    Catches `multiplier or 1.0`, which made such a follower copy its leader."""
    roots = resolve_mimic_chains({"b": ("a", 0.0, 0.3), "c": ("b", 2.0, 0.1)}, JOINTS)
    assert roots["b"] == ("a", 0.0, 0.3)
    assert roots["c"] == ("a", 0.0, pytest.approx(0.7))  # c = 2 (0 a + 0.3) + 0.1


def test_cycles_and_unknown_leaders_are_named():
    with pytest.raises(ValueError, match=r"cycle: b -> c -> b"):
        resolve_mimic_chains({"b": ("c", 1.0, 0.0), "c": ("b", 1.0, 0.0)}, JOINTS)
    with pytest.raises(ValueError, match=r"joint 'b' mimics unknown joint 'zz'"):
        resolve_mimic_chains({"c": ("b", 1.0, 0.0), "b": ("zz", 1.0, 0.0)}, JOINTS)


# -- forward kinematics against yourdfpy's (the reference: its scene graph, one configuration at a time) ----------

ARM_URDF = """<robot name="arm">
  <link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/><link name="tip"/>
  <joint name="j_rev" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0.01 0.02 0.03" rpy="0.3 -0.2 0.1"/><axis xyz="0 2 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j_cont" type="continuous"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.05" rpy="0 0.4 0"/><axis xyz="1 0 0"/></joint>
  <joint name="j_fixed" type="fixed"><parent link="b"/><child link="c"/><origin xyz="0.02 0 0" rpy="0.1 0 0.5"/></joint>
  <joint name="j_pri" type="prismatic"><parent link="c"/><child link="d"/>
    <origin xyz="0 0.01 0"/><axis xyz="0 0 1"/><limit lower="0" upper="0.05" effort="1" velocity="1"/></joint>
  <joint name="j_mimic" type="revolute"><parent link="d"/><child link="tip"/><origin xyz="0 0 0.04"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/><mimic joint="j_rev" multiplier="0.5" offset="0.1"/></joint>
</robot>
"""


def _reference_links(model, cfgs, links):
    """yourdfpy's own forward kinematics of `model` (a yourdfpy.URDF with its scene graph): link -> (N, 4, 4)."""
    import numpy as np

    out = {link: [] for link in links}
    for cfg in cfgs:
        model.update_cfg({k: v for k, v in cfg.items() if k in model.actuated_joint_names})
        for link in links:
            out[link].append(model.get_transform(frame_to=link, frame_from=model.base_link))
    return {link: np.stack(tfs) for link, tfs in out.items()}


def test_forward_kinematics_is_yourdfpys_for_every_joint_type(tmp_path):
    """Revolute about a non-unit axis, continuous, fixed, prismatic and a mimic follower, every configuration at
    once: the same transforms as yourdfpy's one-at-a-time scene graph, and the keypoints their offsets."""
    import numpy as np

    yourdfpy = pytest.importorskip("yourdfpy")
    from lerobot_unidextok.hands.spec import UrdfKeypoint
    from lerobot_unidextok.hands.urdf import UrdfHand

    path = tmp_path / "arm.urdf"
    path.write_text(ARM_URDF)
    keypoints = tuple(UrdfKeypoint(link, (0.01 * i, -0.02, 0.005 * i)) for i, link in
                      enumerate(["base", "a", "b", "c", "d", "tip"] * 3 + ["tip", "d", "a"]))  # fmt: skip
    hand = UrdfHand.load(path, keypoints)
    assert hand.joint_names == ("j_rev", "j_cont", "j_pri") and hand.mimics == {"j_mimic": ("j_rev", 0.5, 0.1)}
    rng = np.random.default_rng(0)
    cfgs = [{"j_rev": rng.uniform(-1, 1), "j_cont": rng.uniform(-3, 3), "j_pri": rng.uniform(0, 0.05)} for _ in range(7)]
    full = [hand.full_cfg(c) for c in cfgs]
    reference = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)  # its mimic tag honoured
    want = _reference_links(reference, full, ["a", "b", "c", "d", "tip"])
    got = hand.link_transforms(full, ["a", "b", "c", "d", "tip"])
    for link in want:
        np.testing.assert_allclose(got[link], want[link], atol=1e-12, err_msg=link)
    points = hand.keypoints_m(cfgs)  # (7, 21, 3): mimics followed
    assert points.shape == (7, 21, 3)
    tip = want["tip"][:, :3, :3] @ np.array([0.01 * 5, -0.02, 0.005 * 5]) + want["tip"][:, :3, 3]
    np.testing.assert_allclose(points[:, 5], tip, atol=1e-12)
    np.testing.assert_allclose(hand.keypoints_m(full, followers=False), points, atol=1e-15)
    origins = hand.link_origins_m(cfgs[0])
    np.testing.assert_allclose(origins["tip"], want["tip"][0, :3, 3], atol=1e-12)
    with pytest.raises(ValueError, match="does not give the movable joint 'j_mimic'"):
        hand.keypoints_m(cfgs, followers=False)


def test_forward_kinematics_is_yourdfpys_on_every_shared_urdf():
    """Every registered hand's URDF in ../shared (skips without it), at random configurations within limits,
    against yourdfpy's scene graph of the same model (its mimic tags removed: chains of mimics are resolved by
    `full_cfg`, which yourdfpy does not do)."""
    import numpy as np

    pytest.importorskip("yourdfpy")
    from pathlib import Path

    from lerobot_unidextok import hands
    from lerobot_unidextok.hands.urdf import UrdfHand
    from lerobot_unidextok.utils.shared_data import urdf_dir

    root = urdf_dir(Path(__file__).resolve().parents[2])
    cases = [(hands.get(n), s) for n in hands.names() if hands.get(n).urdf is not None for s in hands.get(n).sides]
    cases = [(spec, side, root / spec.urdf.files[side]) for spec, side in cases if (root / spec.urdf.files[side]).is_file()]
    if not cases:
        pytest.skip(f"no robot URDFs at {root}; set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf")
    rng = np.random.default_rng(1)
    for spec, side, path in cases:
        hand = UrdfHand.load(path, spec.urdf.keypoints[side])
        limits = [np.clip(hand.limits_rad(j), -np.pi, np.pi) for j in hand.joint_names]
        cfgs = [hand.full_cfg({j: float(rng.uniform(*lim)) for j, lim in zip(hand.joint_names, limits, strict=True)}) for _ in range(3)]
        links = sorted({k.link for k in hand.keypoints})
        want, got = _reference_links(hand.model, cfgs, links), hand.link_transforms(cfgs, links)
        for link in links:
            np.testing.assert_allclose(got[link], want[link], atol=1e-9, err_msg=f"{spec.name} {side} {link}")
    assert len(cases) >= 10
