"""Pooling hands in a `<type>_udt` policy: per-hand normalisation (`unidextok.hand_normalizer`) and no loss on the
slots a row's hand lacks (`unidextok.slot_mask` + the ACT / Diffusion loss), on a real mix of two robots
(unidextok-mix: a G1-like robot with two Inspire hands and a right-only LinkerHand L10 robot)."""

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from l10_robot import HAND as L10
from robot_udhm import INSPIRE

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE, UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.policies import ACTUdtConfig, DiffusionUdtConfig
from lerobot_unidextok.processor import ACTION_SLOT_PAD_KEY, HandNormalizerStep, SlotMaskStep

CHUNK = 4
TINY = {
    "act_udt": dict(chunk_size=CHUNK, n_action_steps=CHUNK, dim_model=32, n_heads=2, dim_feedforward=64,
                    n_encoder_layers=1, n_decoder_layers=1, use_vae=False),
    "diffusion_udt": dict(down_dims=(16, 32), horizon=8, n_action_steps=4, num_inference_steps=2,
                          diffusion_step_embed_dim=16),
}  # fmt: skip
CLASSES = {"act_udt": ACTUdtConfig, "diffusion_udt": DiffusionUdtConfig}


def _config(kind: str, tok_dir, root, **kw):
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.datasets import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata("test/mix", root=root)
    width = meta.features[OBS_STATE]["shape"][0]
    cfg = CLASSES[kind](
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, (width,))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, (meta.features[ACTION]["shape"][0],))},
        udt_pretrained=str(tok_dir), device="cpu", **TINY[kind], **kw,
    )  # fmt: skip
    cfg._runtime_dataset_meta = meta
    cfg.validate_features()
    return cfg, meta


def _batch(root, meta, horizon: int, episodes: list[int], frame: int = 3, obs_steps: int = 0) -> dict:
    """One frame of each episode with its action chunk (and `obs_steps` observation steps, for Diffusion),
    collated as LeRobot's dataloader does."""
    from lerobot.datasets import LeRobotDataset

    deltas = {ACTION: [i / meta.fps for i in range(horizon)]}
    if obs_steps:
        deltas.update({k: [i / meta.fps for i in range(1 - obs_steps, 1)] for k in (OBS_STATE, OBS_HAND_IDS)})
    ds = LeRobotDataset("test/mix", root=root, delta_timestamps=deltas)
    starts = {int(e): int(s) for e, s in zip(ds.meta.episodes["episode_index"], ds.meta.episodes["dataset_from_index"],
                                             strict=True)}  # fmt: skip
    items = [ds[starts[e] + frame] for e in episodes]
    return torch.utils.data.default_collate([{k: v for k, v in it.items() if isinstance(v, torch.Tensor)}
                                             for it in items])  # fmt: skip


def _mix_episodes(root) -> tuple[list[int], list[int]]:
    record = UdhmDatasetMeta(root).record
    by = {0: [], 1: []}
    for e in record.episodes:
        if e.split == "train":
            by[e.origin["mix_source"]].append(e.episode_index)
    return by[0][:2], by[1][:2]


def test_a_mix_policy_normalises_each_hand_by_its_own_statistics(tok_dir, g1_l10_mix):
    from lerobot_unidextok.policies.act_udt import make_act_udt_pre_post_processors

    cfg, meta = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_norm_state=True)  # the state half too
    record = UdhmDatasetMeta(g1_l10_mix).record
    # the mix recorded each hand's statistics; the policy took them, and LeRobot's normaliser leaves state and
    # action to the per-hand step
    assert set(record.hand_stats) == {OBS_STATE, ACTION, "action_delta"}
    assert cfg.udt_hand_stats["modes"] == {OBS_STATE: "MEAN_STD", ACTION: "MEAN_STD"}
    assert cfg.udt_hand_stats[OBS_STATE]["right"][L10]["std"] == record.hand_stats[OBS_STATE]["right"][L10]["std"]
    assert cfg.normalization_mapping["STATE"].value == "IDENTITY" and cfg.normalization_mapping["ACTION"].value == "IDENTITY"
    pre, post = make_act_udt_pre_post_processors(cfg, dataset_stats=meta.stats)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("HandNormalizerStep") < names.index("SlotMaskStep") < names.index("NormalizerProcessorStep")
    post_names = [type(s).__name__ for s in post.steps]
    assert post_names.index("HandNormalizerStep") == post_names.index("UnnormalizerProcessorStep") + 1
    # a batch with both robots' rows: each right block z-scored by its own hand's statistics
    g1, l10 = _mix_episodes(g1_l10_mix)
    batch = _batch(g1_l10_mix, meta, CHUNK, g1 + l10)
    out = pre(dict(batch))
    ids = batch[OBS_HAND_IDS]
    right = find_udhm_blocks(cfg.udt_state_names)[[b.side for b in find_udhm_blocks(cfg.udt_state_names)].index("right")]
    for row in range(len(ids)):
        hand = cfg.udt_hand_vocabulary[int(ids[row, -1])]
        s = record.hand_stats[OBS_STATE]["right"][hand]
        std = np.where(np.asarray(s["std"]) > 1e-6, s["std"], 1.0)
        want = (batch[OBS_STATE][row, right.slice].numpy() - np.asarray(s["mean"])) / std
        np.testing.assert_allclose(out[OBS_STATE][row, right.slice].numpy(), want, rtol=1e-4, atol=1e-4)
    # the action chunk restored by the post step (its pair saw the batch's hands), the slots a hand lacks zero
    restored = post(out[ACTION])
    active = torch.stack([torch.from_numpy(np.concatenate([hands.get(cfg.udt_hand_vocabulary[i]).active_mask
                                                           if i >= 0 else np.zeros(UDHM_DIM, bool) for i in r]))
                          for r in ids.tolist()])  # fmt: skip
    want = batch[ACTION] * active[:, None]
    torch.testing.assert_close(restored, want, rtol=1e-5, atol=1e-5)
    assert torch.equal(out[ACTION_SLOT_PAD_KEY], ~active)


