"""lerobot-unidextok: UDHM hand model, dataset converters and the UniDexTok hand-state tokenizer."""

from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_DIM, UDHM_JOINT_NAMES

__version__ = "0.1.0"

__all__ = ["KEYPOINT_NAMES", "UDHM_DIM", "UDHM_JOINT_NAMES", "__version__"]
