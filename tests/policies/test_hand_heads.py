"""Per-hand output heads (`--policy.udt_hand_heads=true`, `policies/hand_heads.py`) on a real mix of two robots
(unidextok-mix: a G1-like robot with two Inspire hands and a right-only LinkerHand L10 robot): built only with the
flag, zero at the start, each row through its own hand's head after training, saved and reloaded bit for bit, kept
by unidextok-deploy (the bound robot's head; a zero-shot hand: the mean of the trained hands' heads)."""

import json

import pytest
import torch
from l10_robot import HAND as L10
from robot_udhm import INSPIRE
from safetensors.torch import load_file

from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.policies import ACTUdtConfig, DiffusionUdtConfig
from lerobot_unidextok.policies.hand_heads import HandHeads

CHUNK = 4
TINY = dict(chunk_size=CHUNK, n_action_steps=CHUNK, dim_model=32, n_heads=2, dim_feedforward=64, n_encoder_layers=1,
            n_decoder_layers=1, use_vae=False)  # fmt: skip
HEAD_KEYS = ("model.action_head.hand_weight", "model.action_head.hand_bias")


def _config(tok_dir, root, **kw) -> tuple[ACTUdtConfig, object]:
    """The config lerobot-train builds for `root` (`validate_features` with the dataset's metadata)."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.datasets import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata("test/mix", root=root)
    cfg = ACTUdtConfig(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, tuple(meta.features[OBS_STATE]["shape"]))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, tuple(meta.features[ACTION]["shape"]))},
        udt_pretrained=str(tok_dir), device="cpu", **TINY, **kw,
    )  # fmt: skip
    cfg._runtime_dataset_meta = meta
    cfg.validate_features()
    return cfg, meta


def _rows(root, meta, frame: int = 3) -> tuple[dict, list[int], list[int]]:
    """One frame (with its action chunk) of two training episodes of each mixed robot, collated as LeRobot's
    dataloader does, and the row numbers of the G1's and the L10's."""
    from lerobot.datasets import LeRobotDataset

    by = {0: [], 1: []}
    for e in UdhmDatasetMeta(root).record.episodes:
        if e.split == "train":
            by[e.origin["mix_source"]].append(e.episode_index)
    episodes = by[0][:2] + by[1][:2]
    ds = LeRobotDataset("test/mix", root=root, delta_timestamps={ACTION: [i / meta.fps for i in range(CHUNK)]})
    starts = dict(zip(ds.meta.episodes["episode_index"], ds.meta.episodes["dataset_from_index"], strict=True))
    items = [ds[int(starts[e]) + frame] for e in episodes]
    batch = torch.utils.data.default_collate([{k: v for k, v in it.items() if isinstance(v, torch.Tensor)}
                                              for it in items])  # fmt: skip
    return batch, [0, 1], [2, 3]


def _policy(cfg, seed: int = 0):
    from lerobot.policies.factory import get_policy_class

    torch.manual_seed(seed)
    return get_policy_class("act_udt")(cfg)


@torch.no_grad()
def _chunk(policy, batch) -> torch.Tensor:
    """(B, chunk, A) the model's action chunk for a pre-processed batch (eval mode: no dropout)."""
    policy.eval()
    return policy.model(batch)[0]


def test_the_heads_exist_only_with_the_flag_and_start_as_the_shared_head(tok_dir, g1_l10_mix, g1_like_hands):
    from lerobot.policies.factory import make_pre_post_processors

    off, meta = _config(tok_dir, g1_l10_mix)
    on, _ = _config(tok_dir, g1_l10_mix, udt_hand_heads=True)
    plain, heads = _policy(off), _policy(on)
    assert type(plain.model.action_head) is torch.nn.Linear and not any("hand_" in k for k in plain.state_dict())
    head = heads.model.action_head
    vocab, width = on.udt_hand_vocabulary, on.output_features[ACTION].shape[0]
    assert isinstance(head, HandHeads) and len(vocab) == 2
    assert head.hand_weight.shape == (2, width, on.dim_model) and head.hand_bias.shape == (2, width)
    assert torch.count_nonzero(head.hand_weight) == 0 and torch.count_nonzero(head.hand_bias) == 0
    # the same seed gives the same parameters (building the heads draws no random numbers) and the same actions
    ours = {k: v for k, v in heads.state_dict().items() if k not in HEAD_KEYS}
    assert ours.keys() == plain.state_dict().keys()
    assert all(torch.equal(v, plain.state_dict()[k]) for k, v in ours.items())
    pre, _ = make_pre_post_processors(on, dataset_stats=meta.stats)
    batch = pre(_rows(g1_l10_mix, meta)[0])
    assert torch.equal(_chunk(heads, batch), _chunk(plain, batch))
    # one robot: one set of hands, nothing to choose between; the flag builds no heads there
    single, _ = _config(tok_dir, g1_like_hands["root"], udt_hand_heads=True)
    assert type(_policy(single).model.action_head) is torch.nn.Linear
    # the other policy types refuse the flag in one line
    with pytest.raises(ConfigError, match="per-hand output heads exist for act_udt only"):
        DiffusionUdtConfig(udt_hand_heads=True)