def test_a_single_robot_policy_normalises_its_hands_from_its_own_training_episodes(tok_dir, g1_like):
    from lerobot_unidextok.conversion.hand_stats import hand_stats, training_episodes

    cfg, meta = _config("act_udt", tok_dir, g1_like["root"], udt_hand_norm_state=True)
    udhm = UdhmDatasetMeta(g1_like["root"])
    want = hand_stats(g1_like["root"], training_episodes(udhm))
    assert training_episodes(udhm) is not None and len(training_episodes(udhm)) < udhm.total_episodes
    assert cfg.udt_hand_stats[OBS_STATE]["left"][INSPIRE]["mean"] == want[OBS_STATE]["left"][INSPIRE]["mean"]
    off, _ = _config("act_udt", tok_dir, g1_like["root"], udt_hand_norm="off")
    assert off.udt_hand_stats == {} and off.normalization_mapping["STATE"].value == "MEAN_STD"
    # `--policy.udt_hand_norm=off` beside a config file: YAML reads the bare word as false
    assert _config("act_udt", tok_dir, g1_like["root"], udt_hand_norm=False)[0].udt_hand_norm == "off"
    with pytest.raises(ValueError, match="udt_hand_norm must be one of"):
        _config("act_udt", tok_dir, g1_like["root"], udt_hand_norm="z_score")


def _masked_gradient(kind: str, tok_dir, root) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """(gradient of the loss wrt the model's action output, the batch's slot mask, the output's gradient with the
    stock loss on the same batch), the real policy on a real batch of both robots."""
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    cfg, meta = _config(kind, tok_dir, root)
    horizon, obs_steps = (cfg.chunk_size, 0) if kind == "act_udt" else (cfg.horizon, cfg.n_obs_steps)
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    torch.manual_seed(0)
    policy = get_policy_class(kind)(cfg).train()
    module = policy.model.action_head if kind == "act_udt" else policy.diffusion.unet
    grads = []

    def keep(_module, _inputs, output):
        output.retain_grad()
        grads.append(output)

    module.register_forward_hook(keep)
    g1, l10 = _mix_episodes(root)
    batch = pre(dict(_batch(root, meta, horizon, g1 + l10, obs_steps=obs_steps)))
    for masked in (True, False):
        b = dict(batch) if masked else {k: v for k, v in batch.items() if k != ACTION_SLOT_PAD_KEY}
        torch.manual_seed(1)  # the same noise and timesteps for Diffusion
        policy.zero_grad()
        loss, _ = policy.forward(b)
        loss.backward()
    masked_grad, stock_grad = grads[0].grad, grads[1].grad
    return masked_grad, batch[ACTION_SLOT_PAD_KEY], stock_grad, policy


@pytest.mark.parametrize("kind", ["act_udt", "diffusion_udt"])
def test_a_masked_slot_gets_exactly_zero_gradient(kind, tok_dir, g1_l10_mix):
    grad, pad, stock, _ = _masked_gradient(kind, tok_dir, g1_l10_mix)
    pad = pad[:, None, :].expand_as(grad)  # (B, horizon, A)
    assert pad.any() and (~pad).any()
    assert torch.count_nonzero(grad[pad]) == 0  # no gradient on a slot the row's hand lacks
    assert torch.count_nonzero(grad[~pad]) > 0.9 * (~pad).sum()
    assert torch.count_nonzero(stock[pad]) > 0.9 * pad.sum()  # the stock loss trains those zeros
    torch.testing.assert_close(grad[~pad], stock[~pad])  # and the real slots get exactly the stock gradient


