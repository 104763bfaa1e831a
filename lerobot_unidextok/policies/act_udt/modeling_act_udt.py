"""`act_udt` policy: LeRobot's `ACTPolicy`, unchanged, under `ACTUdtConfig` (LeRobot's factory finds it here by name)."""

import torch
from lerobot.policies.act.modeling_act import ACTPolicy

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig


class ACTUdtPolicy(ACTPolicy):
    """ACTPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=act_udt`)."""

    config_class = ACTUdtConfig
    name = "act_udt"

    def __init__(self, config: ACTUdtConfig, **kwargs):
        super().__init__(config, **kwargs)
        if config.udt_relative_actions and config.udt_copy_start:  # the untrained policy copies the state
            torch.nn.init.zeros_(self.model.action_head.weight)
            torch.nn.init.zeros_(self.model.action_head.bias)
