"""Per-hand statistics shrunk toward the pool's (`conversion/hand_stats.shrunk_hand_stats`)."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.constants import ACTION, UDHM_DIM
from lerobot_unidextok.conversion.hand_stats import MIN_PRIOR_HANDS, pool_prior_episodes, shrunk_hand_stats

FEW, MANY = "inspire_rh56_unitree", "linkerhand_l10"


def _summary(x: np.ndarray) -> dict:
    return {"mean": list(x.mean(0)), "std": list(x.std(0)), "min": list(x.min(0)), "max": list(x.max(0)),
            "q01": list(np.quantile(x, 0.01, 0)), "q99": list(np.quantile(x, 0.99, 0)), "frames": len(x)}  # fmt: skip


def _frames(hand: str, n: int, seed: int, spread: float) -> np.ndarray:
    """(n, 22) angles in the hand's slots, zero in those it lacks (as a converted dataset holds them)."""
    rng = np.random.default_rng(seed)
    return rng.normal(0.4, spread, (n, UDHM_DIM)) * hands.get(hand).active_mask


def test_a_hands_statistics_become_those_of_its_frames_joined_by_the_pools():
    few, many = _frames(FEW, 30, 0, 0.01), _frames(MANY, 300, 1, 0.3)
    stats = {ACTION: {"right": {FEW: _summary(few), MANY: _summary(many)}}}
    # a prior as large as the pool's 330 frames: the few hand's frames joined by one copy of every pooled frame
    out = shrunk_hand_stats(stats, prior_frames=330)[ACTION]["right"]
    both = hands.get(FEW).active_mask & hands.get(MANY).active_mask
    only_few = hands.get(FEW).active_mask & ~hands.get(MANY).active_mask
    assert both.sum() >= 5
    joined = np.concatenate([few, few, many])  # its own 30, then the pool's 330 (its own 30 and the other's 300)
    np.testing.assert_allclose(np.asarray(out[FEW]["mean"])[both], joined.mean(0)[both], atol=1e-7)
    np.testing.assert_allclose(np.asarray(out[FEW]["std"])[both], joined.std(0)[both], atol=1e-7)
    # the narrow hand's std grew toward the pool's, and its frames are still its own
    assert (np.asarray(out[FEW]["std"])[both] > 5 * np.asarray(stats[ACTION]["right"][FEW]["std"])[both]).all()
    assert out[FEW]["frames"] == 30
    # a slot the other hand lacks: the pool there is the hand itself, so nothing moves
    np.testing.assert_allclose(np.asarray(out[FEW]["std"])[only_few], few.std(0)[only_few], atol=1e-7)
    # the range statistics widen toward the pool's lowest low and highest high, never past them
    lo, lo_pool = np.asarray(out[FEW]["min"])[both], np.minimum(few.min(0), many.min(0))[both]
    assert (lo <= few.min(0)[both] + 1e-9).all() and (lo >= lo_pool - 1e-9).all() and (lo < few.min(0)[both]).any()
    # the hand with ten times the frames moves far less (weight 300 / 630 on its own against 30 / 360)
    moved = np.abs(np.asarray(out[MANY]["std"]) - many.std(0))[both].max()
    moved_few = np.abs(np.asarray(out[FEW]["std"]) - few.std(0))[both].max()
    assert moved < moved_few / 2


def test_the_pool_spans_both_sides():
    """A UDHM slot is the same joint on a left and a right hand: a two-handed robot's left, the only left hand in a
    mix of right hands, is shrunk toward them as if it were on their side."""
    few, many = _frames(FEW, 30, 0, 0.01), _frames(MANY, 300, 1, 0.3)
    apart = shrunk_hand_stats({ACTION: {"left": {FEW: _summary(few)}, "right": {MANY: _summary(many)}}}, 330)[ACTION]
    together = shrunk_hand_stats({ACTION: {"right": {FEW: _summary(few), MANY: _summary(many)}}}, 330)[ACTION]
    assert apart["left"][FEW] == together["right"][FEW] and apart["right"][MANY] == together["right"][MANY]
    both = hands.get(FEW).active_mask & hands.get(MANY).active_mask
    joined = np.concatenate([few, few, many])
    np.testing.assert_allclose(np.asarray(apart["left"][FEW]["mean"])[both], joined.mean(0)[both], atol=1e-7)
    # the same hand on both sides of one robot: each side joined by the pool of the two
    left, right = _frames(FEW, 30, 2, 0.01), _frames(FEW, 30, 3, 0.01)
    two = shrunk_hand_stats({ACTION: {"left": {FEW: _summary(left)}, "right": {FEW: _summary(right)}}}, 60)[ACTION]
    joined = np.concatenate([left, left, right])
    on = hands.get(FEW).active_mask
    np.testing.assert_allclose(np.asarray(two["left"][FEW]["std"])[on], joined.std(0)[on], atol=1e-7)