def test_slot_mask_of_each_hand_is_the_datasets_udhm_mask(g1_l10_mix):
    """The mask the step derives from the hand ids equals the `udhm_mask` the mix wrote, row by row."""
    import pyarrow.parquet as pq

    from lerobot_unidextok.data.reader import data_files

    meta = UdhmDatasetMeta(g1_l10_mix)
    table = pq.read_table(data_files(meta.root)[0], columns=[OBS_HAND_IDS, "udhm_mask"])
    ids = torch.tensor(np.stack(table.column(OBS_HAND_IDS).to_numpy(zero_copy_only=False)))
    udhm_mask = torch.tensor(np.stack(table.column("udhm_mask").to_numpy(zero_copy_only=False)))
    names = meta.names(OBS_STATE)
    step = SlotMaskStep(state_names=names, action_names=meta.names(ACTION), hand_vocabulary=meta.record.hand_vocabulary)
    assert torch.equal(step.pad_mask(ids, len(ids)), ~udhm_mask)


def test_a_zero_shot_hands_state_slots_no_trained_hand_has_are_held_at_zero():
    """A hand after the vocabulary's trained ones (zero-shot) keeps its state on the slots a trained hand has and
    reads 0 on the others (every training row held 0 there; LeRobot's std of such a column is 0); a trained hand's
    rows, and every row of a step without extra hands, pass unchanged, at inference (no action) too."""
    from lerobot.lerobot_types import TransitionKey

    names = [f"{side}_{n}" for side in ("left", "right") for n in UDHM_JOINT_NAMES]
    vocab = [INSPIRE, "allegro", "shadow"]
    step = SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab, extra_hands=["shadow"])
    trained = hands.get(INSPIRE).active_mask | hands.get("allegro").active_mask
    new_slots = hands.get("shadow").active_mask & ~trained
    assert new_slots.any()  # the Shadow has slots neither the Inspire nor the Allegro has
    state = torch.rand(3, 2 * UDHM_DIM) + 0.1
    ids = torch.tensor([[2, 2], [0, 1], [0, 2]])  # both blocks the Shadow; trained hands; Inspire left, Shadow right
    out = step({TransitionKey.OBSERVATION: {OBS_STATE: state, OBS_HAND_IDS: ids}})[TransitionKey.OBSERVATION][OBS_STATE]
    hold = torch.from_numpy(~trained)
    want = state.clone()
    want[0, :UDHM_DIM][hold] = 0
    want[0, UDHM_DIM:][hold] = 0
    want[2, UDHM_DIM:][hold] = 0
    assert torch.equal(out, want) and torch.equal(out[1], state[1])
    bound = SlotMaskStep(**{**step.get_config(), "fixed_hand_ids": [2, 2]})  # a robot bound zero-shot
    one = bound({TransitionKey.OBSERVATION: {OBS_STATE: state[:1]}})[TransitionKey.OBSERVATION][OBS_STATE]
    assert torch.equal(one, want[:1])
    plain = SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab)
    assert torch.equal(plain({TransitionKey.OBSERVATION: {OBS_STATE: state, OBS_HAND_IDS: ids}})
                       [TransitionKey.OBSERVATION][OBS_STATE], state)  # fmt: skip
    with pytest.raises(ValueError, match="must end hand_vocabulary"):
        SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab, extra_hands=[INSPIRE])


