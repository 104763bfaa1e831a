"""`<type>_udt`: stock LeRobot policies (act, diffusion, vqbet) on UniDexTok hand tokens, one generic wrapper."""

from lerobot_unidextok.policies.udt.configuration_udt import (
    UDT_CONFIGS,
    ACTUdtConfig,
    DiffusionUdtConfig,
    VQBeTUdtConfig,
    udt_config_class,
)

__all__ = ["UDT_CONFIGS", "ACTUdtConfig", "DiffusionUdtConfig", "VQBeTUdtConfig", "udt_config_class"]