def test_no_prior_and_one_hand_leave_the_statistics_as_they_are():
    """One hand on one side (a one-handed robot's own dataset) has no pool to be shrunk toward."""
    few, many = _frames(FEW, 30, 0, 0.01), _frames(MANY, 300, 1, 0.3)
    stats = {ACTION: {"right": {FEW: _summary(few), MANY: _summary(many)}}}
    assert shrunk_hand_stats(stats, prior_frames=0) is stats
    alone = {ACTION: {"right": {FEW: _summary(few)}}}
    assert shrunk_hand_stats(alone, prior_frames=1000) == alone


def test_the_pool_prior_counts_each_other_hand_once_and_starts_at_four_hands():
    """`pool_prior_episodes`: per other hand of the statistics' vocabulary from `MIN_PRIOR_HANDS` hands on (a hand
    on both sides is one hand); none in a mix of fewer."""
    few, many = _summary(_frames(FEW, 30, 0, 0.01)), _summary(_frames(MANY, 300, 1, 0.3))
    assert MIN_PRIOR_HANDS == 4
    assert pool_prior_episodes({ACTION: {"right": {FEW: few}}}, 2.0) == 0.0
    assert pool_prior_episodes({ACTION: {"left": {FEW: few}, "right": {FEW: few, MANY: many}}}, 2.0) == 0.0
    assert pool_prior_episodes({ACTION: {"right": {FEW: few, MANY: many, "leap": many}}}, 2.0) == 0.0
    four = {FEW: few, MANY: many, "leap": many, "allegro": many}
    assert pool_prior_episodes({ACTION: {"right": four}}, 2.0) == 6.0
    assert pool_prior_episodes({ACTION: {"left": {FEW: few}, "right": four}}, 2.0) == 6.0  # FEW counted once
    assert pool_prior_episodes({ACTION: {"right": {**four, "shadow": many, "xhand1": many}}}, 2.0) == 10.0
    assert pool_prior_episodes({ACTION: {"right": four}}, 0.0) == 0.0


def test_a_negative_prior_is_refused_by_name_through_lerobot_trains_parser(capsys):
    """lerobot-train's parser (draccus) says only "Couldn't instantiate class ACTUdtConfig"; the config says why."""
    import draccus
    from draccus.utils import DecodingError
    from lerobot.configs.train import TrainPipelineConfig

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies, as lerobot-train discovers them)
    from lerobot_unidextok.configs import resolve_config_path

    with pytest.raises(DecodingError, match="Couldn't instantiate class ACTUdtConfig"):
        draccus.parse(TrainPipelineConfig, config_path=resolve_config_path("lerobot/act_udt_cpu"),
                      args=["--dataset.repo_id=sim/x", "--policy.udt_hand_stats_prior=-1"])  # fmt: skip
    assert "act_udt: udt_hand_stats_prior is in episodes and must be >= 0" in capsys.readouterr().err
    with pytest.raises(DecodingError, match="Couldn't instantiate class ACTUdtConfig"):
        draccus.parse(TrainPipelineConfig, config_path=resolve_config_path("lerobot/act_udt_cpu"),
                      args=["--dataset.repo_id=sim/x", "--policy.udt_hand_stats_prior_per_hand=-2"])  # fmt: skip
    assert "udt_hand_stats_prior_per_hand is in episodes per other hand of the mix" in capsys.readouterr().err
