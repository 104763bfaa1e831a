"""`--policy.type=act_udt`: LeRobot's ACT (`ACTConfig`) plus the `udt_*` fields of `UdtConfigMixin`."""

from dataclasses import dataclass
from typing import ClassVar

from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.act.configuration_act import ACTConfig

from lerobot_unidextok.policies.udt_config import UdtConfigMixin


@PreTrainedConfig.register_subclass("act_udt")
@dataclass
class ACTUdtConfig(UdtConfigMixin, ACTConfig):
    """LeRobot's ACT on UniDexTok hand tokens: the stock fields, the `udt_*` fields and their checks."""

    supports_hand_heads: ClassVar[bool] = True  # udt_hand_heads: policies/hand_heads.py