def test_a_checkpoint_saved_before_pooling_loads_and_acts_as_before(tok_dir, g1_l10_mix, tmp_path):
    """A checkpoint of the code before per-hand normalisation: no hand statistics, no slot mask, and a config.json
    without the new fields. It reloads through LeRobot's factory with the processors it was saved with and gives
    the same actions."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    import lerobot_policy_unidextok  # noqa: F401

    cfg, meta = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_norm="off", udt_mask_slots=False)
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    assert not any(isinstance(s, HandNormalizerStep | SlotMaskStep) for s in [*pre.steps, *post.steps])
    torch.manual_seed(0)
    policy = get_policy_class("act_udt")(cfg).eval()
    policy.save_pretrained(tmp_path)
    pre.save_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    post.save_pretrained(tmp_path, config_filename="policy_postprocessor.json")
    saved = json.loads((tmp_path / "config.json").read_text())
    for new in ("udt_hand_norm", "udt_hand_stats", "udt_mask_slots"):
        saved.pop(new)
    (tmp_path / "config.json").write_text(json.dumps(saved))
    g1, l10 = _mix_episodes(g1_l10_mix)
    batch = _batch(g1_l10_mix, meta, CHUNK, g1 + l10)
    obs = {k: v for k, v in batch.items() if k.startswith("observation.")}

    def act(pol, p, q):
        pol.reset()
        return q(pol.select_action(p(dict(obs))))

    before = act(policy, pre, post)
    cfg2 = PreTrainedConfig.from_pretrained(tmp_path)
    assert cfg2.udt_hand_stats == {}
    policy2 = get_policy_class("act_udt").from_pretrained(tmp_path).eval()
    pre2, post2 = make_pre_post_processors(cfg2, pretrained_path=str(tmp_path))
    assert [type(s).__name__ for s in pre2.steps] == [type(s).__name__ for s in pre.steps]
    assert torch.equal(act(policy2, pre2, post2), before)


@pytest.fixture(scope="module")
def weighted_mix(g1_like, l10_robot, tmp_path_factory):
    from lerobot_unidextok.conversion.mix import MixOptions, mix

    root = tmp_path_factory.mktemp("weighted") / "mix"
    mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(root), repo_id="test/weighted",
                   weights=[3, 1], progress=False))  # fmt: skip
    return root


def test_a_prior_lends_each_hand_of_a_mix_the_pools_statistics_and_the_checkpoint_keeps_them(tok_dir, g1_l10_mix,
                                                                                                 tmp_path):
    """udt_hand_stats_prior (episodes): the recorded per-hand statistics shrunk by that many episodes' worth of the
    mix's frames (`shrunk_hand_stats`); saved in config.json and read back as trained."""
    from lerobot_unidextok.conversion.hand_stats import shrunk_hand_stats

    plain, meta = _config("act_udt", tok_dir, g1_l10_mix)
    cfg, _ = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_stats_prior=4.0)
    record = UdhmDatasetMeta(g1_l10_mix)
    per_episode = record.info["total_frames"] / record.total_episodes
    want_sides = shrunk_hand_stats(record.record.hand_stats, 4.0 * per_episode)[ACTION]
    want = want_sides["right"]
    got, own = cfg.udt_hand_stats[ACTION]["right"], plain.udt_hand_stats[ACTION]["right"]
    assert set(got) == {INSPIRE, L10}
    for hand in got:
        np.testing.assert_allclose(got[hand]["std"], want[hand]["std"], atol=1e-7)
        assert got[hand]["frames"] == own[hand]["frames"]
    both = hands.get(INSPIRE).active_mask & hands.get(L10).active_mask
    moved = np.abs(np.asarray(got[L10]["mean"]) - np.asarray(own[L10]["mean"]))[both]
    assert moved.max() > 1e-4, "the prior moved nothing"
    # the left block holds the G1's Inspire only; the pool spans both sides, so it is shrunk toward the right's hands
    left, left_own = cfg.udt_hand_stats[ACTION]["left"][INSPIRE], plain.udt_hand_stats[ACTION]["left"][INSPIRE]
    np.testing.assert_allclose(left["std"], want_sides["left"][INSPIRE]["std"], atol=1e-7)
    assert np.abs(np.asarray(left["mean"]) - np.asarray(left_own["mean"]))[both].max() > 1e-4
    cfg._save_pretrained(tmp_path)
    saved = json.loads((tmp_path / "config.json").read_text())
    assert saved["udt_hand_stats_prior"] == 4.0
    assert saved["udt_hand_stats"][ACTION]["right"][L10]["std"] == got[L10]["std"]


def test_the_prior_per_other_hand_needs_four_hands_and_a_fixed_prior_wins(tok_dir, g1_l10_mix):
    """udt_hand_stats_prior_per_hand (act_udt_cpu.yaml's 2): that many episodes for each other hand of a mix of four
    hands or more (`pool_prior_episodes`, tested with its counts in tests/conversion/test_hand_stats.py); this mix
    holds two (the G1's Inspire on both sides is one hand, the L10 one more), so no prior;
    udt_hand_stats_prior > 0 replaces the rule."""
    import yaml

    from lerobot_unidextok.configs import resolve_config_path

    recipe = yaml.safe_load(Path(resolve_config_path("lerobot/act_udt_cpu")).read_text())["policy"]
    assert recipe["udt_hand_stats_prior_per_hand"] == 2
    per_hand, _ = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_stats_prior_per_hand=2.0)
    fixed, _ = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_stats_prior=2.0)
    plain, _ = _config("act_udt", tok_dir, g1_l10_mix)
    assert per_hand.udt_hand_stats == plain.udt_hand_stats != fixed.udt_hand_stats
    both, _ = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_stats_prior=4.0, udt_hand_stats_prior_per_hand=2.0)
    four, _ = _config("act_udt", tok_dir, g1_l10_mix, udt_hand_stats_prior=4.0)
    assert both.udt_hand_stats == four.udt_hand_stats != fixed.udt_hand_stats


def test_hand_norm_state_false_leaves_the_state_to_lerobots_statistics(tok_dir, g1_l10_mix):
    """udt_hand_norm_state=false (the default): only the actions per hand; the state with LeRobot's statistics."""
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config("act_udt", tok_dir, g1_l10_mix)
    assert cfg.udt_hand_stats["modes"] == {ACTION: "MEAN_STD"} and OBS_STATE not in cfg.udt_hand_stats
    assert cfg.normalization_mapping["STATE"].value == "MEAN_STD" and cfg.normalization_mapping["ACTION"].value == "IDENTITY"
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    g1, l10 = _mix_episodes(g1_l10_mix)
    batch = _batch(g1_l10_mix, meta, CHUNK, g1 + l10)
    out = pre(dict(batch))
    mean, std = (torch.as_tensor(meta.stats[OBS_STATE][k], dtype=torch.float32) for k in ("mean", "std"))
    torch.testing.assert_close(out[OBS_STATE], (batch[OBS_STATE] - mean) / (std + 1e-8), rtol=1e-4, atol=1e-4)



