"""A bound checkpoint's state normaliser: the same numbers as LeRobot's, out of reach of a fine-tune's override."""

import numpy as np
import pytest
import torch
from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
from lerobot.processor import NormalizerProcessorStep, PolicyProcessorPipeline

from lerobot_unidextok.processor import KEPT_NORMALIZER_STEP_NAME, KeptNormalizerStep, keep_state_normalizer

STATE, ENV = "observation.state", "observation.environment_state"
FEATURES = {STATE: PolicyFeature(type=FeatureType.STATE, shape=(3,)),
            ENV: PolicyFeature(type=FeatureType.ENV, shape=(2,)),
            "action": PolicyFeature(type=FeatureType.ACTION, shape=(3,))}  # fmt: skip
NORM_MAP = {FeatureType.STATE: NormalizationMode.MEAN_STD, FeatureType.ENV: NormalizationMode.MIN_MAX,
            FeatureType.ACTION: NormalizationMode.IDENTITY}  # fmt: skip


def _stats(scale: float) -> dict:
    """Statistics of a pool (`scale` 1) or of one narrow dataset (another scale): every number differs."""
    return {STATE: {"mean": np.array([0.1, -0.2, 0.3]) * scale, "std": np.array([0.5, 0.2, 1.5]) * scale},
            ENV: {"min": np.array([-1.0, 0.0]) * scale, "max": np.array([1.0, 2.0]) * scale},
            "action": {"mean": np.zeros(3), "std": np.ones(3)}}  # fmt: skip


def _pipeline(steps: list) -> PolicyProcessorPipeline:
    return PolicyProcessorPipeline(steps=steps, name="policy_preprocessor")


def _batch() -> dict:
    g = torch.Generator().manual_seed(0)
    return {STATE: torch.randn(4, 3, generator=g), ENV: torch.randn(4, 2, generator=g)}


def test_the_kept_step_normalises_the_state_as_lerobots_did_bit_for_bit():
    stock = NormalizerProcessorStep(features=FEATURES, norm_map=NORM_MAP, stats=_stats(1.0))
    steps = keep_state_normalizer([stock])
    assert [type(s) for s in steps] == [NormalizerProcessorStep, KeptNormalizerStep]
    rest, kept = steps
    assert (
        STATE not in rest.stats
        and STATE not in rest.normalize_observation_keys
        and ENV in rest.normalize_observation_keys
    )
    assert set(kept.stats) == {STATE} and kept.norm_map == {FeatureType.STATE: NormalizationMode.MEAN_STD}
    before, after = _pipeline([stock])(_batch()), _pipeline(steps)(_batch())
    for key in (STATE, ENV):
        assert torch.equal(before[key], after[key])
    assert not torch.allclose(after[STATE], _batch()[STATE])  # it did normalise
    assert keep_state_normalizer(steps) is steps  # once


def test_a_fine_tunes_override_reaches_lerobots_normaliser_and_not_the_kept_one(tmp_path):
    """What `lerobot-train --policy.path=` does to a saved pre-processor (its `normalizer_processor` override with
    the new dataset's statistics): before, the state read the new dataset's scale; now the saved one's."""
    pooled = NormalizerProcessorStep(features=FEATURES, norm_map=NORM_MAP, stats=_stats(1.0))
    override = {"normalizer_processor": {"stats": _stats(0.1), "features": FEATURES, "norm_map": NORM_MAP}}
    expected = _pipeline([pooled])(_batch())
    for name, steps in (("stock", [pooled]), ("kept", keep_state_normalizer([pooled]))):
        _pipeline(steps).save_pretrained(tmp_path / name, config_filename="policy_preprocessor.json")
        saved = PolicyProcessorPipeline.from_pretrained(tmp_path / name, config_filename="policy_preprocessor.json")
        assert torch.equal(saved(_batch())[STATE], expected[STATE])  # saved and reloaded: the same numbers
        tuned = PolicyProcessorPipeline.from_pretrained(tmp_path / name, config_filename="policy_preprocessor.json",
                                                        overrides=override)  # fmt: skip
        out = tuned(_batch())
        assert torch.equal(out[STATE], expected[STATE]) == (name == "kept")
        assert not torch.equal(out[ENV], expected[ENV])  # every other observation takes the new statistics, as before
    assert KEPT_NORMALIZER_STEP_NAME in (tmp_path / "kept" / "policy_preprocessor.json").read_text()


@pytest.mark.parametrize("case", ["state per hand", "no state statistics", "no normaliser"])
def test_nothing_moves_when_lerobots_normaliser_does_not_normalise_the_state(case):
    norm_map = {**NORM_MAP, FeatureType.STATE: NormalizationMode.IDENTITY} if case == "state per hand" else NORM_MAP
    stats = {k: v for k, v in _stats(1.0).items() if k != STATE} if case == "no state statistics" else _stats(1.0)
    steps = (
        [] if case == "no normaliser" else [NormalizerProcessorStep(features=FEATURES, norm_map=norm_map, stats=stats)]
    )
    assert keep_state_normalizer(steps) is steps