def test_the_hand_ids_reach_the_policy_through_the_pre_processor(tok_dir, g1_l10_mix):
    """The heads read `observation.hand_ids` from the batch the policy gets: the pre-processor passes it unchanged."""
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config(tok_dir, g1_l10_mix, udt_hand_heads=True)
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    raw, _, _ = _rows(g1_l10_mix, meta)
    assert torch.equal(pre(dict(raw))[OBS_HAND_IDS], raw[OBS_HAND_IDS])


def test_the_heads_read_the_hand_ids_whatever_the_identity_encoding(tok_dir, g1_l10_mix):
    """With `udt_hand_identity=morphology` the view carries no vocabulary index; the heads still pick each row's hand
    (its first block's) from the ids, as the tokenizer step does."""
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config(tok_dir, g1_l10_mix, udt_hand_heads=True, udt_hand_identity="morphology")
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    raw, g1, l10 = _rows(g1_l10_mix, meta)
    batch = pre(dict(raw))
    policy = _policy(cfg)
    before = _chunk(policy, batch)
    with torch.no_grad():
        policy.model.action_head.hand_bias[cfg.udt_hand_vocabulary.index(L10)] += 0.5
    after = _chunk(policy, batch)
    assert torch.allclose(after[l10] - before[l10], torch.full_like(after[l10], 0.5), atol=1e-5)
    assert torch.equal(after[g1], before[g1])


@pytest.fixture(scope="module")
def trained(tok_dir, g1_l10_mix, tmp_path_factory):
    """A policy with heads after 30 Adam updates on both robots' rows, saved as lerobot-train saves a checkpoint."""
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config(tok_dir, g1_l10_mix, udt_hand_heads=True)
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    raw, g1, l10 = _rows(g1_l10_mix, meta)
    batch = pre(dict(raw))
    policy = _policy(cfg).train()
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-3)
    for _ in range(30):
        loss, _ = policy.forward(batch)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    out = tmp_path_factory.mktemp("heads") / "pretrained_model"
    policy.save_pretrained(out)
    pre.save_pretrained(out, config_filename="policy_preprocessor.json")
    post.save_pretrained(out, config_filename="policy_postprocessor.json")
    return {"policy": policy.eval(), "cfg": cfg, "batch": batch, "g1": g1, "l10": l10, "checkpoint": out, "raw": raw}


def test_after_a_few_updates_each_row_goes_through_its_own_hands_head(trained):
    policy, cfg, batch, g1, l10 = (trained[k] for k in ("policy", "cfg", "batch", "g1", "l10"))
    vocab = cfg.udt_hand_vocabulary
    inspire, l10_hand = vocab.index(INSPIRE), vocab.index(L10)
    assert batch[OBS_HAND_IDS][g1].tolist() == [[inspire, inspire]] * 2  # a G1 row: two Inspire blocks
    assert batch[OBS_HAND_IDS][l10].tolist() == [[-1, l10_hand]] * 2  # an L10 row: the right block only
    head = policy.model.action_head
    weights = head.hand_weight.detach()
    assert torch.count_nonzero(weights[inspire]) > 0 and torch.count_nonzero(weights[l10_hand]) > 0
    assert not torch.allclose(weights[inspire], weights[l10_hand])  # each hand learned its own residual
    before, bias = _chunk(policy, batch), head.hand_bias.detach().clone()
    for hand, own, other in ((l10_hand, l10, g1), (inspire, g1, l10)):
        with torch.no_grad():
            head.hand_bias[hand] += 0.5
        after = _chunk(policy, batch)
        with torch.no_grad():
            head.hand_bias.copy_(bias)
        assert torch.allclose(after[own] - before[own], torch.full_like(after[own], 0.5), atol=1e-5)
        assert torch.equal(after[other], before[other])  # the other hand's rows never read this head
    assert torch.equal(_chunk(policy, batch), before)


