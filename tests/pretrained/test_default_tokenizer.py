"""The default tokenizer (`DEFAULT_TOKENIZER`) knows every registered hand, and switching it moves nothing that names
another id.

A hand spec added to `lerobot_unidextok/hands/specs/` without retraining or adapting the default tokenizer fails
here (issue 55: the Dex3-1, the ROHand and the Ability were registered and the default refused them), as does a card
whose per-hand table leaves a registered hand out. Checkpoints and configs that name `unidextok/universal-small`
keep its weights and its encoding (its codes: tests/tokenizer/test_golden_codes.py).
"""

import json

import pytest
import torch

from experiments.universal import IN_RANGE_PREFIX
from lerobot_unidextok import hands
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, DEFAULTS_SO_FAR, SHIPPED, UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.training.coverage import range_states


def test_the_default_tokenizer_was_trained_on_every_registered_hand():
    registered = set(hands.names())
    trained = set(UniDexTokConfig.from_pretrained(DEFAULT_TOKENIZER).trained_hands)
    missing = sorted(registered - trained)
    assert not missing, (
        f"hands {missing} are registered (lerobot_unidextok/hands/specs/) but {DEFAULT_TOKENIZER} was not trained on "
        "them: adapt it (unidextok-train --init_from, docs/tokenizer.md) and regenerate its card "
        "(experiments/universal_card.py)"
    )


def test_the_default_tokenizers_card_scores_every_registered_hand_in_range():
    recorded = json.loads((SHIPPED[DEFAULT_TOKENIZER] / "eval.json").read_text())["results"]
    card = (SHIPPED[DEFAULT_TOKENIZER] / "README.md").read_text()
    for hand in hands.names():
        assert IN_RANGE_PREFIX + hand in recorded, hand
        assert f"| {IN_RANGE_PREFIX}{hand} |" in card, hand


def test_configs_naming_universal_small_keep_its_weights_and_encoding():
    """By name: the old default's weights, its 64 codes a hand and its code search, whatever the default is now."""
    from lerobot_unidextok.policies import ACTUdtConfig
    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep

    old = UniDexTok.from_pretrained(UNIVERSAL_SMALL)
    assert old.config.symbols_per_hand() == 64 and old.config.encoding.rounds == 2
    cfg = ACTUdtConfig(device="cpu", udt_pretrained=UNIVERSAL_SMALL)
    assert cfg.untrained_preset() is None and cfg.tokenizer_config() == old.config
    step = UniDexTokStateTokenizerStep(hand_layout=["linkerhand_l10"], pretrained=UNIVERSAL_SMALL)
    rows = range_states("linkerhand_l10", 4, seed=11).states_rad
    tokens, _ = step.tokenize(torch.from_numpy(rows))
    with torch.no_grad():
        want = old.encode(torch.from_numpy(rows), "linkerhand_l10", mask=step.active_masks.repeat(4, 1))
    assert torch.equal(tokens, want.reshape(4, -1))


@pytest.mark.parametrize("saved_default", DEFAULTS_SO_FAR)
def test_a_config_saved_with_a_former_default_and_a_preset_still_means_the_untrained_preset(saved_default):
    """A policy config.json writes `udt_pretrained` out; one saved with the default of its day and `udt_preset=tiny`
    asked for the untrained preset, and gets it after the default changed."""
    from lerobot_unidextok.policies import ACTUdtConfig

    cfg = ACTUdtConfig(device="cpu", udt_pretrained=saved_default, udt_preset="tiny")
    assert cfg.untrained_preset() == "tiny" and cfg.tokenizer_config().num_tokens == 4
    assert UNIVERSAL_SMALL in DEFAULTS_SO_FAR and DEFAULT_TOKENIZER in DEFAULTS_SO_FAR
