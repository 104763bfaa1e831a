"""`--policy.type=diffusion_udt`: LeRobot's Diffusion Policy (`DiffusionConfig`) plus the `udt_*` fields of `UdtConfigMixin`."""

from dataclasses import dataclass

from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

from lerobot_unidextok.policies.udt_config import UdtConfigMixin


@PreTrainedConfig.register_subclass("diffusion_udt")
@dataclass
class DiffusionUdtConfig(UdtConfigMixin, DiffusionConfig):
    """LeRobot's Diffusion Policy on UniDexTok hand tokens: the stock fields, the `udt_*` fields and their checks."""