def test_the_heads_are_saved_in_the_safetensors_and_reload_bit_for_bit(trained):
    from lerobot.policies.factory import get_policy_class

    policy, checkpoint = trained["policy"], trained["checkpoint"]
    saved = load_file(checkpoint / "model.safetensors")
    for key in HEAD_KEYS:
        assert torch.equal(saved[key], policy.state_dict()[key])
    assert json.loads((checkpoint / "config.json").read_text())["udt_hand_heads"] is True
    again = get_policy_class("act_udt").from_pretrained(checkpoint).eval()
    assert isinstance(again.model.action_head, HandHeads)
    assert all(torch.equal(v, policy.state_dict()[k]) for k, v in again.state_dict().items())
    assert torch.equal(_chunk(again, trained["batch"]), _chunk(policy, trained["batch"]))


def test_a_checkpoint_without_the_flag_loads_and_acts_as_before(tok_dir, g1_l10_mix, tmp_path):
    """A config.json written before the flag (no `udt_hand_heads`): no heads, the same actions."""
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    cfg, meta = _config(tok_dir, g1_l10_mix)
    policy = _policy(cfg).eval()
    policy.save_pretrained(tmp_path)
    saved = json.loads((tmp_path / "config.json").read_text())
    saved.pop("udt_hand_heads")
    (tmp_path / "config.json").write_text(json.dumps(saved))
    again = get_policy_class("act_udt").from_pretrained(tmp_path).eval()
    assert again.config.udt_hand_heads is False and type(again.model.action_head) is torch.nn.Linear
    pre, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    batch = pre(_rows(g1_l10_mix, meta)[0])
    assert torch.equal(_chunk(again, batch), _chunk(policy, batch))
    # the same checkpoint given heads to train further (--policy.path=... --policy.udt_hand_heads=true): its own
    # parameters load, the heads (absent from its safetensors) start at zero, so it acts as before until trained
    from lerobot.configs.policies import PreTrainedConfig

    flagged = PreTrainedConfig.from_pretrained(tmp_path)
    flagged.udt_hand_heads = True
    grown = get_policy_class("act_udt").from_pretrained(tmp_path, config=flagged).eval()
    head = grown.model.action_head
    assert isinstance(head, HandHeads) and torch.count_nonzero(head.hand_weight) == 0
    assert torch.equal(head.weight, policy.model.action_head.weight)
    assert torch.equal(_chunk(grown, batch), _chunk(policy, batch))


