"""LeRobot processor steps wrapping UniDexTok (registered in ProcessorStepRegistry on import): the tokenizer step
(`processor_unidextok.py`), its per-row variant for mixed datasets (`mixed.py`) and the two native steps, one per
direction (`native.py`); per-hand normalisation of the state and actions (`hand_normalizer.py`; the relative-action
scale of checkpoints saved before it, `hand_action_scale.py`); the action slots a row's hand lacks, left out of the
loss (`slot_mask.py`); each input's share of a mix as a loss weight per row (`share_weights.py`); which view of
the hands the model reads, state or tokens (`hand_input.py`); and the wrist position as the hand's grasp centre
(`wrist_frame.py`)."""

from lerobot_unidextok.layout import HandLayout, NativeLayout
from lerobot_unidextok.processor.guards import RANGE_CHECKS, hand_bounds_rad
from lerobot_unidextok.processor.hand_action_scale import HAND_ACTION_SCALE_STEP_NAME, HandActionScaleStep
from lerobot_unidextok.processor.hand_input import HAND_INPUT_STEP_NAME, HAND_INPUTS, HandInputStep
from lerobot_unidextok.processor.hand_normalizer import HAND_NORMALIZER_STEP_NAME, STATS_OF_MODE, HandNormalizerStep
from lerobot_unidextok.processor.mixed import IDENTITIES, MIXED_STEP_NAME, UniDexTokMixedTokenizerStep, identity_width
from lerobot_unidextok.processor.native import (
    NATIVE_TO_UDHM_STEP_NAME,
    UDHM_TO_NATIVE_STEP_NAME,
    NativeToUDHMStateStep,
    UDHMToNativeCommandStep,
    tokens_to_native,
    udhm_to_native,
)
from lerobot_unidextok.processor.preview import token_preview
from lerobot_unidextok.processor.processor_unidextok import (
    REPRESENTATIONS,
    STEP_NAME,
    UniDexTokStateTokenizerStep,
    tokenizer_output_dims,
)
from lerobot_unidextok.processor.share_weights import SAMPLE_WEIGHT_KEY, SHARE_WEIGHTS_STEP_NAME, ShareWeightStep
from lerobot_unidextok.processor.slot_mask import ACTION_SLOT_PAD_KEY, SLOT_MASK_STEP_NAME, SlotMaskStep
from lerobot_unidextok.processor.wrist_frame import WRIST_FRAME_STEP_NAME, WristFrameStep

__all__ = [
    "IDENTITIES",
    "identity_width",
    "ACTION_SLOT_PAD_KEY",
    "HAND_ACTION_SCALE_STEP_NAME",
    "HAND_NORMALIZER_STEP_NAME",
    "HAND_INPUTS",
    "HAND_INPUT_STEP_NAME",
    "MIXED_STEP_NAME",
    "NATIVE_TO_UDHM_STEP_NAME",
    "RANGE_CHECKS",
    "REPRESENTATIONS",
    "SAMPLE_WEIGHT_KEY",
    "SHARE_WEIGHTS_STEP_NAME",
    "SLOT_MASK_STEP_NAME",
    "STATS_OF_MODE",
    "STEP_NAME",
    "UDHM_TO_NATIVE_STEP_NAME",
    "WRIST_FRAME_STEP_NAME",
    "HandActionScaleStep",
    "HandInputStep",
    "HandNormalizerStep",
    "HandLayout",
    "NativeLayout",
    "NativeToUDHMStateStep",
    "ShareWeightStep",
    "SlotMaskStep",
    "UDHMToNativeCommandStep",
    "UniDexTokMixedTokenizerStep",
    "UniDexTokStateTokenizerStep",
    "WristFrameStep",
    "hand_bounds_rad",
    "token_preview",
    "tokenizer_output_dims",
    "tokens_to_native",
    "udhm_to_native",
]