def test_a_mixs_shares_weight_each_rows_loss_under_lerobot_train(tok_dir, weighted_mix):
    """lerobot-train samples every frame equally; the shares the mix recorded reach the loss as row weights
    (unidextok.share_weights from the batch's episode_index): ACT's loss is the weighted sum of its rows'."""
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    from lerobot_unidextok.processor import SAMPLE_WEIGHT_KEY

    cfg, meta = _config("act_udt", tok_dir, weighted_mix)
    record = UdhmDatasetMeta(weighted_mix).record
    assert cfg.udt_input_shares == [0.75, 0.25]
    assert cfg.udt_episode_inputs == [e.origin["mix_source"] for e in record.episodes]
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    g1, l10 = _mix_episodes(weighted_mix)
    batch = pre(dict(_batch(weighted_mix, meta, CHUNK, g1[:1] + l10)))  # 1 row of the G1's input, 2 of the L10's
    # 3:1 of the loss from rows that are 1:2 of the batch: the G1 row weighs 0.75 / (1/3), an L10 row 0.25 / (2/3)
    torch.testing.assert_close(batch[SAMPLE_WEIGHT_KEY], torch.tensor([2.25, 0.375, 0.375]))
    batch = pre(dict(_batch(weighted_mix, meta, CHUNK, g1 + l10)))
    torch.manual_seed(0)
    policy = get_policy_class("act_udt")(cfg).eval()

    def loss(w: torch.Tensor) -> torch.Tensor:
        return policy.forward({**batch, SAMPLE_WEIGHT_KEY: w})[0]

    rows = len(g1 + l10)
    one_hot = [loss(torch.eye(rows)[b]) for b in range(rows)]
    w = batch[SAMPLE_WEIGHT_KEY]
    torch.testing.assert_close(loss(w), sum(w[b] * one_hot[b] for b in range(rows)), rtol=1e-5, atol=1e-7)
    plain = {k: v for k, v in batch.items() if k != SAMPLE_WEIGHT_KEY}
    torch.testing.assert_close(loss(torch.ones(rows)), policy.forward(plain)[0])


def _save_checkpoint(cfg, meta, out):
    """What lerobot-train's last checkpoint holds: config, weights and both processors."""
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    torch.manual_seed(0)
    get_policy_class(cfg.type)(cfg).save_pretrained(out)
    pre.save_pretrained(out, config_filename="policy_preprocessor.json")
    post.save_pretrained(out, config_filename="policy_postprocessor.json")
    return out


def test_extra_hand_slots_narrow_what_a_zero_shot_hand_drives():
    """With `extra_hand_slots` (unidextok-deploy --zero_shot_slots=nearest) a zero-shot hand's state reads 0 on
    every slot outside those it drives, as well as on the slots no trained hand has; a trained hand's rows are as
    they were, and the narrowing survives get_config (the saved processor)."""
    from lerobot.lerobot_types import TransitionKey

    names = [f"{side}_{n}" for side in ("left", "right") for n in UDHM_JOINT_NAMES]
    vocab = [INSPIRE, "allegro", "shadow"]
    shadow, allegro = hands.get("shadow").active_mask, hands.get("allegro").active_mask
    driven = [int(i) for i in np.flatnonzero(shadow & allegro)]
    step = SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab, extra_hands=["shadow"],
                        extra_hand_slots={"shadow": driven}, fixed_hand_ids=[1, 2])  # fmt: skip
    state = torch.rand(2, 2 * UDHM_DIM) + 0.1
    out = step({TransitionKey.OBSERVATION: {OBS_STATE: state}})[TransitionKey.OBSERVATION][OBS_STATE]
    kept = torch.zeros(UDHM_DIM, dtype=torch.bool)
    kept[driven] = True
    assert torch.equal(out[:, :UDHM_DIM], state[:, :UDHM_DIM])  # the Allegro (trained), left
    assert torch.equal(out[:, UDHM_DIM:], torch.where(kept, state[:, UDHM_DIM:], torch.zeros(())))  # the Shadow
    assert len(driven) < int(shadow.sum()) and (shadow & ~allegro & (hands.get(INSPIRE).active_mask | allegro)).any()
    again = SlotMaskStep(**step.get_config())
    assert again.extra_hand_slots == {"shadow": driven}
    assert torch.equal(again({TransitionKey.OBSERVATION: {OBS_STATE: state}})[TransitionKey.OBSERVATION][OBS_STATE], out)
    with pytest.raises(ValueError, match="extra_hand_slots must give slots"):
        SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab, extra_hands=["shadow"],
                     extra_hand_slots={"allegro": driven})  # fmt: skip
    with pytest.raises(ValueError, match="extra_hand_slots must give slots"):
        SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocab, extra_hands=["shadow"],
                     extra_hand_slots={"shadow": [22]})  # fmt: skip


