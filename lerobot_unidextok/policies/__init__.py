"""Plugin policy types whose pre-processor holds the UniDexTok step: `--policy.type=<stock type>_udt`
(act_udt, diffusion_udt, vqbet_udt; see policies/udt/configuration_udt.py for why one generic wrapper)."""

from lerobot_unidextok.policies.udt import (
    UDT_CONFIGS,
    ACTUdtConfig,
    DiffusionUdtConfig,
    VQBeTUdtConfig,
    udt_config_class,
)

__all__ = ["UDT_CONFIGS", "ACTUdtConfig", "DiffusionUdtConfig", "VQBeTUdtConfig", "udt_config_class"]
