"""Every shipped hand spec loads, validates and round-trips native -> UDHM -> native (numpy and torch)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_DIM, UDHM_INDEX
from lerobot_unidextok.udhm import Skeleton

JOINT_HANDS = [n for n in hands.names() if hands.get(n).kind == "joints"]
EXPECTED = {
    "human", "linkerhand_l6", "linkerhand_l10", "linkerhand_l20", "linkerhand_l21", "linkerhand_l25",
    "linkerhand_o7", "xhand1", "inspire_rh56", "inspire_rh56_unitree", "leap", "allegro", "shadow", "brainco_revo1",
}  # fmt: skip


def _cases():
    return [(n, s) for n in JOINT_HANDS for s in hands.get(n).sides]


def _sample_raw(spec: hands.HandSpec, side: str, shape: tuple[int, ...], seed: int = 0) -> np.ndarray:
    rr = spec.raw_range(side)  # (J, 2)
    return np.random.default_rng(seed).uniform(rr[:, 0], rr[:, 1], size=(*shape, spec.num_native))


def test_registry_lists_every_required_hand():
    assert EXPECTED <= set(hands.names())


@pytest.mark.parametrize("name", hands.names())
def test_spec_loads_and_validates(name):
    spec = hands.load_spec(hands.SPECS_DIR / f"{name}.yaml")
    assert spec.name == name == hands.get(name).name
    assert spec.embodiment and spec.sides and spec.native_units
    mask = spec.active_mask
    assert mask.shape == (UDHM_DIM,) and mask.dtype == bool
    assert mask.sum() == spec.num_active > 0
    if spec.kind == "joints":
        assert len(set(spec.joint_names)) == spec.num_native
        slots = [j.slot for j in spec.joints if j.slot is not None]
        assert len(set(slots)) == len(slots) == spec.num_active
        assert sorted(np.flatnonzero(mask)) == sorted(UDHM_INDEX[s] for s in slots)
        for side in spec.sides:
            lim = spec.limits_rad(side)
            assert (lim[:, 0] <= lim[:, 1]).all()


def test_inspire_register_and_unitree_share_embodiment_and_udhm():
    reg, uni = hands.get("inspire_rh56"), hands.get("inspire_rh56_unitree")
    assert reg.embodiment == uni.embodiment == "inspire_rh56"
    n = np.random.default_rng(1).uniform(0, 1, size=(50, 6))
    np.testing.assert_allclose(reg.to_udhm(1000 * n), uni.to_udhm(n), atol=1e-12)


@pytest.mark.parametrize(("name", "side"), _cases())
def test_native_udhm_native_round_trip_numpy(name, side):
    spec = hands.get(name)
    raw = _sample_raw(spec, side, (5, 7))
    state = spec.to_udhm(raw, side)
    assert state.shape == (5, 7, UDHM_DIM)
    assert (state[..., ~spec.active_mask] == 0).all()
    back = spec.from_udhm(state, side)
    assert back.shape == raw.shape
    active = np.array([j.slot is not None for j in spec.joints])
    np.testing.assert_allclose(back[..., active], raw[..., active], rtol=0, atol=1e-9 * spec.raw_range(side).max())
    defaults = np.array([j.sides[side].default_raw for j in spec.joints])
    np.testing.assert_array_equal(back[..., ~active], np.broadcast_to(defaults[~active], back[..., ~active].shape))
    # radians round trip too, and vendor direction: raw -> rad is the published linear map
    rad = spec.to_radians(raw, side)
    np.testing.assert_allclose(spec.from_radians(rad, side)[..., active], raw[..., active], atol=1e-9 * 1000)


@pytest.mark.parametrize(("name", "side"), _cases())
def test_torch_matches_numpy(name, side):
    spec = hands.get(name)
    raw = _sample_raw(spec, side, (3, 4), seed=2)
    state_np = spec.to_udhm(raw, side)
    state_t = spec.to_udhm(torch.tensor(raw), side)
    assert isinstance(state_t, torch.Tensor) and state_t.dtype == torch.float64
    np.testing.assert_allclose(state_t.numpy(), state_np, atol=1e-12)
    back_t = spec.from_udhm(state_t, side)
    np.testing.assert_allclose(back_t.numpy(), spec.from_udhm(state_np, side), atol=1e-9)
    f32 = spec.to_udhm(torch.tensor(raw, dtype=torch.float32), side)
    assert f32.dtype == torch.float32
    np.testing.assert_allclose(f32.numpy(), state_np, atol=1e-5)


@pytest.mark.parametrize(("name", "side"), _cases())
def test_append_pad_round_trip_and_mask(name, side):
    spec = hands.get(name)
    raw = _sample_raw(spec, side, (6,), seed=3)
    packed = spec.to_udhm(raw, side, mapping="append_pad")
    semantic = spec.to_udhm(raw, side)
    mask = spec.mask("append_pad")
    assert mask[: spec.num_active].all() and not mask[spec.num_active :].any()
    assert (packed[..., ~mask] == 0).all()
    # same values, only the placement differs
    np.testing.assert_allclose(np.sort(packed[..., mask], -1), np.sort(semantic[..., spec.active_mask], -1))
    back = spec.from_udhm(packed, side, mapping="append_pad")
    active = np.array([j.slot is not None for j in spec.joints])
    np.testing.assert_allclose(back[..., active], raw[..., active], atol=1e-9 * 1000)


@pytest.mark.parametrize("name", JOINT_HANDS)
def test_from_udhm_clips_to_joint_limits(name):
    spec = hands.get(name)
    state = np.random.default_rng(4).uniform(-4, 4, size=(20, UDHM_DIM))
    for side in spec.sides:
        raw = spec.from_udhm(state, side)
        rr = spec.raw_range(side)
        assert (raw >= rr[:, 0]).all() and (raw <= rr[:, 1]).all()
        lo, hi = spec.udhm_limits_rad(side)
        again = spec.to_udhm(raw, side)
        assert (again >= lo - 1e-9).all() and (again <= hi + 1e-9).all()
        # a state inside the limits is reproduced exactly on the active slots
        inside = np.clip(state, lo, hi)
        again = spec.to_udhm(spec.from_udhm(inside, side), side)
        np.testing.assert_allclose(again, inside * spec.active_mask, atol=1e-9)


def test_vendor_directions():
    """LinkerHand 255 = open, Inspire register 1000 = open, Unitree 1 = open, BrainCo and ROHand 0 = open.

    Open is near UDHM zero (within the robots' rest offsets, < 0.3 rad), closed is flexed past 1 rad.
    """
    for name, open_raw, closed_raw, slot in [
        ("linkerhand_l10", 255, 0, "index_mcp_flex"),
        ("inspire_rh56", 1000, 0, "index_mcp_flex"),
        ("inspire_rh56_unitree", 1.0, 0.0, "index_mcp_flex"),
        ("brainco_revo1", 0, 100, "index_mcp_flex"),
        ("oymotion_rohand", 0, 65535, "index_mcp_flex"),
    ]:
        spec = hands.get(name)
        i = UDHM_INDEX[slot]
        assert abs(spec.to_udhm(np.full(spec.num_native, open_raw))[i]) < 0.3
        assert spec.to_udhm(np.full(spec.num_native, closed_raw))[i] > 1.0


def test_rohand_logical_positions_follow_the_protocol():
    """ROHand ModBus order [thumb, index, middle, ring, little, thumb_rotation]; 0 = extended, 65535 = bent; the
    thumb rotation 0 = beside the palm, 65535 = opposed 90 deg (OHandModBusRTUProtocol)."""
    spec = hands.get("oymotion_rohand")
    assert spec.joint_names == ("thumb", "index", "middle", "ring", "little", "thumb_rotation")
    opened, bent = spec.to_udhm(np.zeros(6)), spec.to_udhm(np.full(6, 65535.0))
    fingers = [UDHM_INDEX[f"{f}_mcp_flex"] for f in ("index", "middle", "ring", "pinky")]
    assert np.all(np.abs(opened[fingers]) < np.radians(10)) and np.all(bent[fingers] > np.radians(75))
    rotation = UDHM_INDEX["thumb_cmc_flex"]
    assert bent[rotation] - opened[rotation] == pytest.approx(np.pi / 2, abs=1e-3)
    assert bent[UDHM_INDEX["thumb_mcp_flex"]] > opened[UDHM_INDEX["thumb_mcp_flex"]]
    for side in spec.sides:  # the left hand reads the same logical positions the same way
        np.testing.assert_allclose(spec.to_udhm(np.full(6, 30000.0), side), spec.to_udhm(np.full(6, 30000.0)))


def test_linkerhand_l10_side_specific_ranges():
    spec = hands.get("linkerhand_l10")
    raw = np.zeros(10)  # all channels at 0
    right, left = spec.to_radians(raw, "right"), spec.to_radians(raw, "left")
    assert right[0] == pytest.approx(0.75) and left[0] == pytest.approx(1.45)  # vendor thumb pitch max per side
    full = np.full(10, 255.0)
    # roll channels follow the current SDK mapping.py (right index [-0.26, 0.21], ring [0, 0.21], pinky
    # [0, 0.34], derict 0); the copy the spec used before had right maxima [0, 0.13, 0.26] and derict -1
    np.testing.assert_allclose(spec.to_radians(full, "right")[6:9], [0.21, 0.21, 0.34])
    np.testing.assert_allclose(spec.to_radians(raw, "right")[6:9], [-0.26, 0.0, 0.0])
    assert spec.to_radians(full, "left")[6] == pytest.approx(0.26)


def test_dropped_and_coupled_joints_are_documented():
    l20 = hands.get("linkerhand_l20")
    assert l20.dropped_joints == ("reserved_11", "reserved_12", "reserved_13", "reserved_14")
    assert l20.num_active == 16
    assert all(j.note for j in l20.joints if j.slot is None)
    assert any(c.ratio == pytest.approx(2.4) for c in hands.get("inspire_rh56").coupled)  # Unitree URDF mimic
    assert hands.get("shadow").active_mask.all()


@pytest.mark.parametrize("name", hands.names())
def test_skeleton_is_a_udhm_skeleton(name):
    """Robot hands with a URDF carry the skeleton measured from it (bone lengths exactly as in the YAML);
    the others a scaled human skeleton. `describe()` says which (metrics print it)."""
    spec = hands.get(name)
    skel = spec.skeleton()
    assert isinstance(skel, Skeleton)
    if spec.skeleton_spec.measured:
        bones = np.array([spec.skeleton_spec.bone_lengths_m[f] for f in ("thumb", "index", "middle", "ring", "pinky")])
        np.testing.assert_allclose(skel.bone_lengths_m, bones)
        assert 0.12 < float(skel.hand_length_m()) < 0.35  # a hand, in metres
        assert spec.skeleton_spec.describe().startswith("measured:") and "skeleton" in spec.skeleton_spec.source
    else:
        ratio = skel.hand_length_m() / Skeleton.default().hand_length_m()
        assert ratio == pytest.approx(spec.skeleton_spec.scale)
        assert "approximation" in spec.skeleton_spec.describe()


def test_describe_lists_native_joints_and_slots():
    text = hands.describe()
    for name in hands.names():
        assert f"== {name} " in text
    assert "thumb_cmc_roll" in text and "thumb_mcp_abd" in text  # L10 channel 9 and its slot
    assert "reserved_11" in text and "(dropped)" in text
    assert "LFJ5" in text and "pinky_metacarpal_twist" in text
    # a slot that differs between the sides is shown with the other side's (Allegro's left index/ring order),
    # and only there
    allegro = {ln.split()[1]: ln for ln in hands.describe(["allegro"]).splitlines() if ln.strip()[:1].isdigit()}
    assert allegro["joint_0.0"].endswith("index_mcp_abd (left: ring_mcp_abd)")
    assert allegro["joint_4.0"].endswith("middle_mcp_abd")


def test_docs_cover_every_hand():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "hands.md").read_text(encoding="utf-8")
    for name in hands.names():
        assert f"`{name}`" in doc, f"docs/hands.md does not describe {name}"
