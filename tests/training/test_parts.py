"""Hand mixing, optimiser groups, schedule, rows and config checks."""

import math

import numpy as np
import pytest

from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.training import HandStates, TrainConfig, subsample_episodes
from lerobot_unidextok.training.optim import lr_at, param_groups


def test_no_weight_decay_on_codebooks_embeddings_norms_biases():
    model = UniDexTok(UniDexTokConfig.from_preset("tiny"))
    decay, no_decay = param_groups(model, 0.1)
    names = {id(p): n for n, p in model.named_parameters()}
    no_decay_names = {names[id(p)] for p in no_decay["params"]}
    decay_names = {names[id(p)] for p in decay["params"]}
    assert {"quantizer.codebooks", "hand_embed.weight", "enc_pos", "dec_pos"} <= no_decay_names
    assert all(n.endswith(".weight") for n in decay_names)
    assert "encoder.0.attn.qkv.weight" in decay_names
    assert not any(n.endswith(".bias") for n in decay_names)
    assert len(decay_names) + len(no_decay_names) == len(list(model.parameters()))


def test_warmup_then_cosine():
    lrs = [lr_at(s, 1000, 1e-3, 100, 0.1) for s in range(1000)]
    assert lrs[0] == pytest.approx(1e-5) and lrs[99] == pytest.approx(1e-3)
    assert lrs[100] == pytest.approx(1e-3)
    assert lrs[550] == pytest.approx(1e-4 + 0.9e-3 * 0.5 * (1 + math.cos(math.pi * 0.5)))
    assert all(a >= b for a, b in zip(lrs[100:], lrs[101:], strict=False))
    assert lr_at(1000, 1000, 1e-3, 100, 0.1) == pytest.approx(1e-4)


def test_hand_states_validation():
    with pytest.raises(ValueError, match=r"\(N, 22\)"):
        HandStates(np.zeros((3, 21)), np.array(["human"] * 3), np.ones((3, 21), bool))
    with pytest.raises(ValueError, match="NaN"):
        HandStates(np.full((2, 22), np.nan), np.array(["human"] * 2), np.ones((2, 22), bool))
    with pytest.raises(ValueError, match="hands must be"):
        HandStates(np.zeros((2, 22)), np.array(["human"]), np.ones((2, 22), bool))


def test_subsample_takes_whole_episodes_first():
    data = HandStates(
        np.zeros((100, 22)), np.array(["x"] * 100), np.ones((100, 22), bool), np.repeat(np.arange(10), 10)
    )
    few = subsample_episodes(data, 0.25, seed=0)
    assert len(few) == 25
    assert len(np.unique(few.episode_index)) == 3  # two whole episodes + 5 frames of a third
    with pytest.raises(ValueError, match="fraction"):
        subsample_episodes(data, 0.0)


def test_train_config_checks():
    with pytest.raises(ValueError, match="fraction"):
        TrainConfig(fraction=1.5)
    with pytest.raises(ValueError, match="hand weights"):
        TrainConfig(hand_weights={"human": -1.0})
    with pytest.raises(ValueError, match="reseed_until must be in"):
        TrainConfig(reseed_until=1.5)


def test_total_steps_from_epochs():
    """An epoch = the training rows once at the effective batch (batch x processes), rounded up, at least one
    step; without epochs the configured steps. Catches the rows / batch ratio inverted, the process count
    ignored, the floor of one step raised, and epochs=0 read as "derive the steps"."""
    from lerobot_unidextok.training.loop import total_steps

    assert total_steps(TrainConfig(epochs=2.0, batch_size=8), 100) == 25  # 200 rows / 8
    assert total_steps(TrainConfig(epochs=2.0, batch_size=8), 100, num_processes=2) == 13  # ceil(200 / 16)
    assert total_steps(TrainConfig(epochs=0.5, batch_size=64), 10) == 1  # 5 rows: one (partial) step
    assert total_steps(TrainConfig(epochs=0.0, steps=7, batch_size=8), 100) == 7


