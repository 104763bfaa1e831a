"""lerobot-unidextok: UDHM hand model, dataset converters and the UniDexTok hand-state tokenizer.

from lerobot_unidextok import udhm, hands, UniDexTok
"""

# LeRobot registration on import: the `unidextok.state_tokenizer` / `unidextok.udhm_to_native`
# processor steps and the `act_udt` policy type (see docs/lerobot.md).
from lerobot_unidextok import policies as _policies  # noqa: E402, F401, I001
from lerobot_unidextok import processor as _processor
from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

__version__ = "0.1.0"

__all__ = ["KEYPOINT_NAMES", "UDHM_DIM", "UDHM_JOINT_NAMES", "UniDexTok", "UniDexTokConfig", "__version__"]
