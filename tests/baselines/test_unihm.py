"""UniHM-style baseline: trains (losses fall), per-hand encoders, one codebook, code/shape invariants."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lerobot_unidextok.baselines import UniHMConfig, UniHMTokenizer, reconstruct
from lerobot_unidextok.baselines.base import TrainableStateTokenizer


@pytest.fixture(scope="module")
def fitted(train_states, masks) -> tuple[UniHMTokenizer, dict, float]:
    untrained = UniHMTokenizer(UniHMConfig.from_preset("tiny", teacher_steps=1, rounds=1, finetune_steps=1))
    untrained.fit(train_states, masks)
    err_untrained = float((reconstruct(untrained, train_states["human"], "human") - train_states["human"]).abs().mean())
    tok = UniHMTokenizer(UniHMConfig.from_preset("tiny", teacher_steps=120))
    history = tok.fit(train_states, masks)
    return tok, history, err_untrained


def test_losses_fall(fitted) -> None:
    _, history, _ = fitted
    for phase in ("teacher", "distill", "align"):
        losses = np.asarray(history[phase])
        assert np.isfinite(losses).all()
        assert losses[-5:].mean() < losses[:5].mean(), phase


def test_training_beats_untrained(fitted, train_states) -> None:
    tok, _, err_untrained = fitted
    err = float((reconstruct(tok, train_states["human"], "human") - train_states["human"]).abs().mean())
    assert err < 0.8 * err_untrained


def test_codes_and_shapes(fitted, train_states, masks) -> None:
    tok, _, _ = fitted
    assert isinstance(tok, TrainableStateTokenizer)
    assert set(tok.students) == {"inspire_rh56"} and set(tok.decoders) == {"human", "inspire_rh56"}
    assert tok.encoder_for("human") is tok.teacher and tok.encoder_for("inspire_rh56") is tok.students["inspire_rh56"]
    for hand, states in train_states.items():
        codes = tok.encode(states[:50], hand)
        assert codes.dtype == torch.int64 and codes.shape == (50, 1)
        assert 0 <= codes.min() and codes.max() < tok.config.codebook_size
        recon = tok.decode(codes, hand)
        assert recon.shape == (50, 22) and (recon[:, ~masks[hand]] == 0).all()
    assert tok.rate("human").bits_per_state == np.log2(tok.config.codebook_size)


def test_deterministic_given_seed(train_states, masks) -> None:
    cfg = UniHMConfig.from_preset("tiny", teacher_steps=15, rounds=1, distill_steps=2, align_steps=2, finetune_steps=2)
    a, b = UniHMTokenizer(cfg), UniHMTokenizer(cfg)
    a.fit(train_states, masks)
    b.fit(train_states, masks)
    x = train_states["inspire_rh56"][:20]
    assert torch.equal(a.encode(x, "inspire_rh56"), b.encode(x, "inspire_rh56"))


def test_without_teacher_hand_every_hand_gets_a_student(train_states, masks) -> None:
    cfg = UniHMConfig.from_preset("tiny", teacher_steps=5, rounds=1, distill_steps=2, align_steps=2, finetune_steps=2)
    tok = UniHMTokenizer(cfg)
    tok.fit({"inspire_rh56": train_states["inspire_rh56"]}, {"inspire_rh56": masks["inspire_rh56"]})
    assert set(tok.students) == {"inspire_rh56"}


def test_bad_input_errors(fitted) -> None:
    tok, _, _ = fitted
    with pytest.raises(ValueError, match="knows"):
        tok.encode(torch.zeros(2, 22), "allegro")
    with pytest.raises(ValueError, match=r"\(B, 1\)"):
        tok.decode(torch.zeros(2, 3, dtype=torch.long), "human")
    with pytest.raises(ValueError, match="at least one hand"):
        UniHMTokenizer(UniHMConfig.from_preset("tiny")).fit({})
    with pytest.raises(ValueError, match="unknown UniHM preset"):
        UniHMConfig.from_preset("huge")


def test_retargeted_pairs_are_the_robot_decoder_targets(train_states, masks) -> None:
    """With `paired`, the robot decoder learns to decode the human code into the retargeted robot state
    (UniHM's recipe), not into the semantically inserted human state (the old stand-in)."""
    human = train_states["human"]
    # "retargeted" robot states: flexion reversed, so they differ from the human state inserted into the slots
    target = (1.2 - human) * torch.as_tensor(masks["inspire_rh56"])
    cfg = UniHMConfig.from_preset("tiny", teacher_steps=150, lr=3e-3, kmeans_first_step=30, kmeans_every=60)
    errors = {}
    for paired in (True, False):
        tok = UniHMTokenizer(cfg)
        tok.fit({"human": human, "inspire_rh56": target}, masks, paired={"inspire_rh56": target} if paired else None)
        with torch.no_grad():
            code = tok.encode(human, "human")  # teacher code of each human frame
            out = tok.decode(code, "inspire_rh56")  # decoded by the robot's decoder
        errors[paired] = float((out - target).abs()[:, masks["inspire_rh56"].bool()].mean())
    assert errors[True] < 0.5 * errors[False], errors
    with pytest.raises(ValueError, match="one retargeted state per 'human' training row"):
        UniHMTokenizer(cfg).fit({"human": human, "inspire_rh56": target}, masks, paired={"inspire_rh56": target[:5]})