def test_joint_ranges_cover_the_registry_ranges_and_every_recorded_row():
    """`joint_ranges_rad` (the range normalisation of `input_norm="range"`) is the smallest per-joint box
    holding every training hand's registry range (both sides; UDHM limits for the human on its active
    joints) and every recorded row, also when a row lies outside its hand's range, and whatever the
    chunking; a hand's active joints are those of any of its rows, so an untracked frame (nothing active)
    changes nothing. Catches a bound left at its +-inf start, min/max swapped, rows skipped between chunks,
    the recorded rows ignored, or the active joints taken from every row (`any` -> `all`)."""
    from lerobot_unidextok import hands, udhm
    from lerobot_unidextok.training.loop import joint_ranges_rad

    rng = np.random.default_rng(0)
    l10 = hands.get("linkerhand_l10")
    mask_l10 = l10.mask("semantic")
    lo_r, hi_r = l10.udhm_limits_rad("right")
    lo_l, hi_l = l10.udhm_limits_rad("left")
    robot = rng.uniform(np.minimum(lo_r, lo_l), np.maximum(hi_r, hi_l), size=(40, 22)) * mask_l10
    slot = int(np.flatnonzero(mask_l10)[0])
    robot[17, slot] = max(hi_r[slot], hi_l[slot]) + 0.3  # one row beyond the hand's range: it counts too
    mask_h = np.ones(22, bool)
    mask_h[udhm.joint_index("pinky_metacarpal_twist")] = False  # a human layout without the twist
    human = rng.uniform(-0.2, 0.2, size=(25, 22)) * mask_h
    human[3, 5] = -2.5  # far below every limit
    masks_h = np.tile(mask_h, (25, 1))
    human[0], masks_h[0] = 0.0, False  # an untracked frame: zeros, nothing active
    data = HandStates(
        np.concatenate([robot, human]),
        np.array(["linkerhand_l10"] * 40 + ["human"] * 25),
        np.concatenate([np.tile(mask_l10, (40, 1)), masks_h]),
    )
    limits = udhm.JOINT_LIMITS_RAD
    rows = data.states_rad.astype(np.float64)
    want_lo = np.minimum.reduce([lo_r, lo_l, limits[:, 0] * mask_h, rows.min(0)])
    want_hi = np.maximum.reduce([hi_r, hi_l, limits[:, 1] * mask_h, rows.max(0)])
    for chunk_rows in (1 << 20, 7, 1):
        got = np.array(joint_ranges_rad(data, chunk_rows=chunk_rows))  # (22, 2)
        assert got.shape == (22, 2)
        np.testing.assert_allclose(got[:, 0], want_lo, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got[:, 1], want_hi, rtol=0, atol=1e-12)
    assert got[slot, 1] == pytest.approx(robot[17, slot], abs=1e-6) and got[5, 0] == pytest.approx(-2.5)


def test_joint_ranges_of_a_still_hand_are_the_union_of_its_sides():
    """One L10 frame at zero: the ranges are exactly the union of the right and left registry ranges (the
    left hand's abduction range is not the right's). Catches the sides' upper bounds met by their minimum
    (`hhi.max(0)` -> `hhi.min(0)`), which recorded motion of a wide hand would hide."""
    from lerobot_unidextok import hands
    from lerobot_unidextok.training.loop import joint_ranges_rad

    l10 = hands.get("linkerhand_l10")
    mask = l10.mask("semantic")
    data = HandStates(np.zeros((1, 22)), np.array(["linkerhand_l10"]), mask[None])
    lo_r, hi_r = l10.udhm_limits_rad("right")
    lo_l, hi_l = l10.udhm_limits_rad("left")
    got = np.array(joint_ranges_rad(data))
    assert (hi_r != hi_l).any() and (lo_r != lo_l).any()  # the sides differ, so the test can tell
    np.testing.assert_allclose(got[:, 0], np.minimum.reduce([lo_r, lo_l, np.zeros(22)]), atol=1e-12)
    np.testing.assert_allclose(got[:, 1], np.maximum.reduce([hi_r, hi_l, np.zeros(22)]), atol=1e-12)
