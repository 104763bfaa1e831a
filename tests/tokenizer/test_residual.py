"""Residual stages (`residual_stages`): a second factorised cosine VQ on what the first stage's codes left out.
The first stage stays the paper's N x K token sequence, decodable on its own; a model without residual stages
(every checkpoint before them) keeps its layout and its codes (tests/tokenizer/test_golden_codes.py)."""

import math

import pytest
import torch

from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig, UniDexTok, UniDexTokConfig
from lerobot_unidextok.training.coverage import range_states

HAND = "human"


def _model(residual_stages: int, seed: int = 0, hand: str = HAND, **overrides) -> UniDexTok:
    torch.manual_seed(seed)
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=[hand], trained_hands=[hand], residual_stages=residual_stages,
                                      **overrides)  # fmt: skip
    return UniDexTok(cfg)


def _rows(n: int, seed: int, hand: str = HAND):
    rows = range_states(hand, n, seed)
    return torch.tensor(rows.states_rad), torch.tensor(rows.masks)


def test_codes_of_each_stage_and_their_shapes():
    model = _model(1).eval()
    n, k = model.config.num_tokens, model.config.num_groups
    assert (model.config.num_stages, model.config.symbols_per_hand(), model.config.symbols_per_hand(1)) == (2, 64, 32)
    x, _ = _rows(6, 1)
    both = model.encode(x, HAND)
    first = model.encode(x, HAND, stages=1)
    assert both.shape == (6, n, 2 * k) and first.shape == (6, n, k) and both.dtype == torch.int64
    assert torch.equal(both[..., :k], first)  # stage 1 is its own sequence, the paper's N x K codes
    assert model.num_codes_per_state == 2 * n * k
    assert model.decode(first, HAND).shape == model.decode(both, HAND).shape == (6, 22)
    assert model.code_vectors(both).shape == (6, n, 2 * k, model.config.group_dim)
    with pytest.raises(ValueError, match=f"codes must have shape \\(B, {n}, {k}\\) or \\(B, {n}, {2 * k}\\)"):
        model.decode(both[..., :3], HAND)
    with pytest.raises(ValueError, match="stages must be in \\[1, 2\\]"):
        model.encode(x, HAND, stages=3)
    with pytest.raises(ValueError, match="codes must lie in"):
        model.decode(both.clone().fill_(model.config.codebook_size), HAND)


def test_decode_of_the_codes_is_what_forward_reconstructs_in_eval():
    model = _model(1).eval()
    x, _ = _rows(8, 2)
    with torch.no_grad():
        out = model(x, HAND)
    codes = model.encode(x, HAND)
    assert torch.equal(codes, out.indices)
    assert torch.equal(model.decode(codes, HAND), out.states_rad)
    codes_again, states = model.encode_decode(x, HAND)
    assert torch.equal(codes_again, codes) and torch.equal(states, out.states_rad)
    # the first stage alone decodes as the decoder fed the first stage's output only
    first, first_states = model.encode_decode(x, HAND, stages=1)
    c = model.hand_embed(model.hand_ids(HAND, 8))
    with torch.no_grad():
        alone = model._decode_latent(model.quantizer.get_output_from_indices(first), c)
    assert torch.equal(first_states, alone) and torch.equal(model.decode(first, HAND), alone)


def test_a_model_without_residual_stages_has_the_layout_of_before():
    plain, residual = _model(0), _model(1)
    assert not any("residual" in key for key in plain.state_dict())
    extra = sorted(set(residual.state_dict()) - set(plain.state_dict()))
    assert extra and all(key.startswith("residual_quantizers.0.") for key in extra)
    # the same seed builds the same first-stage model: the residual stage is created after everything else
    torch.testing.assert_close(plain.state_dict()["quantizer.codebooks"], _model(0).state_dict()["quantizer.codebooks"])
    assert UniDexTokConfig.from_dict({"format_version": 1}).residual_stages == 0


