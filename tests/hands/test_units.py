"""Wrong native units raise with the likely fix, before anything converts silently."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.mapping import EpisodeError, map_episode


def _grasp(num: int = 120, seed: int = 0) -> np.ndarray:
    """Normalised 0-1 Inspire-like values (1 = open): a hand closing and opening, with noise."""
    t = np.linspace(0, 1, num)[:, None]
    closing = 1.0 - 0.7 * np.sin(np.pi * t) ** 2
    return np.clip(closing + np.random.default_rng(seed).normal(0, 0.02, (num, 6)), 0, 1)


def test_normalised_values_through_the_register_spec_raise():
    """Normalised 0-1 values through the 0-1000 register spec would convert into a hand held closed (all values
    < 1 of 1000) and validate: they raise, naming the rescaling and the Unitree spec."""
    values = _grasp()
    with pytest.raises(hands.NativeUnitsError) as err:
        hands.check_units(hands.get("inspire_rh56"), values, "right")
    msg = str(err.value)
    assert "multiply by 1000" in msg and "'inspire_rh56_unitree'" in msg and "1% of the lower end" in msg
    hands.check_units(hands.get("inspire_rh56_unitree"), values, "right")  # the right spec accepts them
    hands.check_units(hands.get("inspire_rh56"), 1000 * values, "left")  # and the register spec the registers


def test_degrees_where_radians_are_expected_raise():
    spec = hands.get("xhand1")
    lim = spec.limits_rad("right")
    rad = np.random.default_rng(1).uniform(lim[:, 0], lim[:, 1], size=(80, spec.num_native))
    hands.check_units(spec, rad, "right")
    with pytest.raises(hands.NativeUnitsError, match="np.deg2rad"):
        hands.check_units(spec, np.degrees(rad), "right")


def test_a_hand_held_still_at_one_end_is_not_flagged():
    """An idle hand resting open for a whole episode is data, not a units error (nothing moves)."""
    hands.check_units(hands.get("inspire_rh56"), np.full((50, 6), 1000.0), "right")


def test_conversion_stops_the_episode_with_the_fix():
    values = _grasp()
    raw = RawEpisode(
        source_file="g1_episode.parquet",
        fps=30.0,
        hands=[HandStream(side="right", hand="inspire_rh56", state_native=values, action_native=values)],
        task="pick",
    )
    with pytest.raises(EpisodeError, match="inspire_rh56_unitree"):
        map_episode(raw)
    ok = RawEpisode("g1_episode.parquet", 30.0, [HandStream("right", "inspire_rh56_unitree", values, values)])
    assert map_episode(ok).state_rad.shape == (120, 22)


def test_one_moving_joint_is_enough_to_flag_values_held_at_one_end():
    """Normalised 0-1 values where only one finger moves (the others rest) still sit within 1 % of the lower
    end of a 0-1000 range: flagged. Catches "moving" read as "every joint moves" (`.max()` -> `.min()` over
    the joints' spreads), which let such a stream convert into a hand held closed."""
    values = np.full((60, 6), 0.9)
    values[:, 2] = np.linspace(0.2, 1.0, 60)  # one finger closes and opens; five stay open
    with pytest.raises(hands.NativeUnitsError, match="1% of the lower end"):
        hands.check_units(hands.get("inspire_rh56"), values, "right")
    hands.check_units(hands.get("inspire_rh56"), 1000 * values, "right")  # the same motion in registers is fine


def test_degrees_a_little_past_the_limits_still_get_the_fix():
    """Recorded joints often overshoot the URDF limits by a few percent (calibration offsets). Degrees where
    radians are expected, 5 % of the frames 3 % of the range past each limit, still get the deg2rad
    suggestion (each rescaling may leave values up to 5 % of the range outside). Catches that slack
    shrunk to a hair (`0.05 * span` -> `0.05 / span`), which leaves the user with no suggested fix."""
    spec = hands.get("xhand1")
    lim = spec.limits_rad("right")
    a = spec.active_joint_indices
    rad = np.random.default_rng(2).uniform(lim[:, 0], lim[:, 1], size=(200, spec.num_native))
    span = lim[a, 1] - lim[a, 0]
    rad[:10, a] = lim[a, 1] + 0.03 * span  # 10 of 200 frames overshoot every joint's upper limit
    rad[10:20, a] = lim[a, 0] - 0.03 * span  # and 10 its lower limit
    with pytest.raises(hands.NativeUnitsError, match=r"Likely fix: degrees given where radians are expected"):
        hands.check_units(spec, np.degrees(rad), "right")


def test_one_value_a_little_past_the_range_is_named():
    """The range check allows float rounding only (1e-6 of the range): one joint 2 % of its range past its
    upper limit in one frame is reported with the joint and its reach. Catches a tolerance of a whole range
    width (`1e-6` -> `1.000001`), which let values far outside through."""
    spec = hands.get("xhand1")
    lim = spec.limits_rad("right")
    a = spec.active_joint_indices
    rad = np.random.default_rng(3).uniform(lim[:, 0], lim[:, 1], size=(50, spec.num_native))
    rad[:2, a] = lim[a, 1]  # exactly at the limit: fine
    hands.check_units(spec, rad, "right")
    j = int(a[0])
    rad[7, j] = lim[j, 1] + 0.02 * (lim[j, 1] - lim[j, 0])
    with pytest.raises(hands.NativeUnitsError, match=rf"1 of 50 frames outside the native range \({spec.joint_names[j]}"):
        hands.check_units(spec, rad, "right")


def test_a_few_glitched_frames_are_not_called_other_units():
    """One Unitree Inspire value of 3.0 (range 0-1) among 100 good frames got the advice "divide by 10" for
    the whole stream; it is a glitch, named as one. Most frames outside still get the rescaling."""
    spec = hands.get("inspire_rh56_unitree")
    values = np.random.default_rng(0).uniform(0.05, 0.95, size=(100, spec.num_native))
    values[40, 0] = 3.0
    with pytest.raises(hands.NativeUnitsError, match="1 of 100 frames outside .* glitches") as err:
        hands.check_units(spec, values, "right")
    assert "divide" not in str(err.value)
    values[40, 0] = 0.5
    with pytest.raises(hands.NativeUnitsError, match="value\\(s\\) outside .* divide by 1000"):
        hands.check_units(spec, values * 1000, "right")
