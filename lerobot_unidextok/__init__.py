"""lerobot-unidextok: UDHM hand model, dataset converters and the UniDexTok hand-state tokenizer."""

from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_DIM, UDHM_JOINT_NAMES

__version__ = "0.1.0"

__all__ = ["KEYPOINT_NAMES", "UDHM_DIM", "UDHM_JOINT_NAMES", "__version__"]

# LeRobot registration on import: the `unidextok.state_tokenizer` / `unidextok.udhm_to_native`
# processor steps and the `act_udt` policy type (see docs/lerobot.md).
from lerobot_unidextok import policies as _policies, processor as _processor  # noqa: E402, F401
