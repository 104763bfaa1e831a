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
