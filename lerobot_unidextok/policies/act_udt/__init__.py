"""ACT on UniDexTok hand tokens: `--policy.type=act_udt --policy.discover_packages_path=lerobot_unidextok`."""

from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig

__all__ = ["ACTUdtConfig"]
