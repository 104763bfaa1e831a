"""`vqbet_udt` processors: the stock VQ-BeT pair with the UniDexTok step (`udt_processor.insert_udt_steps`)."""

from __future__ import annotations

import torch
from lerobot.policies.vqbet.processor_vqbet import make_vqbet_pre_post_processors
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.policies.udt_processor import insert_udt_steps
from lerobot_unidextok.policies.vqbet_udt.configuration_vqbet_udt import VQBeTUdtConfig


def make_vqbet_udt_pre_post_processors(
    config: VQBeTUdtConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """VQ-BeT's pre-/post-processors with the UniDexTok step after batching (plus the native-state
    mapper and the native-action decoder)."""
    return insert_udt_steps(config, *make_vqbet_pre_post_processors(config, dataset_stats=dataset_stats),
                            dataset_stats)