@pytest.mark.parametrize("state_half", [False, True], ids=["actions_per_hand", "state_too"])
def test_a_single_robot_checkpoint_binds_zero_shot_to_another_robots_hands(tok_dir, g1_like_hands, tmp_path,
                                                                           state_half):  # fmt: skip
    """A policy trained on one robot (two Inspire hands) was refused by unidextok-deploy ("nothing to bind"); with
    --zero_shot=true it is bound to a robot with two XHand1 hands: the bound checkpoint reloads through LeRobot's
    factory and one select_action on that robot's native state gives its native action, the XHand1 blocks
    normalised with the Inspire's statistics on the slots the Inspire has. With the actions per hand only (the
    default) the XHand1 is still the zero-shot hand: the trained hands were once read from the state's statistics
    alone, which made it a known hand without statistics."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    import lerobot_policy_unidextok  # noqa: F401
    from lerobot_unidextok.policies.deploy import DeployError, deploy

    cfg, meta = _config("act_udt", tok_dir, g1_like_hands["root"], udt_hand_norm_state=state_half)
    checkpoint = _save_checkpoint(cfg, meta, tmp_path / "inspire_act")
    robot = _dexora_robot(tmp_path)
    with pytest.raises(DeployError, match="pass --zero_shot=true"):
        deploy(checkpoint, robot, tmp_path / "refused")
    assert not (tmp_path / "refused").exists()
    bound = deploy(checkpoint, robot, tmp_path / "on_xhand", zero_shot=True)
    cfg2 = PreTrainedConfig.from_pretrained(bound)
    assert cfg2.udt_hand_layout == ["xhand1", "xhand1"] and cfg2.udt_allow_unknown
    policy = get_policy_class(cfg2.type).from_pretrained(bound).eval()
    pre, post = make_pre_post_processors(cfg2, pretrained_path=str(bound))
    normaliser = next(s for s in pre.steps if isinstance(s, HandNormalizerStep))
    assert normaliser.hand_vocabulary == [INSPIRE] and normaliser.extra_hands == ["xhand1"]
    assert normaliser.fixed_hand_ids == [1, 1]
    from lerobot.datasets import LeRobotDataset

    robot_meta = UdhmDatasetMeta(robot)
    state = LeRobotDataset("test/dexora", root=robot)[5][OBS_STATE]  # the robot's converted state, as recorded
    action = post(policy.select_action(pre({OBS_STATE: state})))
    assert action.shape == (1, len(robot_meta.native_layout(ACTION).native_names)) and torch.isfinite(action).all()
    # the XHand1's slots the Inspire has are z-scored with the Inspire's statistics; the others pass unscaled
    # (the actions per hand only: the state is left to LeRobot's normaliser)
    from lerobot.lerobot_types import TransitionKey

    x = torch.rand(2, len(cfg2.udt_state_names))
    z = normaliser({TransitionKey.OBSERVATION: {OBS_STATE: x}})[TransitionKey.OBSERVATION][OBS_STATE]
    if not state_half:
        assert OBS_STATE not in cfg.udt_hand_stats and torch.equal(z, x)
        # the XHand1's slots the Inspire lacks held at 0 before LeRobot's normaliser (std 0 there): the state the
        # policy reads stays in range (it was divided by 1e-8)
        normalised = pre({OBS_STATE: state})[OBS_STATE]
        assert normalised.abs().max() < 1e3
        return
    has = torch.from_numpy(hands.get(INSPIRE).active_mask)
    for block in find_udhm_blocks(cfg2.udt_state_names):
        s = cfg.udt_hand_stats[OBS_STATE][block.side][INSPIRE]
        mean, std = torch.tensor(s["mean"]), torch.tensor(s["std"])
        want = torch.where(has, (x[:, block.slice] - mean) / torch.where(std > 1e-6, std, 1.0), x[:, block.slice])
        torch.testing.assert_close(z[:, block.slice], want, rtol=1e-5, atol=1e-5)


def test_zero_shot_slots_nearest_drives_only_the_nearest_trained_hands_slots(tok_dir, g1_like_hands, tmp_path):
    """--zero_shot_slots=nearest: an Inspire-only checkpoint bound to two XHand1 hands drives only the slots the
    XHand1 shares with the Inspire (its nearest, and only, trained hand): the bound pre-processor holds its other
    state slots at 0 and the post-processor commands 0 there; the record names the slots. Asked without
    --zero_shot, or with an unknown mode, the binding is refused before anything is written."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.lerobot_types import TransitionKey
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    import lerobot_policy_unidextok  # noqa: F401
    from lerobot_unidextok.policies.deploy import DeployError, deploy

    cfg, meta = _config("act_udt", tok_dir, g1_like_hands["root"])
    checkpoint = _save_checkpoint(cfg, meta, tmp_path / "inspire_act")
    robot = _dexora_robot(tmp_path)
    for kw, match in (({}, "pass it with --zero_shot=true"), ({"zero_shot": True}, "must be one of")):
        with pytest.raises(DeployError, match=match):
            deploy(checkpoint, robot, tmp_path / "refused", zero_shot_slots="nearest" if kw == {} else "all", **kw)
        assert not (tmp_path / "refused").exists()
    bound = deploy(checkpoint, robot, tmp_path / "on_xhand", zero_shot=True, zero_shot_slots="nearest")
    xhand, inspire = hands.get("xhand1").active_mask, hands.get(INSPIRE).active_mask
    driven = [int(i) for i in np.flatnonzero(xhand & inspire)]
    assert 0 < len(driven) < int(xhand.sum())
    record = json.loads((bound / "unidextok_deploy.json").read_text())
    assert record["zero_shot_slots"] == {"xhand1": driven}
    cfg2 = PreTrainedConfig.from_pretrained(bound)
    pre, post = make_pre_post_processors(cfg2, pretrained_path=str(bound))
    mask = next(s for s in pre.steps if isinstance(s, SlotMaskStep))
    unnormalise = next(s for s in post.steps if isinstance(s, HandNormalizerStep))
    assert mask.extra_hand_slots == unnormalise.extra_hand_slots == {"xhand1": driven}
    kept = torch.zeros(UDHM_DIM, dtype=torch.bool)
    kept[driven] = True
    state = torch.rand(1, len(cfg2.udt_state_names)) + 0.1
    held = mask({TransitionKey.OBSERVATION: {OBS_STATE: state}})[TransitionKey.OBSERVATION][OBS_STATE]
    action = unnormalise({TransitionKey.ACTION: torch.randn(1, len(cfg2.udt_action_names)) + 3.0})[TransitionKey.ACTION]
    for block in find_udhm_blocks(cfg2.udt_state_names):
        assert torch.equal(held[0, block.slice], torch.where(kept, state[0, block.slice], torch.zeros(())))
    for block in find_udhm_blocks(cfg2.udt_action_names):
        assert (action[0, block.slice][~kept] == 0).all() and (action[0, block.slice][kept] != 0).all()
    policy = get_policy_class(cfg2.type).from_pretrained(bound).eval()
    from lerobot.datasets import LeRobotDataset

    native = post(policy.select_action(pre({OBS_STATE: LeRobotDataset("test/dexora", root=robot)[5][OBS_STATE]})))
    assert native.shape == (1, len(UdhmDatasetMeta(robot).native_layout(ACTION).native_names))
    assert torch.isfinite(native).all()
    cfg, meta = _config("act_udt", tok_dir, g1_like_hands["root"], udt_mask_slots=False)
    unmasked = _save_checkpoint(cfg, meta, tmp_path / "unmasked")
    with pytest.raises(DeployError, match=r"without the slot mask \(udt_mask_slots\).*--zero_shot_slots=own"):
        deploy(unmasked, robot, tmp_path / "refused", zero_shot=True, zero_shot_slots="nearest")
    assert not (tmp_path / "refused").exists()


