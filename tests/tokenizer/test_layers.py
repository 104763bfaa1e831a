"""The hand embedder: the unknown-hand row, hand dropout, growth; and what UniDexTok does with it."""

import torch

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.tokenizer.layers import HandEmbedder


def _embedder(num_hands: int = 3, dim: int = 8) -> HandEmbedder:
    torch.manual_seed(0)
    return HandEmbedder(num_hands, dim)


def test_rows_are_the_hands_then_the_unknown_hand():
    emb = _embedder()
    assert emb.weight.shape == (4, 8) and emb.unknown_id == 3
    ids = torch.tensor([2, 0, 3])
    torch.testing.assert_close(emb(ids), emb.weight[ids], rtol=0, atol=0)


def test_dropout_only_in_training_and_reproducible_from_its_generator():
    emb = _embedder()
    ids = torch.zeros(4000, dtype=torch.long)
    emb.eval()
    torch.testing.assert_close(emb(ids, 0.5), emb.weight[ids], rtol=0, atol=0)  # eval: no drop
    emb.train()
    torch.testing.assert_close(emb(ids, 0.0), emb.weight[ids], rtol=0, atol=0)  # prob 0: no drop
    dropped = emb.token_drop(ids, 0.25, torch.Generator().manual_seed(7))
    assert set(dropped.tolist()) == {0, 3} and 0.22 < (dropped == 3).float().mean().item() < 0.28
    again = emb(ids, 0.25, torch.Generator().manual_seed(7))
    torch.testing.assert_close(again, emb.weight[dropped], rtol=0, atol=0)  # forward drops the same rows
    state = torch.get_rng_state()
    emb(ids, 0.25, torch.Generator().manual_seed(7))
    assert torch.equal(torch.get_rng_state(), state)  # the global stream is not touched


def test_new_hands_start_as_the_unknown_row():
    emb = _embedder()
    grown = emb.with_new_hands(2)
    assert grown.weight.shape == (6, 8) and grown.unknown_id == 5
    torch.testing.assert_close(grown.weight[:3], emb.weight[:3], rtol=0, atol=0)
    for row in (3, 4, 5):
        torch.testing.assert_close(grown.weight[row], emb.weight[3], rtol=0, atol=0)


def test_tokenizer_keeps_the_embedding_key_and_drops_hands_in_training_only():
    """`hand_embed.weight` stays the state-dict key (checkpoints written with an nn.Embedding load), and
    `hand_drop_prob` conditions dropped rows exactly as the unknown hand would be."""
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", "xhand1"]))
    assert "hand_embed.weight" in model.state_dict() and model.unknown_hand_id == 2
    with torch.no_grad():
        model.hand_embed.weight.copy_(torch.randn(model.hand_embed.weight.shape))
    model.quantizer.eval()  # no usage statistics moving between the calls
    x = (torch.rand(64, UDHM_DIM) - 0.3) * 1.5
    h = torch.zeros(64, dtype=torch.long)
    dropped = model.hand_embed.token_drop(h, 0.5, torch.Generator().manual_seed(3))
    with torch.no_grad():
        out = model(x, h, hand_drop_prob=0.5, generator=torch.Generator().manual_seed(3))
        same = model(x, dropped)
    assert 0 < int((dropped == model.unknown_hand_id).sum()) < 64
    torch.testing.assert_close(out.states_rad, same.states_rad, rtol=0, atol=0)
    model.eval()
    with torch.no_grad():
        undropped = model(x, h, hand_drop_prob=0.5, generator=torch.Generator().manual_seed(3))
        plain = model(x, h)
    torch.testing.assert_close(undropped.states_rad, plain.states_rad, rtol=0, atol=0)
    assert model.hand_id("xhand1") == 1 and model.hand_id("allegro", allow_unknown=True) == 2
