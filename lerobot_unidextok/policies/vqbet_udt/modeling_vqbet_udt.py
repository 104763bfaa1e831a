"""`vqbet_udt` policy: LeRobot's `VQBeTPolicy`, unchanged, under `VQBeTUdtConfig` (LeRobot's factory finds it here by name)."""

from lerobot.policies.vqbet.modeling_vqbet import VQBeTPolicy

from lerobot_unidextok.policies.vqbet_udt.configuration_vqbet_udt import VQBeTUdtConfig


class VQBeTUdtPolicy(VQBeTPolicy):
    """VQBeTPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=vqbet_udt`)."""

    config_class = VQBeTUdtConfig
    name = "vqbet_udt"
