"""LeRobot processor steps wrapping UniDexTok (registered in ProcessorStepRegistry on import): the tokenizer step
(`processor_unidextok.py`), its per-row variant for mixed datasets (`mixed.py`) and the two native steps, one per
direction (`native.py`); the per-hand scale of a mix policy's relative actions (`hand_action_scale.py`); and which
view of the hands the model reads, state or tokens (`hand_input.py`)."""

from lerobot_unidextok.layout import HandLayout, NativeLayout
from lerobot_unidextok.processor.guards import RANGE_CHECKS, hand_bounds_rad
from lerobot_unidextok.processor.hand_action_scale import HAND_ACTION_SCALE_STEP_NAME, HandActionScaleStep
from lerobot_unidextok.processor.hand_input import HAND_INPUT_STEP_NAME, HAND_INPUTS, HandInputStep
from lerobot_unidextok.processor.mixed import MIXED_STEP_NAME, UniDexTokMixedTokenizerStep
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

__all__ = [
    "HAND_ACTION_SCALE_STEP_NAME",
    "HAND_INPUTS",
    "HAND_INPUT_STEP_NAME",
    "MIXED_STEP_NAME",
    "NATIVE_TO_UDHM_STEP_NAME",
    "RANGE_CHECKS",
    "REPRESENTATIONS",
    "STEP_NAME",
    "UDHM_TO_NATIVE_STEP_NAME",
    "HandActionScaleStep",
    "HandInputStep",
    "HandLayout",
    "NativeLayout",
    "NativeToUDHMStateStep",
    "UDHMToNativeCommandStep",
    "UniDexTokMixedTokenizerStep",
    "UniDexTokStateTokenizerStep",
    "hand_bounds_rad",
    "token_preview",
    "tokenizer_output_dims",
    "tokens_to_native",
    "udhm_to_native",
]
