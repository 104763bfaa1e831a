"""UDHM blocks: where the 22-wide hand blocks sit in a (possibly wider) state or action vector, found by name.

Layer 0: names only, no lerobot import. A converted dataset's `observation.state` / `action` is

    [passthrough columns of the source (arms, grippers, base...), source names, source order]
    + [one 22-wide UDHM block per hand, named `<side>_<udhm joint>` in UDHM order]

so a hands-only dataset is the special case with no passthrough columns. Consumers (training reader,
processor step, policies) never assume positions: they call `find_udhm_blocks(names)` on the flat
`feature_names` of the feature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lerobot_unidextok.constants import SIDES, UDHM_DIM, UDHM_JOINT_NAMES


def flatten_names(names: object) -> list[str]:
    """LeRobot feature `names` as one flat list of strings, in order.

    LeRobot writes a flat list, a list nested in a list (`[["a", "b"]]`) or a dict of lists (`{"motors": [...]}`,
    `{"axes": [...]}`); no names give []. Anything else is a ValueError.
    """
    if not names:
        return []
    if isinstance(names, dict):
        return [n for value in names.values() for n in flatten_names(value)]
    if isinstance(names, (list, tuple)):
        return [
            n for item in names for n in (flatten_names(item) if isinstance(item, (list, tuple, dict)) else [str(item)])
        ]
    raise ValueError(f"feature names must be a list or dict of lists, got {type(names).__name__}")


def feature_names(feature: dict) -> list[str]:
    """The flat `names` of a LeRobot feature (its entry in `meta/info.json` `features`)."""
    return flatten_names(feature.get("names"))


def udhm_block_names(side: str) -> list[str]:
    """The 22 feature names of one UDHM block: `<side>_<udhm joint>` in UDHM order."""
    if side not in SIDES:
        raise ValueError(f"side must be one of {SIDES}, got {side!r}")
    return [f"{side}_{joint}" for joint in UDHM_JOINT_NAMES]


def udhm_state_names(sides: tuple[str, ...] | list[str]) -> list[str]:
    """Names of consecutive UDHM blocks, one per side in the given order."""
    return [name for side in sides for name in udhm_block_names(side)]


@dataclass(frozen=True)
class UdhmBlock:
    """One UDHM block in a vector: its side and the slice of its 22 columns."""

    side: str
    start: int

    @property
    def stop(self) -> int:
        return self.start + UDHM_DIM

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)


def find_udhm_blocks(names: list[str] | tuple[str, ...]) -> list[UdhmBlock]:
    """Every UDHM block among `names`, in vector order.

    A block is 22 consecutive names `<side>_<joint>` in UDHM order. A name that looks like a UDHM column
    but is not part of a complete block (wrong order, missing joints, duplicated side) raises a ValueError
    naming it, because silently treating half a hand as passthrough would corrupt data.
    """
    names = list(names)
    udhm_like = {f"{side}_{joint}": side for side in SIDES for joint in UDHM_JOINT_NAMES}
    blocks: list[UdhmBlock] = []
    i = 0
    while i < len(names):
        side = udhm_like.get(names[i])
        if side is None:
            i += 1
            continue
        expected = udhm_block_names(side)
        if names[i : i + UDHM_DIM] != expected:
            got = names[i : i + UDHM_DIM]
            bad = next((k for k, (a, b) in enumerate(zip(got, expected, strict=False)) if a != b), len(got))
            raise ValueError(
                f"name {names[i]!r} at position {i} starts a UDHM block, but the block is incomplete or out of order "
                f"at position {i + bad} (expected {expected[bad] if bad < UDHM_DIM else 'end'!r}, got "
                f"{got[bad] if bad < len(got) else 'end of names'!r}); a UDHM block is the 22 names "
                f"{expected[0]} ... {expected[-1]} in UDHM order"
            )
        if any(b.side == side for b in blocks):
            raise ValueError(f"two UDHM blocks for side {side!r} in the names; one block per side")
        blocks.append(UdhmBlock(side=side, start=i))
        i += UDHM_DIM
    return blocks


def passthrough_indices(names: list[str] | tuple[str, ...], blocks: list[UdhmBlock] | None = None) -> np.ndarray:
    """Indices of the columns that belong to no UDHM block (arms, grippers, ...), in vector order."""
    blocks = find_udhm_blocks(names) if blocks is None else blocks
    keep = np.ones(len(names), dtype=bool)
    for b in blocks:
        keep[b.slice] = False
    return np.flatnonzero(keep)
