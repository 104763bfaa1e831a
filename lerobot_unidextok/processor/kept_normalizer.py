"""The state's normaliser of a bound checkpoint, kept through a fine-tune (`unidextok.kept_normalizer`).

`lerobot-train --policy.path=<checkpoint>` (LeRobot 0.6.1, not resumed) rebuilds the checkpoint's pre-processor
with the new dataset's `meta/stats.json` in place of the statistics saved in its `normalizer_processor`: the
override is keyed by that registry name. A policy pooled over several hands learnt its trunk on the mix's scale of
`observation.state`; fine-tuned on one robot's dataset of 10 demonstrations it would read that robot's narrow
scale instead, a different input for the same state. `unidextok-deploy` therefore moves the state's statistics out of LeRobot's normaliser into this
step: the same class, the same arithmetic (bit for bit), under its own registry name, so no override reaches it
and a fine-tune of the bound checkpoint keeps the scale the trunk learnt. LeRobot's normaliser stays in the
pipeline (the fine-tune's override must find it) with no observation key left to normalise.
"""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.configs.types import NormalizationMode
from lerobot.processor import NormalizerProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.constants import OBS_STATE

KEPT_NORMALIZER_STEP_NAME = "unidextok.kept_normalizer"


@dataclass
@ProcessorStepRegistry.register(name=KEPT_NORMALIZER_STEP_NAME)
class KeptNormalizerStep(NormalizerProcessorStep):
    """LeRobot's `NormalizerProcessorStep` under a name `lerobot-train`'s fine-tune override does not reach."""


def keep_state_normalizer(steps: list) -> list:
    """`steps` with the state's normalisation moved from LeRobot's `normalizer_processor` into a
    `KeptNormalizerStep` right after it (the same statistics, mode and eps); unchanged when that normaliser does
    not normalise the state (a per-hand state, `udt_hand_norm_state`, or no statistics for it) or already left it
    to a kept step."""
    at = next((i for i, s in enumerate(steps) if type(s) is NormalizerProcessorStep), None)
    if at is None or any(isinstance(s, KeptNormalizerStep) for s in steps):
        return steps
    stock = steps[at]
    feature = stock.features.get(OBS_STATE)
    keys = stock.normalize_observation_keys
    mode = stock.norm_map.get(feature.type, NormalizationMode.IDENTITY) if feature else NormalizationMode.IDENTITY
    if (
        mode == NormalizationMode.IDENTITY
        or OBS_STATE not in stock.stats
        or (keys is not None and OBS_STATE not in keys)
    ):
        return steps
    kept = KeptNormalizerStep(features={OBS_STATE: feature}, norm_map={feature.type: mode},
                              stats={OBS_STATE: stock.stats[OBS_STATE]}, eps=stock.eps, device=stock.device,
                              dtype=stock.dtype)  # fmt: skip
    rest = NormalizerProcessorStep(features=stock.features, norm_map=stock.norm_map, eps=stock.eps,
                                   stats={k: v for k, v in stock.stats.items() if k != OBS_STATE},
                                   normalize_observation_keys={k for k in (keys or stock.features) if k != OBS_STATE},
                                   device=stock.device, dtype=stock.dtype)  # fmt: skip
    return [*steps[:at], rest, kept, *steps[at + 1 :]]


__all__ = ["KEPT_NORMALIZER_STEP_NAME", "KeptNormalizerStep", "keep_state_normalizer"]
