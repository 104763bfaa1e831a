"""experiments/cross_embodiment.py on the synthetic G1 sample and a synthetic second hand (no ../shared): every arm
trains the same ACT, predictions come back in the target's own layout, and the reference is copying the state."""

import dataclasses

import numpy as np
import pytest

from experiments import cross_embodiment as ce
from experiments.policy_data import load_frames


@pytest.fixture(scope="module")
def result(converted_g1, tmp_path_factory):
    out = tmp_path_factory.mktemp("ce")
    argv = [f"--target={converted_g1}", "--others=[xhand_gestures]", "--target_episodes=[2]", "--seeds=[0]",
            "--other_episodes=2", "--other_frames=40", "--act.steps=3", "--act.batch_size=8", f"--output_root={out}"]  # fmt: skip
    return ce.run(ce.runtime.parse(ce.CrossEmbodimentConfig, argv))


def test_every_arm_is_scored_next_to_copying_the_state(result):
    s = result["summary"]
    assert set(s) == {"copy_state", *(f"2/{arm}" for arm in ce.ARMS)}
    for key, v in s.items():
        for metric in ce.METRICS:
            assert np.isfinite(v[metric]["mean"]) and v[metric]["mean"] >= 0, (key, metric)
    assert [x["name"] for x in result["sources"]] == ["target", "xhand_gestures"]
    assert "| 2 | udhm_mix |" in ce.markdown(result) and "| 2 | udhm_mix_old |" in ce.markdown(result)
    shares = {r["arm"]: r["target_share"] for r in result["runs"] if r["arm"] != "copy_state"}
    assert shares["target_only"] == 1.0 and abs(shares["udhm_mix"] - 0.5) < 0.2  # 3 steps x 8 rows drawn
    spread = result["held_out_state_z_p99"]
    assert list(spread) == ["2"] and spread["2"]["per_source"] > 0 and spread["2"]["pooled"] > 0
    assert "99th percentile of |z|" in ce.markdown(result)


def test_the_mixed_layout_puts_each_side_in_its_block_and_back(converted_g1):
    """The target's blocks go to the mixed (left, right) layout and a prediction comes back into its own
    columns unchanged; the packed-native view of the target is its native hand values, zero-padded."""
    frames = load_frames(converted_g1)
    src = ce.target_source(frames)
    assert src.udhm.shape == (len(frames.state), 44) and src.packed.shape[1] == ce.PACKED_WIDTH
    rows = np.arange(5)
    pred = np.repeat(src.udhm[rows][:, None, :], 3, axis=1)
    back = ce.to_target_layout(pred, "udhm_mix", frames, rows)
    np.testing.assert_allclose(back[:, 0][:, frames.block_columns], frames.state[rows][:, frames.block_columns])
    native = frames.native_layout("action").to_native(frames.state)[:, frames.native_hand_columns("action")]
    np.testing.assert_allclose(src.packed[:, : native.shape[1]], native)
    assert not src.packed[:, native.shape[1] :].any()


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="unknown arms"):
        ce.CrossEmbodimentConfig(arms=["target_only", "magic"])
    with pytest.raises(ValueError, match="normalise must be"):
        ce.CrossEmbodimentConfig(normalise="zscore")
    with pytest.raises(ValueError, match="hand_norm must be"):
        ce.CrossEmbodimentConfig(hand_norm="per_hand")
    with pytest.raises(ValueError, match="share_by must be"):
        ce.CrossEmbodimentConfig(share_by="weights")


def test_a_nested_flag_keeps_the_experiments_step_budget():
    """`--act.chunk_size=30` rebuilt the nested config from SmallACT's class defaults: 5000 steps instead of the
    experiment's 600 (and policy_tokens' 800), silently ~8x the CPU budget."""
    from experiments import policy_tokens

    cfg = ce.runtime.parse(ce.CrossEmbodimentConfig, ["--act.chunk_size=30"])
    assert (cfg.act.steps, cfg.act.chunk_size) == (600, 30)
    assert ce.runtime.parse(policy_tokens.PolicyTokensConfig, ["--act.lr=0.002"]).act.steps == 800


