"""`diffusion_udt` policy: LeRobot's `DiffusionPolicy`, unchanged, under `DiffusionUdtConfig` (LeRobot's factory finds it here by name)."""

from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

from lerobot_unidextok.policies.diffusion_udt.configuration_diffusion_udt import DiffusionUdtConfig


class DiffusionUdtPolicy(DiffusionPolicy):
    """DiffusionPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=diffusion_udt`)."""

    config_class = DiffusionUdtConfig
    name = "diffusion_udt"
