"""Each input's share of a mix, as a loss weight per training row (`unidextok.share_weights`).

`lerobot-train` (LeRobot 0.6.1) samples every frame of the chosen episodes equally and takes no sampler from a
plugin, so the share `unidextok-mix --weights` asks for each input (`data/share_sampler.py`) reaches training as a
weight: this pre-processor step reads each row's `episode_index` (LeRobot keeps it in the batch) and writes its
episode's weight, `share / frame fraction` of its input, as `unidextok_sample_weight` (B,) into the batch; the ACT
and Diffusion `<type>_udt` policies multiply each row's loss by it. Rows of episodes without a weight (test
episodes, episodes added later) weigh 1. Without `episode_index` (inference) the step does nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor import ProcessorStep, ProcessorStepRegistry

SHARE_WEIGHTS_STEP_NAME = "unidextok.share_weights"
SAMPLE_WEIGHT_KEY = "unidextok_sample_weight"  # (B,) float in the batch: the row's loss weight


@ProcessorStepRegistry.register(SHARE_WEIGHTS_STEP_NAME)
@dataclass
class ShareWeightStep(ProcessorStep):
    """Write `unidextok_sample_weight` (B,): the loss weight of each row's episode (module docstring)."""

    episode_weights: list[float] = field(default_factory=list)  # by episode index; 1 past the end

    def __post_init__(self) -> None:
        self._table = torch.tensor([float(w) for w in self.episode_weights], dtype=torch.float32)
        if len(self._table) and not (torch.isfinite(self._table).all() and (self._table >= 0).all()):
            raise ValueError(f"{SHARE_WEIGHTS_STEP_NAME}: episode_weights must be finite and >= 0")

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        extra = transition.get(TransitionKey.COMPLEMENTARY_DATA) or {}
        episodes = extra.get("episode_index")
        if episodes is None or transition.get(TransitionKey.ACTION) is None:
            return transition
        episodes = torch.as_tensor(episodes).long().reshape(-1)
        known = episodes < len(self._table)
        weight = torch.ones(len(episodes))
        weight[known] = self._table[episodes[known].cpu()]
        new = transition.copy()
        device = torch.as_tensor(transition[TransitionKey.ACTION]).device
        new[TransitionKey.COMPLEMENTARY_DATA] = {**extra, SAMPLE_WEIGHT_KEY: weight.to(device)}
        return new

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {"episode_weights": [float(w) for w in self.episode_weights]}


__all__ = ["SAMPLE_WEIGHT_KEY", "SHARE_WEIGHTS_STEP_NAME", "ShareWeightStep"]
