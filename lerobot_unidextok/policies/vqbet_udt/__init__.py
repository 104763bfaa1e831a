"""`--policy.type=vqbet_udt`: LeRobot's VQ-BeT on UniDexTok hand tokens (config, policy, processors)."""

from lerobot_unidextok.policies.vqbet_udt.configuration_vqbet_udt import VQBeTUdtConfig
from lerobot_unidextok.policies.vqbet_udt.modeling_vqbet_udt import VQBeTUdtPolicy
from lerobot_unidextok.policies.vqbet_udt.processor_vqbet_udt import make_vqbet_udt_pre_post_processors

__all__ = ["VQBeTUdtConfig", "VQBeTUdtPolicy", "make_vqbet_udt_pre_post_processors"]
