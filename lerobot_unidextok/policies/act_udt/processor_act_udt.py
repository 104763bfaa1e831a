"""`act_udt` processors: the stock ACT pair with the UniDexTok step (`udt_processor.insert_udt_steps`)."""

from __future__ import annotations

import torch
from lerobot.policies.act.processor_act import make_act_pre_post_processors
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig
from lerobot_unidextok.policies.udt_processor import insert_udt_steps


def make_act_udt_pre_post_processors(
    config: ACTUdtConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """ACT's pre-/post-processors with the UniDexTok step after batching (plus the native-state
    mapper and the native-action decoder)."""
    return insert_udt_steps(config, *make_act_pre_post_processors(config, dataset_stats=dataset_stats),
                            dataset_stats)
