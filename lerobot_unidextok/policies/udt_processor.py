"""The processors of every `<type>_udt` type: the stock pipelines with the UniDexTok step inserted after batching.

    rename -> to_batch -> unidextok.state_tokenizer -> device -> normalizer      (pre)
    unnormalizer -> to cpu [-> unidextok.udhm_to_native]                          (post)

The step sits after `to_batch_processor`, so its outputs have the batch dimensions of the batched state
(LeRobot's batching step adds them only to its own keys: with the step before it, `observation.hand_tokens`
of one frame stayed `(T,)` beside a `(1, D)` state), and before `normalizer_processor` (it must see raw
radians, never normalised values). Each `processor_<type>_udt.make_<type>_udt_pre_post_processors` builds
the stock pair and passes it through `insert_udt_steps`.
"""

from __future__ import annotations

from lerobot.processor import AddBatchDimensionProcessorStep, NormalizerProcessorStep, PolicyProcessorPipeline

from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.processor import NativeLayout, UDHMToNativeCommandStep, UniDexTokStateTokenizerStep


def insert_udt_steps(
    config: UdtConfigMixin, pre: PolicyProcessorPipeline, post: PolicyProcessorPipeline
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """The stock `pre`, `post` of `config`'s policy with the UniDexTok step (and the native-action decoder)."""
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
    after_batch = [i + 1 for i, s in enumerate(steps) if isinstance(s, AddBatchDimensionProcessorStep)]
    normalizer = [i for i, s in enumerate(steps) if isinstance(s, NormalizerProcessorStep)]
    if not after_batch and not normalizer:
        raise ValueError(
            f"the stock {config.type} pre-processor has no batching or normaliser step to place the UniDexTok "
            f"step by ({[type(s).__name__ for s in steps]}); this policy type cannot be wrapped"
        )
    steps.insert(min(after_batch[:1] + normalizer[:1]), step)  # after batching, before normalising
    pre.steps = steps
    if config.udt_native_action and config.udt_native_layout:
        post.steps = [*post.steps, UDHMToNativeCommandStep.from_layout(NativeLayout(**config.udt_native_layout))]
    return pre, post
