"""Processors of the `<type>_udt` types: the stock pipelines with the UniDexTok step inserted before batching.

    rename -> unidextok.state_tokenizer -> to_batch -> device -> normalizer      (pre)
    unnormalizer -> to cpu [-> unidextok.udhm_to_native]                          (post)

The step sits before `to_batch_processor` (custom keys must exist before batching, and it must see raw
radians, never normalised values). LeRobot finds `make_<type>_udt_pre_post_processors` here by name.
"""

from __future__ import annotations

import importlib
import re
from typing import Any

import torch
from lerobot.processor import AddBatchDimensionProcessorStep, NormalizerProcessorStep, PolicyProcessorPipeline

from lerobot_unidextok.policies.udt.configuration_udt import UDT_CONFIGS, UdtFields
from lerobot_unidextok.processor import NativeLayout, UDHMToNativeCommandStep, UniDexTokStateTokenizerStep

_FACTORY_NAME = re.compile(r"make_(\w+)_pre_post_processors")


def _stock_factory(config: UdtFields):
    """`make_<base>_pre_post_processors` of the stock policy the config wraps."""
    base = type(config).__mro__[2]  # (XUdtConfig, UdtFields, XConfig, ...)
    module = importlib.import_module(base.__module__.replace("configuration_", "processor_"))
    return getattr(module, f"make_{config.base_type}_pre_post_processors")


def make_udt_pre_post_processors(
    config: UdtFields,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """The stock processors of `config.base_type` with the UniDexTok step (and the native-action decoder)."""
    pre, post = _stock_factory(config)(config, dataset_stats=dataset_stats)
    step = UniDexTokStateTokenizerStep(
        hand_layout=config.udt_hand_layout,
        state_names=config.udt_state_names,
        pretrained=config.udt_pretrained,
        preset=config.udt_preset,
        representation=config.udt_representation,
        allow_unknown=config.udt_allow_unknown,
        range_check=config.udt_range_check,
    )
    steps = list(pre.steps)
    before = [i for i, s in enumerate(steps) if isinstance(s, AddBatchDimensionProcessorStep | NormalizerProcessorStep)]
    if not before:
        raise ValueError(
            f"the stock {config.base_type} pre-processor has no batching or normaliser step to put the UniDexTok "
            f"step before ({[type(s).__name__ for s in steps]}); this policy type cannot be wrapped"
        )
    steps.insert(before[0], step)
    pre.steps = steps
    if config.udt_native_action and config.udt_native_layout:
        post.steps = [*post.steps, UDHMToNativeCommandStep.from_layout(NativeLayout(**config.udt_native_layout))]
    return pre, post


def __getattr__(name: str) -> Any:
    match = _FACTORY_NAME.fullmatch(name)
    if match is None or match.group(1) not in UDT_CONFIGS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return make_udt_pre_post_processors