def _bound_actions(bound, robot_state: torch.Tensor, bump: int | None = None) -> torch.Tensor:
    """select_action of the bound checkpoint through its saved processors on the robot's own state, with
    `bump` (a hand's head) shifted by 0.5 first."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    cfg = PreTrainedConfig.from_pretrained(bound)
    policy = get_policy_class(cfg.type).from_pretrained(bound).eval()
    if bump is not None:
        with torch.no_grad():
            policy.model.action_head.hand_bias[bump] += 0.5
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(bound))
    policy.reset()
    return post(policy.select_action(pre({OBS_STATE: robot_state})))


def test_a_bound_checkpoint_keeps_the_robots_own_head(trained, g1_like_hands, tmp_path):
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.datasets import LeRobotDataset
    from lerobot.policies.factory import get_policy_class

    from lerobot_unidextok.policies.deploy import deploy

    vocab = trained["cfg"].udt_hand_vocabulary
    bound = deploy(trained["checkpoint"], g1_like_hands["root"], tmp_path / "on_g1")
    cfg = PreTrainedConfig.from_pretrained(bound)
    assert cfg.udt_hand_heads and cfg.udt_fixed_hand_ids == [vocab.index(INSPIRE)] * 2
    policy = get_policy_class(cfg.type).from_pretrained(bound)
    assert all(torch.equal(policy.state_dict()[k], trained["policy"].state_dict()[k]) for k in HEAD_KEYS)
    state = LeRobotDataset("test/g1_hands", root=g1_like_hands["root"])[5][OBS_STATE]  # the robot's state
    action = _bound_actions(bound, state)
    native = UdhmDatasetMeta(g1_like_hands["root"]).native_layout(ACTION).native_names
    assert action.shape == (1, len(native)) and torch.isfinite(action).all()
    # the robot's rows go through the Inspire's head, never the L10's
    assert torch.equal(_bound_actions(bound, state, bump=vocab.index(L10)), action)
    assert not torch.equal(_bound_actions(bound, state, bump=vocab.index(INSPIRE)), action)


def test_a_zero_shot_binding_runs_with_the_mean_of_the_trained_hands_heads(trained, tmp_path):
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.policies.deploy import deploy
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["dexora"], episodes_per_source=2, frames_per_episode=20)
    robot = tmp_path / "dexora"  # two XHand1 hands, which the mix never had
    convert(ConvertOptions(source="dexora", input=raw["dexora"], root=robot, progress=False, keep="hands"))
    bound = deploy(trained["checkpoint"], robot, tmp_path / "on_xhand", zero_shot=True)
    cfg = PreTrainedConfig.from_pretrained(bound)
    vocab = cfg.udt_hand_vocabulary
    assert cfg.udt_extra_hands == ["xhand1"] and cfg.udt_fixed_hand_ids == [len(vocab)] * 2
    state = LeRobotDataset("test/dexora", root=robot)[5][OBS_STATE]
    action = _bound_actions(bound, state)
    assert torch.isfinite(action).all()
    bumped = [_bound_actions(bound, state, bump=hand) for hand in range(len(vocab))]
    for hand in range(len(vocab)):  # every trained hand's head counts, each by 1 / V: the mean of the heads
        assert not torch.allclose(bumped[hand], action, rtol=0, atol=1e-4)
        torch.testing.assert_close(bumped[hand], bumped[0], rtol=0, atol=1e-5)


def test_each_row_goes_through_its_hands_head_the_mean_head_or_the_shared_head_alone():
    from lerobot_unidextok.policies.hand_heads import NO_HAND, UNSEEN_HAND, HandHeads, row_hands

    torch.manual_seed(0)
    heads = HandHeads(4, 3, num_hands=2, num_blocks=2)
    with torch.no_grad():
        heads.hand_weight.normal_()
        heads.hand_bias.normal_()
    # blocks (left, right): a known hand first, a known hand after an absent block, a zero-shot hand (id 2 >= V = 2)
    # beside an absent block, no hand at all, a zero-shot hand before a known one
    ids = torch.tensor([[1, 0], [-1, 0], [2, -1], [-1, -1], [2, 1]])
    rows = row_hands({OBS_STATE: torch.zeros(5, 8), OBS_HAND_IDS: ids}, 2, 2, [])
    assert rows.tolist() == [1, 0, UNSEEN_HAND, NO_HAND, 1]
    x = torch.randn(5, 6, 4)  # (B, S, dim_model)
    heads.row_hands = rows
    out = heads(x)
    shared = x @ heads.weight.T + heads.bias  # (B, S, A)
    for b, h in ((0, 1), (1, 0), (4, 1)):  # (row, its hand)
        own = torch.einsum("sd,ad->sa", x[b], heads.hand_weight[h]) + heads.hand_bias[h]
        torch.testing.assert_close(out[b], shared[b] + own)
    mean = torch.einsum("sd,ad->sa", x[2], heads.hand_weight.mean(0)) + heads.hand_bias.mean(0)
    torch.testing.assert_close(out[2], shared[2] + mean)
    torch.testing.assert_close(out[3], shared[3])


def test_lerobot_train_takes_the_flag_and_saves_the_heads(tok_dir, g1_l10_mix, tmp_path):
    """`lerobot-train --policy.type=act_udt --policy.udt_hand_heads=true` on the mix: the checkpoint has the heads."""
    import subprocess
    import sys
    from pathlib import Path

    from linkerhand_udhm import subprocess_env

    out = tmp_path / "run"
    tiny = [f"--policy.{k}={v}" for k, v in TINY.items()]
    r = subprocess.run([str(Path(sys.executable).parent / "lerobot-train"), "--policy.type=act_udt",
                        f"--policy.udt_pretrained={tok_dir}",
                        "--policy.udt_hand_heads=true", *tiny, f"--dataset.root={g1_l10_mix}",
                        "--dataset.repo_id=test/g1_l10_mix", "--policy.device=cpu", "--policy.push_to_hub=false",
                        "--steps=2", "--batch_size=4", "--num_workers=0", "--save_freq=2", f"--output_dir={out}"],
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    model = out / "checkpoints" / "last" / "pretrained_model"
    saved = load_file(model / "model.safetensors")
    vocab = json.loads((model / "config.json").read_text())["udt_hand_vocabulary"]
    assert saved[HEAD_KEYS[0]].shape == (len(vocab), saved["model.action_head.weight"].shape[0], TINY["dim_model"])
    assert torch.count_nonzero(saved[HEAD_KEYS[0]]) > 0  # trained by the two updates
