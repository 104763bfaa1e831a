"""`--policy.type=act_udt`: LeRobot's ACT on UniDexTok hand tokens (config, policy, processors)."""

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig
from lerobot_unidextok.policies.act_udt.modeling_act_udt import ACTUdtPolicy
from lerobot_unidextok.policies.act_udt.processor_act_udt import make_act_udt_pre_post_processors

__all__ = ["ACTUdtConfig", "ACTUdtPolicy", "make_act_udt_pre_post_processors"]
