"""unidextok.hand_normalizer: each UDHM block of each row normalised with the statistics of the hand it holds,
the passthrough columns with their own, restored after the policy, a zero-shot hand on pooled statistics, saved
and reloaded as a LeRobot pipeline step."""

import numpy as np
import pytest
import torch
from lerobot.lerobot_types import TransitionKey
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.converters import identity_transition

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE, UDHM_DIM
from lerobot_unidextok.conversion.hand_stats import _summary
from lerobot_unidextok.processor import STATS_OF_MODE, HandNormalizerStep

VOCAB = ["inspire_rh56_unitree", "shadow"]  # 6 slots, small moves / 22 slots, large moves
NAMES = ["task_x", "task_y", *udhm_state_names(["right"])]  # 2 passthrough columns, one block
PASS_MEAN, PASS_STD = np.array([5.0, -3.0]), np.array([2.0, 0.5])


def _frames(hand: str, n: int, rng) -> np.ndarray:
    """(n, 24) rows of one hand: its own slots move around its own centre and scale, the others are 0."""
    scale, centre = (0.02, 0.3) if hand == VOCAB[0] else (1.5, -2.0)
    block = (centre + scale * rng.standard_normal((n, UDHM_DIM))) * hands.get(hand).active_mask
    task = PASS_MEAN + PASS_STD * rng.standard_normal((n, 2))
    return np.concatenate([task, block], 1).astype(np.float32)


def _data(n: int = 4000, seed: int = 0):
    rng = np.random.default_rng(seed)
    rows = {h: _frames(h, n, rng) for h in VOCAB}
    stats = {key: {"right": {h: _summary(rows[h][:, 2:].astype(np.float64)) for h in VOCAB}} for key in (OBS_STATE, ACTION)}
    together = np.concatenate(list(rows.values()))
    dataset = {key: {"mean": together.mean(0), "std": together.std(0), "min": together.min(0),
                     "max": together.max(0), "q01": np.quantile(together, 0.01, 0),
                     "q99": np.quantile(together, 0.99, 0)} for key in (OBS_STATE, ACTION)}  # fmt: skip
    for key in (OBS_STATE, ACTION):
        dataset[key]["mean"][:2], dataset[key]["std"][:2] = PASS_MEAN, PASS_STD
    return rows, stats, dataset


def _step(mode: str, stats=None, dataset=None, norm="MEAN_STD", **kw) -> HandNormalizerStep:
    lo, hi = STATS_OF_MODE[norm]
    picked = {key: {"right": {h: {lo: s[lo], hi: s[hi], "frames": s["frames"]} for h, s in per["right"].items()}}
              for key, per in (stats or {}).items()}  # fmt: skip
    return HandNormalizerStep(mode=mode, modes={OBS_STATE: norm, ACTION: norm}, state_names=NAMES, action_names=NAMES,
                              hand_vocabulary=VOCAB, stats=picked, dataset_stats=dataset or {}, **kw)  # fmt: skip


def _batch(rows: dict, n: int = 1000):
    """One batch holding both hands, interleaved: (2n, 24) values and (2n, 1) hand ids."""
    x = torch.from_numpy(np.concatenate([rows[VOCAB[0]][:n], rows[VOCAB[1]][:n]]))
    ids = torch.tensor([0] * n + [1] * n)[:, None]
    order = torch.randperm(2 * n, generator=torch.Generator().manual_seed(0))
    return x[order], ids[order]


def test_two_hands_of_very_different_ranges_are_normalised_each_by_its_own_and_restored_exactly():
    rows, stats, dataset = _data()
    pre = _step("normalize", stats, dataset)
    post = _step("unnormalize", pair=pre)
    post.load_state_dict(pre.state_dict())
    x, ids = _batch(rows)
    out = pre({TransitionKey.OBSERVATION: {OBS_STATE: x, OBS_HAND_IDS: ids}, TransitionKey.ACTION: x.clone()})
    z_state, z_action = out[TransitionKey.OBSERVATION][OBS_STATE], out[TransitionKey.ACTION]
    torch.testing.assert_close(z_state, z_action)
    for v, hand in enumerate(VOCAB):
        active = torch.from_numpy(hands.get(hand).active_mask)
        z = z_state[ids[:, 0] == v][:, 2:]
        # each hand's own slots: about zero mean and unit std (the batch is 1000 of the 4000 frames per hand)
        assert z[:, active].mean(0).abs().max() < 0.1, z[:, active].mean(0)
        assert (z[:, active].std(0) - 1).abs().max() < 0.1, z[:, active].std(0)
        assert torch.equal(z[:, ~active], torch.zeros_like(z[:, ~active]))  # the slots it lacks stay 0
    # the passthrough columns with their own statistics (the dataset's), not a hand's
    want = (x[:, :2].numpy() - PASS_MEAN) / PASS_STD
    np.testing.assert_allclose(z_state[:, :2].numpy(), want, rtol=1e-5, atol=1e-5)
    # one pooled z-score would have scaled the Inspire's moves by the Shadow's: its values would be ~0.01 std
    pooled = (x[:, 2:] - x[:, 2:].mean(0)) / x[:, 2:].std(0)
    assert pooled[ids[:, 0] == 0][:, 2 + 10 : 2 + 12].std(0).max() < 0.2
    # restored with the hands the paired pre step saw
    back = post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: z_action})[TransitionKey.ACTION]
    torch.testing.assert_close(back, x, rtol=0, atol=2e-6)