def test_the_code_search_is_refused_on_several_stages_and_runs_on_the_first():
    with pytest.raises(ConfigError, match="with residual_stages=1 the encoding must be the nearest codes"):
        UniDexTokConfig(residual_stages=1, encoding={"rounds": 1})
    with pytest.raises(ConfigError, match="residual_stages must be >= 0"):
        UniDexTokConfig(residual_stages=-1)
    with pytest.raises(ConfigError, match="residual_drop_prob"):
        UniDexTokConfig(residual_drop_prob=1.0)
    model = _model(1).eval()
    x, mask = _rows(4, 3)
    with pytest.raises(ValueError, match="encode with stages=1"):
        model.encode(x, HAND, encoding=EncodingConfig(rounds=1))
    searched = model.encode(x, HAND, encoding=EncodingConfig(rounds=1), stages=1, mask=mask)
    assert searched.shape == (4, model.config.num_tokens, model.config.num_groups)


def _train(model: UniDexTok, hand: str, steps: int, seed: int) -> UniDexTok:
    """A short run of the plain recipe: AdamW, batches of in-range states, dead codes re-seeded."""
    torch.manual_seed(seed)
    x, mask = _rows(4096, seed, hand)
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    gen = torch.Generator().manual_seed(seed)
    model.train()
    for step in range(steps):
        rows = torch.randint(0, len(x), (256,), generator=gen)
        out = model(x[rows], hand, mask=mask[rows], generator=gen)
        opt.zero_grad()
        out.loss.backward()
        opt.step()
        if (step + 1) % 50 == 0 and step < 0.7 * steps:
            model.reseed_dead_codes()
    return model.eval()


def _mae_deg(model: UniDexTok, hand: str, x, mask, stages=None) -> float:
    back = model.decode(model.encode(x, hand, encoding=NEAREST_CODES, stages=stages), hand)
    return math.degrees(float((back - x).abs()[mask].mean()))


def test_a_residual_stage_cuts_the_nearest_codes_error_of_a_short_training_run():
    """Same preset, seed, data and steps, through the nearest codes alone, on held-out in-range states: the model
    with a residual stage decodes closer than the one without, and its first stage alone about as close as the
    model without (it is trained to decode alone on a residual_drop_prob share of rows). The first stage is made
    coarse (one group of 4 codes per token: 8 bits a state) so that, in 400 steps, the codes and not the networks
    limit the error; measured: 10.96 deg without, 8.32 with the residual stage, 11.30 its first stage alone."""
    torch.set_num_threads(1)
    hand, coarse = "inspire_rh56", {"num_groups": 1, "codebook_dim": 32, "codebook_size": 4}
    plain = _train(_model(0, seed=5, hand=hand, **coarse), hand, 400, 5)
    residual = _train(_model(1, seed=5, hand=hand, **coarse), hand, 400, 5)
    x, mask = _rows(1000, 99, hand)
    errors = {"plain": _mae_deg(plain, hand, x, mask), "residual": _mae_deg(residual, hand, x, mask),
              "residual, stage 1": _mae_deg(residual, hand, x, mask, stages=1)}  # fmt: skip
    assert errors["residual"] < 0.85 * errors["plain"], errors
    assert errors["residual, stage 1"] < 1.2 * errors["plain"], errors


@pytest.mark.parametrize("representation", ["dequantized", "embedding"])
def test_the_processor_step_emits_every_stage(tmp_path, representation):
    """A residual tokenizer behind the processor step: H x N x K x stages tokens per frame, the features it
    declares, and the tokenizer's own codes of each block."""
    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep, tokenizer_output_dims

    hand = "inspire_rh56"
    model = _model(1, hand=hand)
    model.save_pretrained(tmp_path / "tok")
    step = UniDexTokStateTokenizerStep(hand_layout=[hand, hand], pretrained=str(tmp_path / "tok"),
                                       representation=representation, range_check="off")  # fmt: skip
    x, _ = _rows(10, 4, hand)
    states = x.reshape(5, 44)  # five two-hand frames
    tokens, view = step.tokenize(states)
    n_tokens, width = tokenizer_output_dims(step.tokenizer.config, 2, representation)
    cfg = step.tokenizer.config
    assert tokens.shape == (5, n_tokens) and n_tokens == 2 * cfg.num_tokens * cfg.num_groups * 2
    assert view.shape == (5, width)
    want = step.tokenizer.encode(x, hand)  # (10, N, 2K)
    assert torch.equal(tokens.reshape(10, cfg.num_tokens, 2 * cfg.num_groups), want)
    with pytest.raises(ValueError, match="the code search picks one stage's codes and this tokenizer has 2"):
        UniDexTokStateTokenizerStep(hand_layout=[hand], pretrained=str(tmp_path / "tok"),
                                    encoding=EncodingConfig(rounds=1))  # fmt: skip
