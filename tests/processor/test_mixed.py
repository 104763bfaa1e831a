"""unidextok.mixed_state_tokenizer: each row tokenised with its own hands, absent blocks zero, the hand identity
beside the token view; the same numbers as the fixed step for the rows of each robot."""

import numpy as np
import pytest
import torch
from l10_robot import HAND as L10
from l10_robot import l10_motion
from lerobot.processor import PolicyProcessorPipeline
from robot_udhm import INSPIRE, inspire_states

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import OBS_HAND_IDS, OBS_HAND_TOKEN_FEATURES, OBS_HAND_TOKENS, OBS_STATE, UDHM_DIM
from lerobot_unidextok.processor import UniDexTokMixedTokenizerStep, UniDexTokStateTokenizerStep
from lerobot_unidextok.tokenizer import UniDexTok

NAMES = udhm_state_names(["left", "right"])
VOCAB = [INSPIRE, L10]


@pytest.fixture(scope="module")
def rows():
    """(10, 44) states and (10, 2) hand ids: 5 frames of two Inspire hands, 5 of a right-only L10."""
    g1 = inspire_states(5, seed=1)
    l10 = np.zeros((5, 2 * UDHM_DIM), np.float32)
    l10[:, UDHM_DIM:] = hands.get(L10).to_udhm(l10_motion(5, seed=2).astype(np.float64), "right")
    ids = np.array([[0, 0]] * 5 + [[-1, 1]] * 5)
    return torch.from_numpy(np.concatenate([g1, l10])), torch.from_numpy(ids)


def test_each_row_is_tokenised_as_the_fixed_step_tokenises_its_robot(tok_dir, rows):
    states, ids = rows
    mixed = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir))
    out = mixed.observation({OBS_STATE: states, OBS_HAND_IDS: ids})
    view, tokens = out[OBS_HAND_TOKEN_FEATURES], out[OBS_HAND_TOKENS]
    assert view.shape == (10, 2 * (UDHM_DIM + len(VOCAB))) and tokens.shape == (10, 2 * 4 * 8)
    g1 = UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE], pretrained=str(tok_dir))
    want = g1.observation({OBS_STATE: states[:5]})
    torch.testing.assert_close(view[:5, : 2 * UDHM_DIM], want[OBS_HAND_TOKEN_FEATURES])
    torch.testing.assert_close(tokens[:5], want[OBS_HAND_TOKENS])
    l10 = UniDexTokStateTokenizerStep(hand_layout=[L10], state_names=NAMES[UDHM_DIM:], pretrained=str(tok_dir))
    want = l10.observation({OBS_STATE: states[5:, UDHM_DIM:]})
    torch.testing.assert_close(view[5:, UDHM_DIM : 2 * UDHM_DIM], want[OBS_HAND_TOKEN_FEATURES])
    torch.testing.assert_close(tokens[5:, 32:], want[OBS_HAND_TOKENS])
    # the absent left block of the L10 rows: a zero view, tokens -1, no identity
    assert not view[5:, :UDHM_DIM].any() and (tokens[5:, :32] == -1).all()
    identity = view[:, 2 * UDHM_DIM :].reshape(10, 2, len(VOCAB))
    assert identity[:5].tolist() == [[[1, 0], [1, 0]]] * 5 and identity[5:].tolist() == [[[0, 0], [0, 1]]] * 5


def test_a_bound_robot_needs_no_hand_ids_and_a_mixed_policy_refuses_a_state_without_them(tok_dir, rows):
    states, ids = rows
    bound = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                        fixed_hand_ids=[-1, 1])  # fmt: skip
    one = bound.observation({OBS_STATE: states[5]})  # a single frame, no batch, no hand ids
    given = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir))
    want = given.observation({OBS_STATE: states[5:6], OBS_HAND_IDS: ids[5]})  # one frame of ids beside a batch
    torch.testing.assert_close(one[OBS_HAND_TOKEN_FEATURES], want[OBS_HAND_TOKEN_FEATURES][0])
    with pytest.raises(KeyError, match="trained on a mix of hands. Bind it to your robot with `unidextok-deploy"):
        given.observation({OBS_STATE: states[:2]})
    with pytest.raises(ValueError, match=r"holds \[-1, 5\], outside -1 .. 1"):
        given.observation({OBS_STATE: states[:1], OBS_HAND_IDS: torch.tensor([[5, -1]])})
    with pytest.raises(ValueError, match="fixed_hand_ids"):
        UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                    fixed_hand_ids=[0])  # fmt: skip


def test_ranges_are_checked_with_each_rows_own_hand(tok_dir, rows):
    states, ids = rows
    step = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir))
    bad = states[5:6].clone()
    bad[0, UDHM_DIM + 2] = 3.0  # an L10 thumb slot far outside the L10's range
    with pytest.raises(ValueError, match=f"block 0 \\({L10}\\)"):
        step.observation({OBS_STATE: bad, OBS_HAND_IDS: ids[5:6]})


def test_the_step_survives_a_pipeline_save_and_reload(tok_dir, rows, tmp_path):
    states, ids = rows
    step = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                       fixed_hand_ids=[0, 0])  # fmt: skip
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    (loaded,) = again.steps
    assert isinstance(loaded, UniDexTokMixedTokenizerStep) and loaded.fixed_hand_ids == [0, 0]
    a = step.observation({OBS_STATE: states, OBS_HAND_IDS: ids})[OBS_HAND_TOKEN_FEATURES]
    b = loaded.observation({OBS_STATE: states, OBS_HAND_IDS: ids})[OBS_HAND_TOKEN_FEATURES]
    torch.testing.assert_close(a, b, rtol=0, atol=0)


