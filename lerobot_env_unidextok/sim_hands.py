"""Which model a registered hand spec runs on in the simulator: the choice above both sources.

A spec whose embodiment has a model file (`hand_models/<embodiment>.yaml`, `hand_model.from_model_file`) runs on
it; any other spec is built from its URDF (`urdf_hand.sim_hand`: the MJCF from `urdf_model.model_xml`, a shipped
one where the URDF is not found). `load` is what the env, the recorder and LeRobot's config call.
"""

from __future__ import annotations

import functools

from lerobot_env_unidextok import urdf_model
from lerobot_env_unidextok.errors import SimHandError
from lerobot_env_unidextok.hand_model import SimHand, from_model_file, model_names
from lerobot_env_unidextok.urdf_hand import sim_hand
from lerobot_unidextok import hands
from lerobot_unidextok.utils.shared_data import URDF_DIR_ENV, urdf_dir


def sim_hand_names() -> tuple[str, ...]:
    """Hand specs the simulator runs: every registered spec whose embodiment has a model file, or whose built model
    ships with the package, or whose URDF is found (`$UNIDEXTOK_URDF_DIR`, else ../shared/data/urdf)."""
    models = set(model_names())
    return tuple(n for n in hands.names()
                 if hands.get(n).embodiment in models or urdf_model.buildable(hands.get(n)))  # fmt: skip


def load(hand: str) -> SimHand:
    """The simulator's model of the registered hand spec `hand` (its native units), right side: its embodiment's
    model file when there is one, else built from its URDF (or the built model the package ships)."""
    if hand not in hands.names():
        raise SimHandError(f"unknown hand {hand!r}; the simulator runs: {', '.join(sim_hand_names())}")
    spec = hands.get(hand)
    if spec.embodiment not in model_names() and not urdf_model.buildable(spec):
        why = (f"its URDF {spec.urdf.files['right']} is not under {urdf_dir()} and no built model of "
               f"it ships (set {URDF_DIR_ENV} to the folder holding it)"
               if spec.kind == "joints" and spec.urdf is not None and "right" in spec.urdf.files
               else "its spec maps no URDF (a `urdf:` block, docs/hands.md)")  # fmt: skip
        raise SimHandError(f"hand {hand!r} cannot be simulated: {why}; the simulator runs: "
                           f"{', '.join(sim_hand_names())}")  # fmt: skip
    return _load(hand)


@functools.cache
def _load(hand: str) -> SimHand:
    spec = hands.get(hand)
    return from_model_file(spec) if spec.embodiment in model_names() else sim_hand(spec)


__all__ = ["load", "sim_hand_names"]
