"""LeRobot processor steps wrapping UniDexTok (registered in ProcessorStepRegistry on import)."""

from lerobot_unidextok.processor.guards import RANGE_CHECKS, hand_bounds_rad
from lerobot_unidextok.processor.layout import HandLayout, NativeLayout, hand_layout_from_dataset
from lerobot_unidextok.processor.native_state import NATIVE_STATE_STEP_NAME, NativeToUDHMStateStep
from lerobot_unidextok.processor.preview import token_preview
from lerobot_unidextok.processor.processor_unidextok import (
    NATIVE_STEP_NAME,
    REPRESENTATIONS,
    STEP_NAME,
    UDHMToNativeCommandStep,
    UniDexTokStateTokenizerStep,
    load_tokenizer,
    tokenizer_output_dims,
    tokens_to_native,
    udhm_to_native,
)

__all__ = [
    "NATIVE_STATE_STEP_NAME",
    "NATIVE_STEP_NAME",
    "RANGE_CHECKS",
    "REPRESENTATIONS",
    "STEP_NAME",
    "HandLayout",
    "NativeLayout",
    "NativeToUDHMStateStep",
    "UDHMToNativeCommandStep",
    "UniDexTokStateTokenizerStep",
    "hand_bounds_rad",
    "hand_layout_from_dataset",
    "load_tokenizer",
    "token_preview",
    "tokenizer_output_dims",
    "tokens_to_native",
    "udhm_to_native",
]