def test_quantile_mode_maps_each_hands_own_q01_q99_to_minus_one_and_one():
    rows, stats, dataset = _data()
    pre = _step("normalize", stats, dataset, norm="QUANTILES")
    x, ids = _batch(rows, n=4000)
    z = pre({TransitionKey.OBSERVATION: {OBS_STATE: x, OBS_HAND_IDS: ids}})[TransitionKey.OBSERVATION][OBS_STATE]
    for v, hand in enumerate(VOCAB):
        active = torch.from_numpy(hands.get(hand).active_mask)
        z_hand = z[ids[:, 0] == v][:, 2:][:, active].double()
        torch.testing.assert_close(torch.quantile(z_hand, 0.01, dim=0), -torch.ones(int(active.sum()), dtype=torch.float64),
                                   atol=1e-3, rtol=0)  # fmt: skip
        torch.testing.assert_close(torch.quantile(z_hand, 0.99, dim=0), torch.ones(int(active.sum()), dtype=torch.float64),
                                   atol=1e-3, rtol=0)  # fmt: skip


def test_a_zero_shot_hand_gets_the_pooled_statistics_of_the_known_hands_that_have_each_slot():
    rows, stats, _ = _data()
    step = _step("normalize", stats, extra_hands=["allegro"], fixed_hand_ids=[2])
    x = torch.ones(1, len(NAMES)) * 0.7
    z = step({TransitionKey.OBSERVATION: {OBS_STATE: x}})[TransitionKey.OBSERVATION][OBS_STATE][0, 2:]
    inspire, shadow = (stats[OBS_STATE]["right"][h] for h in VOCAB)
    has_inspire = hands.get(VOCAB[0]).active_mask
    for slot in range(UDHM_DIM):
        parts = [(shadow["frames"], shadow["mean"][slot], shadow["std"][slot])]
        if has_inspire[slot]:
            parts.append((inspire["frames"], inspire["mean"][slot], inspire["std"][slot]))
        n = sum(p[0] for p in parts)
        mean = sum(p[0] * p[1] for p in parts) / n
        std = np.sqrt(sum(p[0] * (p[2] ** 2 + p[1] ** 2) for p in parts) / n - mean**2)
        assert z[slot].item() == pytest.approx((0.7 - mean) / std, rel=1e-4), slot
    # a slot no known hand has passes unscaled: a hand-only vocabulary of the Inspire, bound to a Shadow
    only = HandNormalizerStep(mode="normalize", modes={OBS_STATE: "MEAN_STD"}, state_names=NAMES, action_names=NAMES,
                              hand_vocabulary=VOCAB[:1], extra_hands=["shadow"], fixed_hand_ids=[1],
                              stats={OBS_STATE: {"right": {VOCAB[0]: inspire}}})  # fmt: skip
    z = only({TransitionKey.OBSERVATION: {OBS_STATE: x}})[TransitionKey.OBSERVATION][OBS_STATE][0, 2:]
    assert torch.equal(z[~torch.from_numpy(has_inspire)], x[0, 2:][~torch.from_numpy(has_inspire)])


def test_relative_offsets_are_scaled_not_shifted_and_unnormalize_zeroes_the_slots_a_hand_lacks():
    rows, stats, _ = _data()
    pre = _step("normalize", stats, relative_actions=True, fixed_hand_ids=[0])
    post = _step("unnormalize", stats, relative_actions=True, fixed_hand_ids=[0])
    zero = torch.zeros(3, 4, len(NAMES))  # (B, chunk, A): "hold the state" stays zero both ways
    assert torch.equal(pre({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: zero})[TransitionKey.ACTION], zero)
    out = post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: torch.ones(3, 4, len(NAMES))})[TransitionKey.ACTION]
    lacks = ~torch.from_numpy(hands.get(VOCAB[0]).active_mask)
    assert torch.equal(out[..., 2:][..., lacks], torch.zeros(3, 4, int(lacks.sum())))
    assert (out[..., 2:][..., ~lacks] > 0).all()
    assert torch.equal(out[..., :2], torch.ones(3, 4, 2))  # relative passthrough offsets: unscaled


