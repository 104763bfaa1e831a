"""Pre/post processors of `act_udt`: the UniDexTok step sits before batching."""

from typing import Any

import torch
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.factory import (
    make_default_policy_processor_steps,
    make_policy_processor_pipelines,
)

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig
from lerobot_unidextok.processor import (
    UDHMToNativeCommandStep,
    UniDexTokStateTokenizerStep,
)


def make_act_udt_pre_post_processors(
    config: ACTUdtConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[PolicyProcessorPipeline[dict[str, Any], dict[str, Any]], PolicyProcessorPipeline]:
    """rename -> UniDexTok -> batch -> device -> normalize / unnormalize -> cpu [-> native commands]."""
    s = make_default_policy_processor_steps(config, dataset_stats, normalizer_device=config.device)
    tokenizer_step = UniDexTokStateTokenizerStep(
        hand_layout=config.udt_hand_layout,
        pretrained=config.udt_pretrained,
        preset=config.udt_preset,
        representation=config.udt_representation,
    )
    output_steps = [s.unnormalize, s.to_cpu]
    if config.udt_command_hands:
        output_steps.append(UDHMToNativeCommandStep(hand_layout=config.udt_command_hands, sides=config.udt_sides))
    return make_policy_processor_pipelines(
        input_steps=[
            s.rename_observations,
            tokenizer_step,
            s.add_batch_dim,
            s.to_device,
            s.normalize,
        ],
        output_steps=output_steps,
    )
