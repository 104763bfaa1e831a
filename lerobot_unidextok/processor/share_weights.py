"""Each input's share of a mix, as a loss weight per training row (`unidextok.share_weights`).

`lerobot-train` (LeRobot 0.6.1) samples every frame of the chosen episodes equally and takes no sampler from a
plugin, so the share `unidextok-mix` records for each input (its rule's, or `--weights`; `data/share_sampler.py`)
reaches training as a weight: this pre-processor step reads each row's `episode_index` (LeRobot keeps it in the batch), looks up the
input that episode came from, and writes `share / (the input's rows / all rows)` as `unidextok_sample_weight` (B,)
into the batch (`share_loss_weights`; the rows counted over the batches this step has seen, so the shares hold on
any subset of episodes a run trains on); the ACT and Diffusion `<type>_udt` policies multiply each row's loss by
it. Rows of episodes without an input (episodes added later) weigh 1. Without `episode_index` (inference)
the step does nothing.

Checkpoints saved before 2026-12-05 carry `episode_weights` (one fixed weight per episode, from the mix's frame
counts) instead; they keep those weights when training resumes.

`map_of` names the dataset the map was made for (`data.share_sampler.episode_map_key`) and goes into the batch
beside the weights (`unidextok_sample_weight_map`): a checkpoint trained further on another dataset keeps this step
as it was saved (LeRobot reloads the pipeline unchanged), while its config's map is made anew for the new dataset;
the policies then weight by the config's map, not by this one (`policies/udt_loss.py`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor import ProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.data.share_sampler import share_loss_weights

SHARE_WEIGHTS_STEP_NAME = "unidextok.share_weights"
SAMPLE_WEIGHT_KEY = "unidextok_sample_weight"  # (B,) float in the batch: the row's loss weight
SAMPLE_WEIGHT_MAP_KEY = "unidextok_sample_weight_map"  # str in the batch: the dataset the weights' map is for


@ProcessorStepRegistry.register(SHARE_WEIGHTS_STEP_NAME)
@dataclass
class ShareWeightStep(ProcessorStep):
    """Write `unidextok_sample_weight` (B,): each row's loss weight from its input's share (module docstring)."""

    episode_inputs: list[int] = field(default_factory=list)  # by episode index: its input (-1 none); none past the end
    shares: list[float] = field(default_factory=list)  # each input's asked share of the training frames
    episode_weights: list[float] = field(default_factory=list)  # legacy (saved before 2026-12-05): fixed weights
    map_of: str = ""  # the dataset the map is for (data.share_sampler.episode_map_key); "" before 2026-12-06

    def __post_init__(self) -> None:
        self._inputs = torch.tensor([int(k) for k in self.episode_inputs], dtype=torch.long)
        self._shares = torch.tensor([float(s) for s in self.shares], dtype=torch.float32)
        self._table = torch.tensor([float(w) for w in self.episode_weights], dtype=torch.float32)
        self._seen = torch.zeros(len(self._shares))  # rows of each input in the batches weighted so far
        for name, values in (("shares", self._shares), ("episode_weights", self._table)):
            if len(values) and not (torch.isfinite(values).all() and (values >= 0).all()):
                raise ValueError(f"{SHARE_WEIGHTS_STEP_NAME}: {name} must be finite and >= 0, got {values.tolist()}")
        if len(self._inputs) and (self._inputs.max() >= len(self._shares) or self._inputs.min() < -1):
            raise ValueError(
                f"{SHARE_WEIGHTS_STEP_NAME}: episode_inputs name inputs {sorted(set(self._inputs.tolist()))} but "
                f"there are {len(self._shares)} shares; the policy's udt_episode_inputs and udt_input_shares come "
                "from one mix's record"
            )

    def weights(self, episodes: torch.Tensor) -> torch.Tensor:
        """(B,) loss weights of rows from `episodes` (B,), counting their inputs among the rows seen."""
        episodes = episodes.long().reshape(-1).cpu()
        if len(self._inputs):
            inputs = torch.full_like(episodes, -1)
            known = (episodes >= 0) & (episodes < len(self._inputs))
            inputs[known] = self._inputs[episodes[known]]
            self._seen += torch.bincount(inputs[inputs >= 0], minlength=len(self._shares)).float()
            return share_loss_weights(inputs, self._shares, self._seen)
        weight = torch.ones(len(episodes))
        known = (episodes >= 0) & (episodes < len(self._table))
        weight[known] = self._table[episodes[known]]
        return weight

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        extra = transition.get(TransitionKey.COMPLEMENTARY_DATA) or {}
        episodes = extra.get("episode_index")
        if episodes is None or transition.get(TransitionKey.ACTION) is None:
            return transition
        new = transition.copy()
        device = torch.as_tensor(transition[TransitionKey.ACTION]).device
        new[TransitionKey.COMPLEMENTARY_DATA] = {**extra, SAMPLE_WEIGHT_KEY: self.weights(torch.as_tensor(episodes)).to(device),
                                                 SAMPLE_WEIGHT_MAP_KEY: self.map_of}  # fmt: skip
        return new

    def reset(self) -> None:
        self._seen.zero_()

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        if self.episode_weights and not self.episode_inputs:  # a legacy checkpoint saves what it loaded
            return {"episode_weights": [float(w) for w in self.episode_weights]}
        return {"episode_inputs": [int(k) for k in self.episode_inputs], "shares": [float(s) for s in self.shares],
                "map_of": self.map_of}  # fmt: skip


__all__ = ["SAMPLE_WEIGHT_KEY", "SAMPLE_WEIGHT_MAP_KEY", "SHARE_WEIGHTS_STEP_NAME", "ShareWeightStep"]
