"""`act_udt` policy: LeRobot's `ACTPolicy`, unchanged, under `ACTUdtConfig` (LeRobot's factory finds it here by name)."""

from lerobot.policies.act.modeling_act import ACTPolicy

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig


class ACTUdtPolicy(ACTPolicy):
    """ACTPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=act_udt`)."""

    config_class = ACTUdtConfig
    name = "act_udt"