def _target_and_xhand(converted_g1):
    frames = load_frames(converted_g1)
    return frames, [ce.target_source(frames), ce.xhand_source(episodes=2, frames=40)]


def test_the_slots_a_source_lacks_are_its_specs_and_whole_missing_sides(converted_g1):
    from lerobot_unidextok import hands

    frames, (target, xhand) = _target_and_xhand(converted_g1)
    hand_of = dict(zip(frames.sides, frames.hands, strict=True))
    expected = np.concatenate([~hands.get(hand_of[s]).active_mask if s in hand_of else np.ones(22, bool)
                               for s in ce.SIDES])  # fmt: skip
    np.testing.assert_array_equal(ce.lacking(target, packed=False), expected)
    lacks = ce.lacking(xhand, packed=False)
    assert lacks[:22].all()  # the XHand source has no left hand: every left slot lacks
    np.testing.assert_array_equal(lacks[22:], ~hands.get("xhand1").active_mask)
    np.testing.assert_array_equal(ce.lacking(xhand, packed=True), np.arange(22) >= 12)


def test_the_new_recipe_normalises_per_source_masks_and_samples_the_old_arm_does_not(converted_g1):
    frames, sources = _target_and_xhand(converted_g1)
    cfg = ce.CrossEmbodimentConfig(target_episodes=[2], seeds=[0], hand_norm="per_source", hand_prior_per_hand=0.0,
                                   act=ce.CrossEmbodimentACT(steps=50, batch_size=8))  # fmt: skip
    target_train = np.flatnonzero(frames.episode == np.unique(frames.episode)[0])
    new = ce.training_set(cfg, "udhm_mix", sources, target_train, {}, seed=0)
    n0 = len(target_train)
    assert new.target_rows == n0 and len(new.hands) == n0 + len(sources[1].episode)  # no copies
    # the target half of the drawn batches (ShareSampler), though 1 row in (1 + 80 / n0) is its own
    assert len(new.order) == 50 * 8 and abs(np.mean(new.order < n0) - 0.5) < 0.06
    assert n0 / len(new.hands) < 0.45
    # each source's hand input with its own statistics: every column of each source mean 0, std 1 (or constant 0)
    for rows in (slice(0, n0), slice(n0, None)):
        x = new.hands[rows]
        np.testing.assert_allclose(x.mean(0), 0, atol=1e-5)
        assert np.all(np.isclose(x.std(0), 1, atol=1e-4) | (x.std(0) < 1e-6))
    raw = sources[0].udhm[target_train]
    np.testing.assert_allclose(new.state_scale(raw), new.hands[:n0])
    xhand_scale = ce.Standardiser.fit(sources[1].udhm)
    assert not np.allclose(new.state_scale.std[22:], xhand_scale.std[22:])  # the two hands' statistics differ
    # a lacked slot carries zero loss weight in every row; the hands' own slots are trained
    np.testing.assert_array_equal(new.slot_pad[:n0], np.tile(ce.lacking(sources[0], False), (n0, 1)))
    np.testing.assert_array_equal(new.slot_pad[n0:], np.tile(ce.lacking(sources[1], False), (len(sources[1].episode), 1)))
    np.testing.assert_array_equal(new.target_lacks, ce.lacking(sources[0], False))

    old = ce.training_set(cfg, ce.OLD_ARM, sources, target_train, {}, seed=0)
    assert old.slot_pad is None and old.order is None and old.state_scale is None and old.target_lacks is None
    assert old.target_rows > n0 and old.target_rows % n0 == 0  # the target's rows copied up to its share
    np.testing.assert_allclose(old.hands[:n0], raw)  # the raw input, z-scored pooled by train_act
    flags = ce.CrossEmbodimentConfig(hand_norm="pooled", mask_slots=False, share_by="copies", hand_prior_per_hand=0.0,
                                     act=cfg.act)  # fmt: skip
    same = ce.training_set(flags, "udhm_mix", sources, target_train, {}, seed=0)
    np.testing.assert_array_equal(same.hands, old.hands)  # the old recipe is these four flags away
    np.testing.assert_array_equal(same.actions, old.actions)
    assert new.actions_prescaled and not old.actions_prescaled and not same.actions_prescaled
    state = ce.training_set(dataclasses.replace(cfg, hand_norm="state"), "udhm_mix", sources, target_train, {}, 0)
    actions = ce.training_set(dataclasses.replace(cfg, hand_norm="actions"), "udhm_mix", sources, target_train, {}, 0)
    np.testing.assert_array_equal(state.hands, new.hands)  # the hand input per source, the actions pooled on top
    assert state.state_scale is not None and not state.actions_prescaled
    np.testing.assert_array_equal(actions.hands[:n0], raw)  # the hand input pooled, the actions per source only
    assert actions.state_scale is None and actions.actions_prescaled
    assert ce.CrossEmbodimentConfig().hand_norm == "actions"  # the recipe's default, as udt_hand_norm_state=false


