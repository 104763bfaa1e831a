"""The converted dataset's features and native layout, from one mapped episode (converted-dataset contract).

`observation.state` / `action` = the source's passthrough columns (arms, grippers, base: source names,
source order, values unchanged) followed by one 22-wide UDHM block per hand (`<side>_<udhm joint>`);
`hand_type`, `udhm_mask`; then every copied source feature (images, other observations) and video
unchanged. `native_layouts` says how to rebuild the robot's own vectors (docs/architecture.md).
"""

from __future__ import annotations

from copy import deepcopy

import numpy as np

from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION, HAND_TYPE_KEY, OBS_STATE, UDHM_MASK_KEY
from lerobot_unidextok.conversion.mapping import UdhmEpisode
from lerobot_unidextok.layout import NativeLayout


def udhm_features(
    sides: tuple[str, ...],
    with_action: bool,
    state_passthrough: tuple[str, ...] = (),
    action_passthrough: tuple[str, ...] = (),
) -> dict[str, dict]:
    """LeRobot features of the state/action/hand_type/udhm_mask part of the contract."""
    udhm = udhm_state_names(list(sides))
    state = [*state_passthrough, *udhm]
    features = {OBS_STATE: {"dtype": "float32", "shape": (len(state),), "names": state}}
    if with_action:
        action = [*action_passthrough, *udhm]
        features[ACTION] = {"dtype": "float32", "shape": (len(action),), "names": action}
    features[HAND_TYPE_KEY] = {"dtype": "string", "shape": (1,), "names": None}
    features[UDHM_MASK_KEY] = {"dtype": "bool", "shape": (len(udhm),), "names": udhm}
    return features


def _passthrough_names(ep: UdhmEpisode, key: str) -> tuple[str, ...]:
    p = ep.passthrough.get(key)
    return p.names if p is not None else ()


def episode_features(ep: UdhmEpisode) -> dict[str, dict]:
    """Every feature of the dataset whose first episode is `ep` (copied features keep their specs)."""
    features = udhm_features(
        ep.sides, ep.action_rad is not None, _passthrough_names(ep, OBS_STATE), _passthrough_names(ep, ACTION)
    )
    for key, ft in {**ep.copied_features, **ep.video_features}.items():
        if key in features:
            raise ValueError(f"source feature {key!r} collides with a feature the conversion writes; rename it")
        spec = deepcopy(ft)
        spec.pop("fps", None)  # LeRobot's info writer sets it
        spec["shape"] = tuple(spec["shape"])
        features[key] = spec
    return features


def episode_frames(ep: UdhmEpisode) -> dict[str, np.ndarray | str]:
    """The arrays the writer builds for `ep`: [passthrough | UDHM] vectors, hand_type, mask."""
    frames: dict[str, np.ndarray | str] = {
        OBS_STATE: _with_passthrough(ep, OBS_STATE, ep.state_rad),
        HAND_TYPE_KEY: ep.hand_type,
        UDHM_MASK_KEY: ep.mask,
    }
    if ep.action_rad is not None:
        frames[ACTION] = _with_passthrough(ep, ACTION, ep.action_rad)
    return frames


def _with_passthrough(ep: UdhmEpisode, key: str, udhm: np.ndarray) -> np.ndarray:
    p = ep.passthrough.get(key)
    if p is None:
        return udhm
    return np.concatenate([p.values.astype(np.float32, copy=False), udhm], axis=1)  # float32 source: bit-identical


def native_layouts(ep: UdhmEpisode, mapping: str) -> dict[str, NativeLayout]:
    """How to rebuild the robot's native vectors from the converted ones (robot hands only), per key.

    Native vector = the source's column names in source order; passthrough columns copied by name; each hand's
    `columns` = `hands.get(hand).from_udhm(block, side, mapping)`. Keypoint (human) hands have no native joint
    columns. A hands-only conversion (`--keep=hands`) has no passthrough columns: the native names are then the
    hand columns in source order and `source_names` lists every source column (where the robot's vector puts them).
    """
    features = episode_features(ep)
    out: dict[str, NativeLayout] = {}
    for key, which in ((OBS_STATE, 0), (ACTION, 1)):
        if key not in features:
            continue
        hands = [
            {"side": side, "hand": hand, "columns": list(cols[which])}
            for side, hand, cols in zip(
                ep.sides, ep.hands, ep.hand_columns or [(None, None)] * len(ep.sides), strict=True
            )
            if cols[which] is not None
        ]
        if not hands:
            continue
        native = ep.native_names.get(key) or [*_passthrough_names(ep, key), *(c for h in hands for c in h["columns"])]
        out[key] = NativeLayout(
            names=features[key]["names"],
            native_names=native,
            hands=hands,
            mapping=mapping,
            source_names=ep.source_names.get(key, []),
            source_key=ep.native_keys.get(key),
            dropped=ep.dropped.get(key, []),
        )
    return out