def test_the_morphology_identity_describes_every_hand_and_a_zero_shot_one_too(tok_dir, rows):
    """identity=morphology: each block's hand as its spec's vector (66 wide), a zero-shot hand included, where the
    one-hot identity gives a hand the mix never had nothing."""
    from lerobot_unidextok.hands.morphology import MORPHOLOGY_WIDTH, morphology_vector

    states, ids = rows
    step = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                       identity="morphology")  # fmt: skip
    view = step.observation({OBS_STATE: states, OBS_HAND_IDS: ids})[OBS_HAND_TOKEN_FEATURES]
    assert view.shape == (10, 2 * (UDHM_DIM + MORPHOLOGY_WIDTH))
    onehot = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir))
    base = onehot.observation({OBS_STATE: states, OBS_HAND_IDS: ids})[OBS_HAND_TOKEN_FEATURES]
    torch.testing.assert_close(view[:, : 2 * UDHM_DIM], base[:, : 2 * UDHM_DIM])  # the token view is the same
    identity = view[:, 2 * UDHM_DIM :].reshape(10, 2, MORPHOLOGY_WIDTH).numpy()
    np.testing.assert_array_equal(identity[0, 0], morphology_vector(INSPIRE, "left"))
    np.testing.assert_array_equal(identity[0, 1], morphology_vector(INSPIRE, "right"))
    np.testing.assert_array_equal(identity[7, 1], morphology_vector(L10, "right"))
    assert not identity[5:, 0].any()  # the absent block
    # bound zero-shot to a hand the mix never had: the one-hot identity is zero, the morphology is the hand's
    for kind, width in (("onehot", len(VOCAB)), ("morphology", MORPHOLOGY_WIDTH)):
        bound = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                            fixed_hand_ids=[-1, 2], extra_hands=["linkerhand_l20"],
                                            identity=kind, range_check="off", allow_unknown=True)  # fmt: skip
        out = bound.observation({OBS_STATE: states[5:6]})[OBS_HAND_TOKEN_FEATURES]
        tail = out[0, 2 * UDHM_DIM :].reshape(2, width).numpy()
        want = morphology_vector("linkerhand_l20", "right") if kind == "morphology" else np.zeros(width)
        np.testing.assert_array_equal(tail[1], want)
    with pytest.raises(ValueError, match=r"hand identity must be one of \('onehot', 'morphology'\), got 'id'"):
        UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir), identity="id")


def test_a_hands_morphology_identity_is_the_same_in_any_mix(tok_dir, rows):
    """The one-hot of a hand depends on the mix's vocabulary (its place in it); its morphology does not."""
    states, ids = rows
    kwargs = dict(state_names=NAMES, pretrained=str(tok_dir), identity="morphology")
    a = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, **kwargs)
    b = UniDexTokMixedTokenizerStep(hand_vocabulary=[L10, "human", INSPIRE], allow_unknown=True, **kwargs)
    swapped = torch.where(ids == 1, 0, torch.where(ids == 0, 2, ids))  # the same hands under b's indices
    view_a = a.observation({OBS_STATE: states, OBS_HAND_IDS: ids})[OBS_HAND_TOKEN_FEATURES]
    view_b = b.observation({OBS_STATE: states, OBS_HAND_IDS: swapped})[OBS_HAND_TOKEN_FEATURES]
    torch.testing.assert_close(view_a[:, 2 * UDHM_DIM :], view_b[:, 2 * UDHM_DIM :], rtol=0, atol=0)
    onehot = [UniDexTokMixedTokenizerStep(hand_vocabulary=v, state_names=NAMES, pretrained=str(tok_dir),
                                          allow_unknown=True) for v in (VOCAB, [L10, "human", INSPIRE])]  # fmt: skip
    tails = [s.observation({OBS_STATE: states, OBS_HAND_IDS: i})[OBS_HAND_TOKEN_FEATURES][:, 2 * UDHM_DIM :]
             for s, i in zip(onehot, (ids, swapped), strict=True)]  # fmt: skip
    assert tails[0].shape != tails[1].shape  # a one-hot is as wide as its mix's vocabulary


def test_a_mixed_step_that_does_not_encode_keeps_each_rows_identity(tok_dir, rows, monkeypatch):
    """`encode=False` (`udt_hand_input=state`): the hand identity the policy reads is the encoding step's, the
    token view zero and every code -1, without running the tokenizer."""
    states, ids = rows
    want = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                       identity="morphology").observation({OBS_STATE: states, OBS_HAND_IDS: ids})  # fmt: skip
    monkeypatch.setattr(UniDexTok, "encode_decode", lambda *a, **k: pytest.fail("the tokenizer ran"))
    quiet = UniDexTokMixedTokenizerStep(hand_vocabulary=VOCAB, state_names=NAMES, pretrained=str(tok_dir),
                                        identity="morphology", encode=False)  # fmt: skip
    out = quiet.observation({OBS_STATE: states, OBS_HAND_IDS: ids})
    view, tokens = out[OBS_HAND_TOKEN_FEATURES], out[OBS_HAND_TOKENS]
    assert view.shape == want[OBS_HAND_TOKEN_FEATURES].shape and tokens.shape == want[OBS_HAND_TOKENS].shape
    assert not view[:, : 2 * UDHM_DIM].any() and (tokens == -1).all()
    torch.testing.assert_close(view[:, 2 * UDHM_DIM :], want[OBS_HAND_TOKEN_FEATURES][:, 2 * UDHM_DIM :])
    assert view[:, 2 * UDHM_DIM :].any() and quiet.get_config()["encode"] is False