def test_saved_and_reloaded_bit_exactly_and_an_unbound_reloaded_post_step_says_to_bind(tmp_path):
    import lerobot_unidextok.processor  # noqa: F401  (registration)

    rows, stats, dataset = _data()
    pre = _step("normalize", stats, dataset)
    post = _step("unnormalize", pair=pre)
    post.load_state_dict(pre.state_dict())
    for name, step in (("pre", pre), ("post", post)):
        PolicyProcessorPipeline(steps=[step], name=name, to_transition=identity_transition,
                                to_output=identity_transition).save_pretrained(tmp_path, config_filename=f"{name}.json")  # fmt: skip
    pre2 = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="pre.json", to_transition=identity_transition,
                                                   to_output=identity_transition).steps[0]  # fmt: skip
    post2 = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="post.json", to_transition=identity_transition,
                                                    to_output=identity_transition).steps[0]  # fmt: skip
    x, ids = _batch(rows, n=20)
    a = pre({TransitionKey.OBSERVATION: {OBS_STATE: x, OBS_HAND_IDS: ids}})[TransitionKey.OBSERVATION][OBS_STATE]
    b = pre2({TransitionKey.OBSERVATION: {OBS_STATE: x, OBS_HAND_IDS: ids}})[TransitionKey.OBSERVATION][OBS_STATE]
    assert torch.equal(a, b)
    with pytest.raises(KeyError, match="unidextok-deploy"):
        post2({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: x})


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="mode must be one of"):
        HandNormalizerStep(mode="scale", state_names=NAMES, action_names=NAMES, hand_vocabulary=VOCAB)
    with pytest.raises(ValueError, match="keys must be"):
        HandNormalizerStep(modes={OBS_STATE: "Z"}, state_names=NAMES, action_names=NAMES, hand_vocabulary=VOCAB)
    with pytest.raises(ValueError, match="one hand per block"):
        HandNormalizerStep(modes={OBS_STATE: "MEAN_STD"}, state_names=NAMES, action_names=NAMES,
                           hand_vocabulary=VOCAB, fixed_hand_ids=[0, 1])  # fmt: skip
    step = _step("normalize", fixed_hand_ids=[0])
    with pytest.raises(ValueError, match="24 wide|expected 24"):
        step({TransitionKey.OBSERVATION: {OBS_STATE: torch.zeros(2, 23)}})


@pytest.mark.parametrize("norm", ["MEAN_STD", "MIN_MAX"])
def test_a_column_that_never_varies_comes_back_as_its_value_whatever_the_policy_predicts(norm):
    """A wrist roll the demonstrations never moved (std 0): a prediction's noise there must not become a command.
    Scaled by 1 on the way back it did (0.005-0.007 rad of roll in closed loop, which the state, z-scored by its
    1e-4 std, then read 50 stds out: the Inspire's press fell from 30/50 to 7/50 alone); LeRobot's MEAN_STD
    returns the mean, and so does this step, for a passthrough column and a hand's slot alike."""
    rows, stats, dataset = _data()
    for key in (OBS_STATE, ACTION):
        dataset[key]["std"][0], dataset[key]["min"][0], dataset[key]["max"][0] = 0.0, 5.0, 5.0
        dataset[key]["mean"][0] = 5.0
    steady = hands.get(VOCAB[1]).active_mask.nonzero()[0][0]  # one of the Shadow's slots, held at 0.25 rad
    for key in (OBS_STATE, ACTION):
        s = stats[key]["right"][VOCAB[1]]
        for name in ("std",):
            s[name][steady] = 0.0
        for name in ("mean", "min", "max", "q01", "q99", "q10", "q90"):
            s[name][steady] = 0.25
    post = _step("unnormalize", stats, dataset, norm)
    noisy = torch.randn(64, len(NAMES), generator=torch.Generator().manual_seed(1))
    out = post({TransitionKey.ACTION: noisy, TransitionKey.OBSERVATION: {OBS_HAND_IDS: torch.ones(64, 1, dtype=torch.long)}})
    action = out[TransitionKey.ACTION]
    torch.testing.assert_close(action[:, 0], torch.full((64,), 5.0))  # the constant passthrough column
    torch.testing.assert_close(action[:, 2 + steady], torch.full((64,), 0.25))  # the hand's constant slot
    assert action[:, 1].std() > 0.1  # a column that varies still follows the prediction
    pre = _step("normalize", stats, dataset, norm)
    x = torch.full((4, len(NAMES)), 5.0)
    normed = pre({TransitionKey.OBSERVATION: {OBS_STATE: x, OBS_HAND_IDS: torch.ones(4, 1, dtype=torch.long)}})
    assert torch.isfinite(normed[TransitionKey.OBSERVATION][OBS_STATE]).all()
    assert normed[TransitionKey.OBSERVATION][OBS_STATE][:, 0].abs().max() == 0  # its value, centred, scaled by 1
