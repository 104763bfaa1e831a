"""lerobot-unidextok: UDHM hand model, dataset converters and the UniDexTok hand-state tokenizer.

from lerobot_unidextok import udhm, hands, UniDexTok
"""

# Before anything imports LeRobot or tqdm: LeRobot's ~100-line torchcodec/FFmpeg warning becomes a one-line
# note, and progress bars refresh every 30 s when stderr is not a terminal (utils/cli.py).
from lerobot_unidextok.utils.cli import configure_output  # noqa: I001

configure_output()

# LeRobot registration on import: the `unidextok.state_tokenizer` / `unidextok.udhm_to_native`
# processor steps and the `<type>_udt` policy types (act_udt, diffusion_udt, vqbet_udt; docs/lerobot.md).
from lerobot_unidextok import policies as _policies  # noqa: E402, F401
from lerobot_unidextok import processor as _processor  # noqa: E402, F401
from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_DIM, UDHM_JOINT_NAMES  # noqa: E402
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig  # noqa: E402

__version__ = "0.1.0"

__all__ = ["KEYPOINT_NAMES", "UDHM_DIM", "UDHM_JOINT_NAMES", "UniDexTok", "UniDexTokConfig", "__version__"]
