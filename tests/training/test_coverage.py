"""Coverage sampler: synthesised rows stay inside each hand's joint ranges and masks, sources follow weights.

The expected ranges are typed here from the hands' documented conventions (docs/hands.md, the spec YAML
comments), not read from the code under test, so a wrong range in the sampler fails.
"""

import math

import numpy as np
import pytest

from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.training import HandStates
from lerobot_unidextok.training.coverage import SOURCES, CoverageConfig, MixtureSampler

DEG = math.pi / 180
# inspire_rh56_unitree (Unitree convention): fingers [0, 1.7] rad, thumb bend [0, 0.5], thumb rotation [-0.1, 1.3].
# UDHM = sign * (rad - rest) (docs/hands.md); from the URDF check: thumb rotation -> thumb_cmc_flex, sign +1,
# rest -0.33 rad right / -0.24 left; thumb bend -> thumb_cmc_spread, sign -1, rest 1.048 right / 1.08 left.
# Expected: the union of both sides' boxes.
INSPIRE = {
    "pinky_mcp_flex": (0.0, 1.7), "ring_mcp_flex": (0.0, 1.7), "middle_mcp_flex": (0.0, 1.7),
    "index_mcp_flex": (0.0, 1.7),
    "thumb_cmc_flex": (min(-0.1 + 0.33, -0.1 + 0.24), max(1.3 + 0.33, 1.3 + 0.24)),
    "thumb_cmc_spread": (min(1.048 - 0.5, 1.08 - 0.5), max(1.048, 1.08)),
}  # fmt: skip
# a few human UDHM limits (udhm/joints.py cites AAOS / Hume et al.): index MCP flex -45..100 deg, PIP -10..120,
# thumb CMC spread -10..95 (AAOS 0-80 radial abduction, 5 deg toward the thumb with the knuckle-row zero)
HUMAN = {"index_mcp_flex": (-45 * DEG, 100 * DEG), "index_pip_flex": (-10 * DEG, 120 * DEG),
         "thumb_cmc_spread": (-10 * DEG, 95 * DEG)}  # fmt: skip