def test_a_prior_moves_each_sources_statistics_toward_the_pool(converted_g1):
    """`--hand_prior` (as `--policy.udt_hand_stats_prior`): per slot, a source's mean is its frames' joined by
    `prior` episodes' worth of the pool's, the pool over both sides' hands that have the slot."""
    from lerobot_unidextok import hands

    frames, sources = _target_and_xhand(converted_g1)
    cfg = ce.CrossEmbodimentConfig(target_episodes=[2], seeds=[0], hand_norm="per_source", hand_prior_per_hand=0.0,
                                   act=ce.CrossEmbodimentACT(steps=50, batch_size=8))  # fmt: skip
    target_train = np.flatnonzero(frames.episode == np.unique(frames.episode)[0])
    own = ce.training_set(cfg, "udhm_mix", sources, target_train, {}, seed=0)
    shrunk = ce.training_set(dataclasses.replace(cfg, hand_prior=10.0), "udhm_mix", sources, target_train, {}, 0)
    n, m = len(target_train), len(sources[1].episode)
    prior = 10.0 * (n + m) / (1 + len(np.unique(sources[1].episode)))  # episodes at the mean episode length
    w = n / (n + prior)
    # the pool spans both sides (a slot is the same joint on either hand): the G1's left and right, the XHand's right
    target_hand = dict(zip(frames.sides, frames.hands, strict=True))
    x = sources[0].udhm[target_train]
    blocks = [(x[:, :22], hands.get(target_hand["left"]).active_mask, n),
              (x[:, 22:], hands.get(target_hand["right"]).active_mask, n),
              (sources[1].udhm[:, 22:], hands.get("xhand1").active_mask, m)]  # fmt: skip
    weight = np.stack([k * has for _, has, k in blocks])
    pool_mean = (weight * np.stack([b.mean(0) for b, _, _ in blocks])).sum(0) / np.maximum(weight.sum(0), 1)
    for side, (b, has, _) in zip((slice(0, 22), slice(22, 44)), blocks[:2], strict=True):
        expected = w * b.mean(0) + (1 - w) * pool_mean
        np.testing.assert_allclose(shrunk.state_scale.mean[side][has], expected[has], atol=1e-6)
        assert not np.allclose(shrunk.state_scale.mean[side][has], own.state_scale.mean[side][has])
    assert (shrunk.action_scale.std != own.action_scale.std).any()  # the per-source actions are shrunk too
    off = ce.training_set(dataclasses.replace(cfg, hand_prior=0.0), "udhm_mix", sources, target_train, {}, 0)
    np.testing.assert_array_equal(off.hands, own.hands)
    with pytest.raises(ValueError, match="hand_prior and hand_prior_per_hand must be"):
        ce.CrossEmbodimentConfig(hand_prior=-1.0)
    with pytest.raises(ValueError, match="hand_prior and hand_prior_per_hand must be"):
        ce.CrossEmbodimentConfig(hand_prior_per_hand=-1.0)


