"""`diffusion_udt` processors: the stock Diffusion Policy pair with the UniDexTok step (`udt_processor.insert_udt_steps`)."""

from __future__ import annotations

import torch
from lerobot.policies.diffusion.processor_diffusion import make_diffusion_pre_post_processors
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.policies.diffusion_udt.configuration_diffusion_udt import DiffusionUdtConfig
from lerobot_unidextok.policies.udt_processor import insert_udt_steps


def make_diffusion_udt_pre_post_processors(
    config: DiffusionUdtConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """Diffusion Policy's pre-/post-processors with the UniDexTok step after batching (plus the native-state
    mapper and the native-action decoder)."""
    return insert_udt_steps(config, *make_diffusion_pre_post_processors(config, dataset_stats=dataset_stats),
                            dataset_stats)
