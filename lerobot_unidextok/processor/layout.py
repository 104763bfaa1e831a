"""Which hand sits in which 22-wide block of `observation.state` (no lerobot import here)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_unidextok.constants import (
    HAND_TYPE_KEY,
    OBS_STATE,
    SIDES,
    UDHM_DIM,
    UDHM_JOINT_NAMES,
)


@dataclass
class HandLayout:
    """Hand spec name and side of each UDHM block, in block order."""

    hands: list[str]  # hand spec names, e.g. ["inspire_rh56", "inspire_rh56"] or ["human"]
    sides: list[str] = field(default_factory=list)  # "right" | "left" per block; [] = unknown

    def __post_init__(self) -> None:
        self.hands, self.sides = list(self.hands), list(self.sides)
        if not self.hands:
            raise ValueError("HandLayout needs at least one hand name, e.g. HandLayout(['human'])")
        if self.sides and len(self.sides) != len(self.hands):
            raise ValueError(f"got {len(self.sides)} sides for {len(self.hands)} hands: {self.sides} vs {self.hands}")
        bad = [s for s in self.sides if s not in SIDES]
        if bad:
            raise ValueError(f"sides must be in {SIDES}, got {bad}")

    @property
    def num_hands(self) -> int:
        return len(self.hands)

    @property
    def state_dim(self) -> int:
        return UDHM_DIM * self.num_hands

    def check_width(self, width: int, key: str = OBS_STATE) -> None:
        """Raise a ValueError naming the fix when `width` is not this layout's state width."""
        if width != self.state_dim:
            known = ", ".join(f"{UDHM_DIM * h} ({h} hand{'s' * (h > 1)})" for h in (1, 2))
            raise ValueError(
                f"{key} has width {width}, which matches no UDHM layout for hands {self.hands} "
                f"(expected {self.state_dim}; known widths: {known}). Convert the dataset to UDHM with "
                "unidextok-convert, or set hand_layout to one hand name per 22-wide block"
            )

    @classmethod
    def from_state_names(cls, names: list[str], hands: list[str] | str) -> HandLayout:
        """Layout from `<side>_<udhm joint>` feature names; `hands` is one name or one per block."""
        names = list(names)
        if len(names) % UDHM_DIM or not names:
            raise ValueError(
                f"{len(names)} state names match no UDHM layout (need 22 per hand); "
                "is this a dataset written by unidextok-convert?"
            )
        sides = []
        for b in range(len(names) // UDHM_DIM):
            block = names[b * UDHM_DIM : (b + 1) * UDHM_DIM]
            side = block[0].split("_", 1)[0]
            expected = [f"{side}_{j}" for j in UDHM_JOINT_NAMES]
            if side not in SIDES or block != expected:
                raise ValueError(
                    f"state names of block {b} are not '<side>_<udhm joint>' in UDHM order: "
                    f"got {block[:3]}..., expected {expected[:3]}..."
                )
            sides.append(side)
        hands = [hands] * len(sides) if isinstance(hands, str) else list(hands)
        if len(hands) != len(sides):
            raise ValueError(f"{len(hands)} hand names for {len(sides)} UDHM blocks ({sides})")
        return cls(hands=hands, sides=sides)


def hand_layout_from_dataset(root: str | Path) -> HandLayout:
    """Layout of a converted UDHM dataset folder: sides from state names, hands from `hand_type`."""
    import pyarrow.parquet as pq

    root = Path(root)
    info_path = root / "meta" / "info.json"
    if not info_path.is_file():
        raise FileNotFoundError(f"{info_path} not found: pass the root folder of a LeRobotDataset v3.0")
    features = json.loads(info_path.read_text())["features"]
    if OBS_STATE not in features or HAND_TYPE_KEY not in features:
        raise ValueError(f"{root} lacks '{OBS_STATE}' or '{HAND_TYPE_KEY}'; convert it to UDHM with unidextok-convert")
    files = sorted((root / "data").rglob("*.parquet"))
    if not files:
        raise FileNotFoundError(f"no data parquet under {root / 'data'}")
    import pyarrow as pa
    import pyarrow.compute as pc

    column = pa.concat_arrays([pq.read_table(f, columns=[HAND_TYPE_KEY]).column(0).combine_chunks() for f in files])
    if pa.types.is_list(column.type) or pa.types.is_fixed_size_list(column.type):
        column = pc.list_flatten(column)
    hand_types = sorted(pc.unique(column).to_pylist())
    if len(hand_types) != 1:
        raise ValueError(
            f"{root} mixes hand layouts across frames ({hand_types}), but a processor step tokenises every "
            "frame with one fixed layout. Convert each hand into its own dataset (e.g. --max_episodes or "
            "separate inputs), or pass hand_layout explicitly if one layout is really meant for all frames"
        )
    return HandLayout.from_state_names(features[OBS_STATE]["names"], str(hand_types[0]).split(","))
