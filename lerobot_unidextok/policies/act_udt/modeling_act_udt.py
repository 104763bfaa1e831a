"""ACT policy reading UniDexTok features; the model itself is LeRobot's ACT."""

from lerobot.policies.act.modeling_act import ACTPolicy

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig


class ACTUdtPolicy(ACTPolicy):
    """ACT with `observation.environment_state` = UniDexTok view of the hand state."""

    config_class = ACTUdtConfig
    name = "act_udt"