def _dexora_robot(tmp_path):
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["dexora"], episodes_per_source=2, frames_per_episode=20)
    root = tmp_path / "dexora"
    convert(ConvertOptions(source="dexora", input=raw["dexora"], root=root, progress=False, keep="hands"))
    return root


def test_a_single_robot_checkpoints_refusals_name_deploys_own_fixes(tok_dir, g1_like, tmp_path):
    """A one-robot checkpoint with arms, bound to a robot without them, was told to "bind a hands-only mix" (it is not
    a mix); bound to a dataset whose episodes hold different hands, it got lerobot-train's --policy.udt_hand_layout
    hint. Each is one error with deploy's own fix, and nothing is written."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.policies.deploy import deploy
    from lerobot_unidextok.policies.deploy_single import SingleBindError
    from lerobot_unidextok.samples import write_samples

    cfg, meta = _config("act_udt", tok_dir, g1_like["root"])
    checkpoint = _save_checkpoint(cfg, meta, tmp_path / "g1_act")
    with pytest.raises(SingleBindError) as err:
        deploy(checkpoint, _dexora_robot(tmp_path), tmp_path / "a", zero_shot=True)
    text = str(err.value)
    assert text.startswith("the policy was trained on a robot whose state has columns [") and "hands-only mix" not in text
    assert "which this robot does not report" in text and "unidextok-convert --keep=hands" in text
    raw = write_samples(tmp_path / "raw_lh", sources=["linkerhand"], episodes_per_source=4, frames_per_episode=20)
    several = tmp_path / "lh"
    convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=several, progress=False))
    with pytest.raises(SingleBindError, match=r"holds episodes of different hands .*a robot has one set of hands: bind "
                                              r"to a dataset of this robot alone") as err:  # fmt: skip
        deploy(checkpoint, several, tmp_path / "b", zero_shot=True)
    assert "udt_hand_layout" not in str(err.value) and "lerobot-train" not in str(err.value)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    assert not list(tmp_path.glob(".a*")) and not list(tmp_path.glob(".b*"))


def test_fine_tuning_a_bound_mix_checkpoint_on_one_robot_makes_the_episode_map_anew(tok_dir, weighted_mix, l10_robot,
                                                                                    g1_like_hands, tmp_path):  # fmt: skip
    """Pool, then specialise: `lerobot-train --policy.path=<bound mix> --dataset.root=<one robot>` kept the mix's
    episode map and shares, so the target's rows were weighted by another dataset's map (its first episodes
    happened to be the target's). The map is now made for the dataset trained on, said in one line; the saved
    pre-processor keeps its step with the old map, whose weights the policy no longer takes."""
    import subprocess
    import sys

    from lerobot.policies.factory import get_policy_class, make_pre_post_processors
    from linkerhand_udhm import subprocess_env

    from lerobot_unidextok.data.share_sampler import episode_map_key
    from lerobot_unidextok.errors import InvalidInputError
    from lerobot_unidextok.policies.deploy import deploy
    from lerobot_unidextok.policies.udt_loss import share_weight
    from lerobot_unidextok.processor import SAMPLE_WEIGHT_KEY

    cfg, meta = _config("act_udt", tok_dir, weighted_mix)
    mix_episodes = UdhmDatasetMeta(weighted_mix).total_episodes
    assert len(cfg.udt_episode_inputs) == mix_episodes and cfg.udt_episode_map_of == episode_map_key(
        UdhmDatasetMeta(weighted_mix))
    robot = g1_like_hands["root"]  # two Inspire hands: the mix's blocks (a robot with fewer is refused, below)
    bound = deploy(_save_checkpoint(cfg, meta, tmp_path / "pooled"), robot, tmp_path / "bound")
    out = tmp_path / "fine_tuned"
    r = subprocess.run([str(Path(sys.executable).parent / "lerobot-train"), f"--policy.path={bound}",
                        f"--dataset.root={robot}", "--dataset.repo_id=test/g1_hands", "--policy.device=cpu",
                        "--policy.push_to_hub=false", "--steps=1", "--batch_size=2", "--num_workers=0", "--save_freq=1",
                        f"--output_dir={out}"], env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True,
                       text=True, timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    target = UdhmDatasetMeta(robot)
    assert target.total_episodes != mix_episodes and f"episode map ({mix_episodes} episodes) was made for another dataset" in r.stderr
    tuned = json.loads((out / "checkpoints" / "last" / "pretrained_model" / "config.json").read_text())
    assert tuned["udt_episode_map_of"] == episode_map_key(target)
    assert tuned["udt_episode_map_of"].startswith(f"{target.total_episodes} episodes ")
    assert tuned["udt_episode_inputs"] == [] and tuned["udt_input_shares"] == []  # one robot: no shares to weigh by
    # the state's statistics are the robot dataset's (LeRobot's override of its normaliser), not the mix's: keeping
    # the mix's was measured and lost 1.5-3.4 points on the pinch (docs/pooling.md, "Pool, then fine-tune")
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.datasets import LeRobotDataset, LeRobotDatasetMetadata
    from lerobot.processor import NormalizerProcessorStep, PolicyProcessorPipeline

    from lerobot_unidextok.policies.checkpoint import PREPROCESSOR

    def state_stats(folder: Path) -> dict:
        steps = PolicyProcessorPipeline.from_pretrained(folder, config_filename=PREPROCESSOR).steps
        return next(s for s in steps if type(s) is NormalizerProcessorStep).stats[OBS_STATE]

    robot_stats = LeRobotDatasetMetadata("test/g1_hands", root=robot).stats[OBS_STATE]
    bound_stats = state_stats(bound)
    tuned_stats = state_stats(out / "checkpoints" / "last" / "pretrained_model")
    assert not np.allclose(bound_stats["std"], robot_stats["std"])  # the mix's scale is not the robot's
    for stat in ("mean", "std"):
        np.testing.assert_allclose(tuned_stats[stat], robot_stats[stat], rtol=1e-6)
    # in the process: the reloaded pipeline still weighs by the mix's map; the policy takes none of it
    tuning = PreTrainedConfig.from_pretrained(bound)
    tuning._runtime_dataset_meta = LeRobotDatasetMetadata("test/g1_hands", root=robot)
    policy = get_policy_class("act_udt").from_pretrained(bound, config=tuning)
    pre, _ = make_pre_post_processors(tuning, pretrained_path=str(bound))
    rows = LeRobotDataset("test/g1_hands", root=robot, delta_timestamps={ACTION: [i / target.fps for i in range(
        tuning.chunk_size)]})  # fmt: skip
    batch = pre(torch.utils.data.default_collate([rows[0], rows[len(rows) - 1]]))
    assert SAMPLE_WEIGHT_KEY in batch and share_weight(batch, policy.config, policy._own_shares) is None
    # a robot whose blocks are not the checkpoint's (the right-only L10): one line, not LeRobot's shape error
    other = PreTrainedConfig.from_pretrained(bound)
    other._runtime_dataset_meta = LeRobotDatasetMetadata("test/l10_udhm", root=l10_robot)
    with pytest.raises(InvalidInputError, match=r"hand blocks \['right'\]\), the checkpoint was trained on 44 \(hand "
                                                r"blocks \['left', 'right'\]\): it trains further only on"):  # fmt: skip
        other.validate_features()
