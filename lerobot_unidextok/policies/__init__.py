"""Plugin policy types whose pre-processor holds the UniDexTok step: `--policy.type=<stock type>_udt`.

One LeRobot trio per wrapped stock policy (`act_udt/`, `diffusion_udt/`, `vqbet_udt/`: `configuration_*`,
`modeling_*`, `processor_*`), sharing `udt_config.UdtConfigMixin` (the `udt_*` fields) and
`udt_processor.insert_udt_steps` (the processor assembly). Importing this package registers the types;
LeRobot's CLIs import it through the `lerobot_policy_unidextok` plugin package.
"""

from lerobot_unidextok.policies.act_udt import ACTUdtConfig
from lerobot_unidextok.policies.diffusion_udt import DiffusionUdtConfig
from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.policies.vqbet_udt import VQBeTUdtConfig

UDT_CONFIGS = {"act_udt": ACTUdtConfig, "diffusion_udt": DiffusionUdtConfig, "vqbet_udt": VQBeTUdtConfig}

__all__ = ["UDT_CONFIGS", "ACTUdtConfig", "DiffusionUdtConfig", "UdtConfigMixin", "VQBeTUdtConfig"]