def _inspire_rows(n: int, seed: int) -> HandStates:
    """Recorded-like Inspire rows that cover only a narrow band of the range (as the real G1 left hand does)."""
    rng = np.random.default_rng(seed)
    q = np.zeros((n, 22), np.float32)
    mask = np.zeros(22, bool)
    for joint, (lo, hi) in INSPIRE.items():
        mid = (lo + hi) / 2
        q[:, UDHM_INDEX[joint]] = rng.uniform(mid - 0.05, mid + 0.05, n)
        mask[UDHM_INDEX[joint]] = True
    return HandStates(q, np.full(n, "inspire_rh56_unitree"), np.tile(mask, (n, 1)), np.arange(n) // 10)


def _human_rows(n: int, seed: int) -> HandStates:
    from lerobot_unidextok.samples.motion import gesture_track

    q = gesture_track(np.random.default_rng(seed), n, 30.0).angles_rad.astype(np.float32)
    return HandStates(q, np.full(n, "human"), np.ones((n, 22), bool), np.arange(n) // 20)


def _by_source(batch, name: str) -> np.ndarray:
    return batch.sources == SOURCES.index(name)


def test_uniform_rows_fill_the_registered_inspire_range_and_keep_the_mask():
    data = _inspire_rows(200, 0)
    sampler = MixtureSampler(data, coverage=CoverageConfig(robot={"uniform": 1.0}), seed=0)
    batch = sampler.sample(20_000)
    assert (batch.sources == SOURCES.index("uniform")).all()
    active = data.masks[0]
    assert (batch.masks == active).all()
    assert (batch.states_rad[:, ~active] == 0).all()  # padded slots are never filled
    for joint, (lo, hi) in INSPIRE.items():
        col = batch.states_rad[:, UDHM_INDEX[joint]]
        assert col.min() >= lo - 1e-6 and col.max() <= hi + 1e-6, joint
        # covers the range, not just the recorded band: both ends within 1 % of the range
        assert col.min() < lo + 0.01 * (hi - lo) and col.max() > hi - 0.01 * (hi - lo), joint


def test_side_specific_ranges_stay_inside_one_side():
    """linkerhand_l10 has side-specific ranges: a uniform row lies inside the right or the left box."""
    from lerobot_unidextok import hands

    spec = hands.get("linkerhand_l10")
    lo_r, hi_r = spec.udhm_limits_rad("right")
    lo_l, hi_l = spec.udhm_limits_rad("left")
    assert not (np.allclose(lo_r, lo_l) and np.allclose(hi_r, hi_l)), "fixture needs a hand with per-side ranges"
    mask = spec.active_mask
    data = HandStates(np.where(mask, (lo_r + hi_r) / 2, 0)[None].repeat(5, 0), np.full(5, "linkerhand_l10"),
                      np.tile(mask, (5, 1)))  # fmt: skip
    x = MixtureSampler(data, coverage=CoverageConfig(robot={"uniform": 1.0}), seed=1).sample(5000).states_rad
    tol = 1e-6
    in_right = ((x >= lo_r - tol) & (x <= hi_r + tol)).all(1)
    in_left = ((x >= lo_l - tol) & (x <= hi_l + tol)).all(1)
    assert (in_right | in_left).all()
    assert in_right.mean() > 0.3 and in_left.mean() > 0.3


def test_human_sources_stay_inside_udhm_limits_and_follow_their_definitions():
    data = _human_rows(300, 0)
    weights = {"recorded": 1.0, "recombine": 1.0, "noise": 1.0, "interpolate": 1.0, "uniform": 1.0}
    sampler = MixtureSampler(data, coverage=CoverageConfig(human=weights, noise_deg=5.0), seed=0)
    batch = sampler.sample(10_000)
    shares = np.bincount(batch.sources, minlength=len(SOURCES)) / len(batch.sources)
    assert np.allclose(shares, 0.2, atol=0.02), shares
    for joint, (lo, hi) in HUMAN.items():
        col = batch.states_rad[:, UDHM_INDEX[joint]]
        assert col.min() >= lo - 1e-6 and col.max() <= hi + 1e-6, joint
    rec = data.states_rad
    # recorded rows are recorded rows
    r = batch.states_rad[_by_source(batch, "recorded")]
    assert (np.abs(r[:, None] - rec[None]).max(-1).min(1) == 0).all()
    # noise: within 5 deg of some recorded row, and not a copy
    nz = batch.states_rad[_by_source(batch, "noise")]
    dist = np.abs(nz[:, None] - rec[None]).max(-1).min(1)
    assert (dist <= 5 * DEG + 1e-6).all() and np.median(dist) > 1 * DEG
    # recombine: each finger's joints equal that finger of some recorded row
    rc = batch.states_rad[_by_source(batch, "recombine")]
    thumb = slice(0, 5)
    assert (np.abs(rc[:, None, thumb] - rec[None, :, thumb]).max(-1).min(1) == 0).all()
    pinky = slice(17, 22)
    assert (np.abs(rc[:, None, pinky] - rec[None, :, pinky]).max(-1).min(1) == 0).all()
    # interpolate: inside the recorded rows' box per joint
    it = batch.states_rad[_by_source(batch, "interpolate")]
    assert (it >= rec.min(0) - 1e-6).all() and (it <= rec.max(0) + 1e-6).all()
    # every human row is a full 22-DoF row
    assert batch.masks[batch.hands == sampler.hand_names.index("human")].all()


def test_hand_shares_then_source_shares():
    data = HandStates.concat([_inspire_rows(100, 0), _human_rows(400, 1)])
    cov = CoverageConfig(robot={"recorded": 1.0, "uniform": 3.0}, human={"recorded": 1.0})
    sampler = MixtureSampler(data, {"human": 3.0}, 1.0, cov, seed=0)
    batch = sampler.sample(40_000)
    human = batch.hands == sampler.hand_names.index("human")
    assert abs(human.mean() - 0.75) < 0.01
    assert (batch.sources[human] == SOURCES.index("recorded")).all()
    robot_uniform = (batch.sources[~human] == SOURCES.index("uniform")).mean()
    assert abs(robot_uniform - 0.75) < 0.02
    d = sampler.describe()["hands"]
    assert d["inspire_rh56_unitree"]["sources"] == {"recorded": 0.25, "uniform": 0.75}
    assert d["human"]["kind"] == "human" and d["inspire_rh56_unitree"]["ranges_from"] == "registry"
    only = MixtureSampler(data, {"inspire_rh56_unitree": 1.0}, 0.0, cov, seed=0)
    assert set(only.sample(500).hands.tolist()) == {only.hand_names.index("inspire_rh56_unitree")}
    with pytest.raises(ValueError, match="all hand weights are zero"):
        MixtureSampler(data, {}, 0.0, cov, seed=0)


def test_append_pad_layout_and_unregistered_hands():
    from lerobot_unidextok import hands

    spec = hands.get("inspire_rh56_unitree")
    pad_mask = spec.mask("append_pad")
    q = np.zeros((10, 22), np.float32)
    q[:, :6] = 0.3
    data = HandStates.concat([
        HandStates(q, np.full(10, "inspire_rh56_unitree"), np.tile(pad_mask, (10, 1))),
        HandStates(np.full((10, 22), 0.2, np.float32) + np.linspace(0, 0.1, 10)[:, None].astype(np.float32),
                   np.full(10, "my_lab_hand"), np.ones((10, 22), bool)),
    ])  # fmt: skip
    sampler = MixtureSampler(data, coverage=CoverageConfig(robot={"uniform": 1.0}), seed=0)
    batch = sampler.sample(4000)
    pad = batch.hands == sampler.hand_names.index("inspire_rh56_unitree")
    x = batch.states_rad[pad]
    # append_pad packs the UDHM values in native order: little, ring, middle, index (0..1.7), thumb bend
    # (as thumb_cmc_spread, INSPIRE above), thumb rotation (as thumb_cmc_flex)
    assert x[:, :4].max() <= 1.7 + 1e-6 and x[:, :4].max() > 1.6
    (s_lo, s_hi), (f_lo, f_hi) = INSPIRE["thumb_cmc_spread"], INSPIRE["thumb_cmc_flex"]
    assert x[:, 4].min() >= s_lo - 1e-6 and x[:, 4].max() <= s_hi + 1e-6
    assert x[:, 5].min() >= f_lo - 1e-6 and x[:, 5].max() <= f_hi + 1e-6 and (x[:, 6:] == 0).all()
    lab = batch.states_rad[~pad]  # no registered spec: the recorded range
    assert lab.min() >= 0.2 - 1e-6 and lab.max() <= 0.3 + 1e-6
    assert sampler.describe()["hands"]["my_lab_hand"]["ranges_from"] == "recorded"


def test_coverage_config_checks():
    with pytest.raises(ValueError, match="unknown sources"):
        CoverageConfig(robot={"uniformly": 1.0})
    with pytest.raises(ValueError, match="positive sum"):
        CoverageConfig(human={"recorded": 0.0})


def test_range_states_of_a_spec_object_equal_those_of_its_registered_name():
    """A spec that is not registered (`hands.load_spec`) is sampled like a registered one: same draws."""
    from lerobot_unidextok import hands
    from lerobot_unidextok.training.coverage import range_states

    for name in ("linkerhand_l6", "human"):
        by_name, by_spec = range_states(name, 300, seed=5), range_states(hands.get(name), 300, seed=5)
        np.testing.assert_array_equal(by_name.states_rad, by_spec.states_rad)
        np.testing.assert_array_equal(by_name.masks, by_spec.masks)
        assert set(by_spec.hands) == {name}

