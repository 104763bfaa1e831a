"""Policy classes of the `<type>_udt` types: the stock LeRobot model, unchanged, under the `<type>_udt` config.

LeRobot's factory resolves `<X>UdtConfig` -> `<X>UdtPolicy` in this module by name. Each class is created
on first access (PEP 562 module `__getattr__`), so a type's stock modeling module (and its optional
dependencies, e.g. diffusers for Diffusion) is imported only when that type is used.
"""

from __future__ import annotations

from lerobot.policies.pretrained import PreTrainedPolicy

from lerobot_unidextok.policies.udt import configuration_udt


def __getattr__(name: str) -> type[PreTrainedPolicy]:
    config_cls = getattr(configuration_udt, name.removesuffix("Policy") + "Config", None)
    if not name.endswith("UdtPolicy") or config_cls is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from lerobot.policies.factory import get_policy_class

    base = get_policy_class(config_cls.base_type)  # e.g. ACTPolicy
    doc = f"LeRobot's {base.__name__} reading UniDexTok hand tokens (`--policy.type={config_cls.udt_type}`)."
    namespace = {"__module__": __name__, "__qualname__": name, "__doc__": doc}
    cls = type(name, (base,), {**namespace, "config_class": config_cls, "name": config_cls.udt_type})
    globals()[name] = cls
    return cls
