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