def test_the_default_prior_is_the_recipes_rule_per_other_hand(converted_g1):
    """By default (as act_udt_cpu.yaml's `udt_hand_stats_prior_per_hand: 2`) the prior is 2 episodes per other hand
    among the training rows' sources from four hands on: the experiment's pool (the G1's Inspire on both sides, the
    human hand, the L10, the XHand) gets 6; the G1 with the XHand alone, two hands, none; `udhm_mix_old` never
    shrinks."""
    from types import SimpleNamespace

    frames, sources = _target_and_xhand(converted_g1)
    assert ce.CrossEmbodimentConfig().hand_prior_per_hand == 2.0
    pool = [SimpleNamespace(hands=h) for h in (("inspire_rh56_unitree", "inspire_rh56_unitree"), (None, "human"),
                                               (None, "linkerhand_l10"), (None, "xhand1"))]  # fmt: skip
    assert ce.prior_episodes(pool, 2.0) == 6.0 and ce.prior_episodes(pool[:3], 2.0) == 0.0
    assert ce.prior_episodes(sources, 2.0) == 0.0
    cfg = ce.CrossEmbodimentConfig(target_episodes=[2], seeds=[0], hand_norm="per_source",
                                   act=ce.CrossEmbodimentACT(steps=50, batch_size=8))  # fmt: skip
    target_train = np.flatnonzero(frames.episode == np.unique(frames.episode)[0])
    default = ce.training_set(cfg, "udhm_mix", sources, target_train, {}, seed=0)
    own = ce.training_set(dataclasses.replace(cfg, hand_prior_per_hand=0.0), "udhm_mix", sources, target_train, {}, 0)
    fixed = ce.training_set(dataclasses.replace(cfg, hand_prior=2.0), "udhm_mix", sources, target_train, {}, 0)
    np.testing.assert_array_equal(default.state_scale.std, own.state_scale.std)
    assert (fixed.state_scale.std != own.state_scale.std).any()
    old = [ce.training_set(dataclasses.replace(cfg, hand_prior=k), ce.OLD_ARM, sources, target_train, {}, 0)
           for k in (0.0, 2.0)]  # fmt: skip
    np.testing.assert_array_equal(old[0].actions, old[1].actions)


def test_a_masked_slot_gets_exactly_zero_gradient():
    """train_act's `slot_pad` loss (act_udt's, on the stock ACT): the masked action column's output layer gets no
    gradient, every other column does."""
    import torch
    from lerobot.policies.act.modeling_act import ACTPolicy

    from experiments.policy_training import SmallACT, act_config
    from lerobot_unidextok.policies.act_udt.modeling_act_udt import ACTUdtPolicy
    from lerobot_unidextok.processor.slot_mask import ACTION_SLOT_PAD_KEY

    torch.manual_seed(0)
    size = SmallACT(dim_model=16, dim_feedforward=32, n_heads=2, latent_dim=4, chunk_size=3)
    policy = ACTPolicy(act_config(size, 2, 5, 4))
    batch = {"observation.state": torch.randn(6, 2), "observation.environment_state": torch.randn(6, 5),
             "action": torch.randn(6, 3, 4), "action_is_pad": torch.zeros(6, 3, dtype=torch.bool)}  # fmt: skip
    slot_pad = torch.zeros(6, 4, dtype=torch.bool)
    slot_pad[:, 1] = True
    loss, _ = ACTUdtPolicy.forward(policy, {**batch, ACTION_SLOT_PAD_KEY: slot_pad})
    loss.backward()
    head = policy.model.action_head
    assert torch.equal(head.weight.grad[1], torch.zeros_like(head.weight.grad[1])) and head.bias.grad[1] == 0
    assert all(head.weight.grad[c].abs().sum() > 0 for c in (0, 2, 3))


def test_the_recorded_command_leaves_out_where_the_run_writes():
    from experiments.common import shown_command

    cfg = ce.CrossEmbodimentConfig(output_root="elsewhere/out", cache_dir="elsewhere/data", hand_norm="pooled")
    assert ce.command_line(cfg) == "python experiments/cross_embodiment.py --hand_norm=pooled"
    recorded = {"command": "python experiments/cross_embodiment.py --output_root=x/y --cache_dir=x/z --seeds='[0]'"}
    assert shown_command(recorded["command"]) == "python experiments/cross_embodiment.py --seeds='[0]'"
