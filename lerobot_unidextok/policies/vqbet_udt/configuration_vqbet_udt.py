"""`--policy.type=vqbet_udt`: LeRobot's VQ-BeT (`VQBeTConfig`) plus the `udt_*` fields of `UdtConfigMixin`."""

from dataclasses import dataclass

from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.vqbet.configuration_vqbet import VQBeTConfig

from lerobot_unidextok.policies.udt_config import UdtConfigMixin


@PreTrainedConfig.register_subclass("vqbet_udt")
@dataclass
class VQBeTUdtConfig(UdtConfigMixin, VQBeTConfig):
    """LeRobot's VQ-BeT on UniDexTok hand tokens: the stock fields, the `udt_*` fields and their checks."""
