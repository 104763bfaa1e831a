"""The processors of every `<type>_udt` type: the stock pipelines with the UniDexTok step inserted after batching.

    rename -> to_batch [-> unidextok.native_to_udhm] -> unidextok.state_tokenizer [-> unidextok.wrist_frame]
        -> device [-> relative] [-> unidextok.hand_normalizer] [-> unidextok.slot_mask]
        [-> unidextok.share_weights] [-> unidextok.hand_input] -> normalizer                                    (pre)
    unnormalizer [-> unidextok.hand_normalizer] [-> absolute] -> to cpu [-> unidextok.wrist_frame]
        [-> unidextok.udhm_to_native]                                                                           (post)

Grasp-centre frame (`udt_grasp_centres_m`, filled unless `udt_wrist_frame=robot`): `unidextok.wrist_frame` moves
the wrist position of the state and action to each row's hand's grasp centre before everything that reads them
(relative step, normalisers) and moves the predicted action back to the wrist after them
(`processor/wrist_frame.py`).

Per-hand normalisation (`udt_hand_stats`, filled unless `udt_hand_norm=off`): `unidextok.hand_normalizer`
normalises the action (and the state, `udt_hand_norm_state`) per hand before LeRobot's normaliser (IDENTITY for
them then) and restores the action after its unnormaliser; `unidextok.slot_mask` marks the action slots each
row's hand lacks for the loss (`udt_mask_slots`), `unidextok.share_weights` each row's share weight on a mix with
`--weights`. Checkpoints saved before these (and `udt_hand_norm=off`) keep `unidextok.hand_action_scale` between
the relative pair on a mix.

The steps sit after `to_batch_processor`, so their outputs have the batch dimensions of the batched state
(LeRobot's batching step adds them only to its own keys: with the tokenizer step before it,
`observation.hand_tokens` of one frame stayed `(T,)` beside a `(1, D)` state), and before
`normalizer_processor` (they must see raw values, never normalised ones). `unidextok.native_to_udhm` maps the
robot's native `observation.state` to the converted layout (the converted state of the training batches
passes unchanged); it is there when the training dataset recorded a native state layout and
`udt_native_state` is on. With `udt_relative_actions`, LeRobot's own `RelativeActionsProcessorStep` (action -=
converted state, the state cached) sits just before the normaliser and its `AbsoluteActionsProcessorStep` (action
+= that cached state) just after the unnormaliser, as in LeRobot's pi0 processors; both are saved with the
checkpoint and LeRobot's factory re-pairs them on reload (`make_pre_post_processors(pretrained_path=...)`). On a
mix, `unidextok.hand_action_scale` sits inside that pair (after the relative step, before the absolute one) and
scales each block's offsets by the hand it holds (`udt_hand_action_scale`). On a
dataset written by `unidextok-mix` the tokenizer step is `unidextok.mixed_state_tokenizer` (hands per row,
`processor/mixed.py`). Each `processor_<type>_udt.make_<type>_udt_pre_post_processors` builds the stock pair and
passes it through `insert_udt_steps`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from lerobot.processor import (
    AbsoluteActionsProcessorStep,
    AddBatchDimensionProcessorStep,
    NormalizerProcessorStep,
    PolicyProcessorPipeline,
    RelativeActionsProcessorStep,
    UnnormalizerProcessorStep,
)

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import ACTION, OBS_STATE, UDHM_DIM
from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.processor import (
    HandActionScaleStep,
    HandInputStep,
    HandNormalizerStep,
    NativeLayout,
    NativeToUDHMStateStep,
    ShareWeightStep,
    SlotMaskStep,
    UDHMToNativeCommandStep,
    UniDexTokMixedTokenizerStep,
    UniDexTokStateTokenizerStep,
    WristFrameStep,
)


def insert_udt_steps(
    config: UdtConfigMixin,
    pre: PolicyProcessorPipeline,
    post: PolicyProcessorPipeline,
    dataset_stats: dict[str, dict[str, Any]] | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """The stock `pre`, `post` of `config`'s policy with the UniDexTok step (and the native-action decoder, the
    per-hand normaliser and the slot mask); `dataset_stats` (LeRobot's) give the passthrough columns' statistics."""
    common = dict(
        state_names=config.udt_state_names,
        pretrained=config.udt_pretrained,
        preset=config.udt_preset,
        representation=config.udt_representation,
        # the one place that asks the tokenizer about the hands, and only when its tokens are the policy's input
        allow_unknown=config.udt_allow_unknown or not config.reads_trained_tokens,
        range_check=config.udt_range_check,
        encoding=config.udt_encoding,
        encode=config.reads_tokens,  # the state alone: the token view is never read, so never made
    )
    if config.udt_hand_vocabulary:  # a mix of robots and people: hands per row, and their identity
        step = UniDexTokMixedTokenizerStep(
            hand_vocabulary=config.udt_hand_vocabulary,
            fixed_hand_ids=config.udt_fixed_hand_ids,
            extra_hands=config.udt_extra_hands,
            identity=config.udt_hand_identity,
            **common,
        )
    else:
        step = UniDexTokStateTokenizerStep(hand_layout=config.udt_hand_layout, **common)
    steps = list(pre.steps)
    after_batch = [i + 1 for i, s in enumerate(steps) if isinstance(s, AddBatchDimensionProcessorStep)]
    normalizer = [i for i, s in enumerate(steps) if isinstance(s, NormalizerProcessorStep)]
    if not after_batch and not normalizer:
        raise ValueError(
            f"the stock {config.type} pre-processor has no batching or normaliser step to place the UniDexTok "
            f"step by ({[type(s).__name__ for s in steps]}); this policy type cannot be wrapped"
        )
    at = min(after_batch[:1] + normalizer[:1])  # after batching, before normalising
    steps.insert(at, step)
    frame = wrist_frame_steps(config) if config.uses_wrist_frame else None
    if frame is not None:  # right after the UniDexTok step: the converted state, before relative and normalisers
        steps.insert(at + 1, frame[0])
    if config.udt_native_state and config.udt_native_state_layout:
        steps.insert(at, NativeToUDHMStateStep.from_layout(NativeLayout.from_dict(config.udt_native_state_layout)))
    if config.udt_relative_actions:
        _insert_relative_pair(config, steps, post)
    if config.udt_hand_stats or (config.udt_mask_slots and config.udt_action_names):
        _insert_hand_steps(config, steps, post, dataset_stats or {})
    if config.udt_share_weights and (config.udt_input_shares or config.udt_episode_weights):  # before the normaliser
        at = max(i for i, s in enumerate(steps) if isinstance(s, NormalizerProcessorStep))
        steps.insert(at, ShareWeightStep(episode_inputs=list(config.udt_episode_inputs),
                                         shares=list(config.udt_input_shares),
                                         episode_weights=list(config.udt_episode_weights),
                                         map_of=config.udt_episode_map_of))  # fmt: skip
    if config.udt_hand_input != "both":  # after the relative step (it reads the real state), before normalising
        at = max(i for i, s in enumerate(steps) if isinstance(s, NormalizerProcessorStep))
        identity = config.num_udt_blocks * config.identity_width  # a mix's hand identity, kept
        steps.insert(at, HandInputStep(mode=config.udt_hand_input, state_names=list(config.udt_state_names),
                                       identity_width=identity))  # fmt: skip
    pre.steps = steps
    if frame is not None:  # after the absolute step and the unnormalisers, before the native decoder
        post.steps = [*post.steps, frame[1]]
    if config.udt_native_action and config.udt_native_layout:
        post.steps = [
            *post.steps,
            UDHMToNativeCommandStep.from_layout(NativeLayout.from_dict(config.udt_native_layout)),
        ]
    return pre, post


def _insert_relative_pair(config: UdtConfigMixin, pre_steps: list, post: PolicyProcessorPipeline) -> None:
    """LeRobot's relative/absolute action steps: before the normaliser (it sees the converted state) and after
    the unnormaliser (sharing the relative step, whose cached state it adds back)."""
    normalizer = [i for i, s in enumerate(pre_steps) if isinstance(s, NormalizerProcessorStep)]
    unnormalizer = [i for i, s in enumerate(post.steps) if isinstance(s, UnnormalizerProcessorStep)]
    if not normalizer or not unnormalizer:
        raise ValueError(
            f"udt_relative_actions: the stock {config.type} processors have no normaliser/unnormaliser step to place "
            "the relative/absolute action steps by; set --policy.udt_relative_actions=false"
        )
    relative = RelativeActionsProcessorStep(enabled=True, action_names=list(config.udt_action_names) or None)
    pre_steps.insert(normalizer[0], relative)
    post_steps = list(post.steps)
    post_steps.insert(unnormalizer[0] + 1, AbsoluteActionsProcessorStep(enabled=True, relative_step=relative))
    legacy = not config.udt_hand_stats  # checkpoints saved before per-hand normalisation, or udt_hand_norm=off
    if legacy and config.udt_hand_vocabulary and config.udt_hand_action_scale and config.udt_action_delta_stats:
        scale = hand_action_scale_step(config, "normalize")
        pre_steps.insert(normalizer[0] + 1, scale)  # after the relative step, before the normaliser
        post_steps.insert(unnormalizer[0] + 1, hand_action_scale_step(config, "unnormalize", pair=scale))
    post.steps = post_steps


def row_hands(config: UdtConfigMixin) -> tuple[list[str], list[str], list[int]]:
    """The hands with statistics, the zero-shot hands after them, and the fixed hand per block ([] = per row) that
    the normaliser and the slot mask index: a mix's vocabulary, its zero-shot hands and bound hands; for one robot,
    the hands its statistics have (the hands it trained on), the layout's others (a checkpoint bound zero-shot to
    another robot's hands, `unidextok-deploy --zero_shot=true`) and its layout."""
    if config.udt_hand_vocabulary:
        return list(config.udt_hand_vocabulary), list(config.udt_extra_hands), list(config.udt_fixed_hand_ids)
    trained = {h for key in (OBS_STATE, ACTION) for per in config.udt_hand_stats.get(key, {}).values() for h in per}
    known = sorted(trained) if trained else sorted(set(config.udt_hand_layout))
    extra = sorted(set(config.udt_hand_layout) - set(known))
    return known, extra, [[*known, *extra].index(h) for h in config.udt_hand_layout]


def wrist_frame_steps(config: UdtConfigMixin) -> tuple[WristFrameStep, WristFrameStep]:
    """The pre (`to_centre`) and post (`to_wrist`) grasp-centre frame steps of `config`'s hands and centres."""
    known, extra, fixed = row_hands(config)
    common = dict(state_names=list(config.udt_state_names), action_names=list(config.udt_action_names),
                  wrist_columns=list(config.udt_wrist_columns), hand_vocabulary=[*known, *extra],
                  grasp_centres_m=dict(config.udt_grasp_centres_m), fixed_hand_ids=fixed)  # fmt: skip
    pre = WristFrameStep(mode="to_centre", **common)
    return pre, WristFrameStep(mode="to_wrist", pair=pre, **common)


def _insert_hand_steps(config: UdtConfigMixin, pre_steps: list, post: PolicyProcessorPipeline,
                       dataset_stats: dict[str, dict[str, Any]]) -> None:  # fmt: skip
    """The per-hand normaliser (pre: before the normaliser, after the relative step; post: after the unnormaliser,
    before the absolute step) and the slot mask (pre), when the config has their statistics / asks for it."""
    known, extra, fixed = row_hands(config)
    state_names, action_names = list(config.udt_state_names), list(config.udt_action_names)
    if not state_names or not find_udhm_blocks(state_names) or (action_names and not find_udhm_blocks(action_names)):
        return  # a layout given without the dataset's column names: nothing to locate the blocks by
    at = max(i for i, s in enumerate(pre_steps) if isinstance(s, NormalizerProcessorStep))
    if config.udt_mask_slots and action_names:
        pre_steps.insert(at, SlotMaskStep(state_names=state_names, action_names=action_names,
                                          hand_vocabulary=[*known, *extra], fixed_hand_ids=fixed,
                                          extra_hands=extra))  # fmt: skip
    stats = config.udt_hand_stats
    if not stats or not stats.get("modes"):
        return
    common = dict(modes=dict(stats["modes"]), state_names=state_names, action_names=action_names,
                  hand_vocabulary=known, extra_hands=extra, fixed_hand_ids=fixed,
                  relative_actions=config.udt_relative_actions)  # fmt: skip
    pre_step = HandNormalizerStep(mode="normalize", stats={k: v for k, v in stats.items() if k != "modes"},
                                  dataset_stats=_as_lists(dataset_stats), **common)  # fmt: skip
    pre_steps.insert(at, pre_step)
    post_step = HandNormalizerStep(mode="unnormalize", pair=pre_step, **common)
    post_step.load_state_dict(pre_step.state_dict())
    post_steps = list(post.steps)
    unnormalizer = max(i for i, s in enumerate(post_steps) if isinstance(s, UnnormalizerProcessorStep))
    post_steps.insert(unnormalizer + 1, post_step)
    post.steps = post_steps


def _as_lists(dataset_stats: dict[str, dict[str, Any]]) -> dict[str, dict[str, list[float]]]:
    """LeRobot's dataset statistics (tensors or arrays) of the state and action as plain lists."""
    out = {}
    for key in (OBS_STATE, ACTION):
        if key in dataset_stats:
            out[key] = {k: np.asarray(v, dtype=np.float64).reshape(-1).tolist() for k, v in dataset_stats[key].items()
                        if np.asarray(v).dtype.kind in "fiu"}  # fmt: skip
    return out


def hand_action_scale_step(
    config: UdtConfigMixin, mode: str, pair: HandActionScaleStep | None = None
) -> HandActionScaleStep:
    """The per-hand relative-action scale of a mix policy (`processor/hand_action_scale.py`)."""
    return HandActionScaleStep(
        mode=mode,
        sides=list(config.udt_sides),
        hand_vocabulary=list(config.udt_hand_vocabulary),
        stats=config.udt_action_delta_stats,
        action_offset=len(config.udt_action_names) - UDHM_DIM * len(config.udt_sides),
        fixed_hand_ids=list(config.udt_fixed_hand_ids),
        pair=pair,
    )
