"""`--policy.type=diffusion_udt`: config and processors. The policy class, `modeling_diffusion_udt.DiffusionUdtPolicy`, is imported
only by LeRobot's factory when the policy is built (Diffusion's modeling needs the optional diffusers)."""

from lerobot_unidextok.policies.diffusion_udt.configuration_diffusion_udt import DiffusionUdtConfig
from lerobot_unidextok.policies.diffusion_udt.processor_diffusion_udt import make_diffusion_udt_pre_post_processors

__all__ = ["DiffusionUdtConfig", "make_diffusion_udt_pre_post_processors"]
