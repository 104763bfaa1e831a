"""Plugin policy types whose pre-processor holds the UniDexTok step (`--policy.type=act_udt`)."""

from lerobot_unidextok.policies.act_udt import ACTUdtConfig

__all__ = ["ACTUdtConfig"]
