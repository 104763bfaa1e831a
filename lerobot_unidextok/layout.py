"""Layouts: where the hands sit in a converted state / action vector, and how to get back to the robot's own.

The word "layout" means these two and nothing else (docs/architecture.md). A converted vector is
`[passthrough columns] + [one 22-wide UDHM block per hand]` (the converted-dataset contract); blocks are found
by name with `blocks.find_udhm_blocks`, never by position.

- `HandLayout`: hand spec name, side and columns of each UDHM block of `observation.state` (what the tokenizer
  step reads).
- `NativeLayout`: the robot's native vector <-> the converted vector. `to_native` (actions, the post-processor):
  passthrough columns copied by name, each hand's native columns from `hands.get(hand).from_udhm(block, side)`;
  `to_converted` (the robot's `observation.state`, the pre-processor): the inverse, each hand's native columns
  through `hands.get(hand).to_udhm(values, side)` into its UDHM block. `to_dict()` is its one schema, written
  by the converter into `meta/unidextok_conversion.json` and by the policies into their configs.

Reading them from a converted dataset folder: `data.meta.UdhmDatasetMeta`.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lerobot_unidextok.blocks import find_udhm_blocks, passthrough_indices, udhm_state_names
from lerobot_unidextok.constants import OBS_STATE, SIDES, UDHM_DIM


def _hand_spec(name: str):
    """The registered hand spec `name`. The registry imports torch, so it is imported here, on first use:
    `unidextok-convert --help` reaches this module through the conversion record without needing torch."""
    from lerobot_unidextok import hands

    return hands.get(name)


@dataclass
class HandLayout:
    """Hand spec name and side of each UDHM block, in block order, and where the blocks sit in the state.

    `state_names` empty: the state is exactly the blocks (22 * H wide, a hands-only dataset). Otherwise the
    blocks are found by name among `state_names` and every other column is passthrough (arms, grippers...).
    """

    hands: list[str]  # hand spec names, e.g. ["inspire_rh56", "inspire_rh56"] or ["human"]
    sides: list[str] = field(default_factory=list)  # "right" | "left" per block; [] = unknown
    state_names: list[str] = field(default_factory=list)  # names of the whole state vector; [] = blocks only

    def __post_init__(self) -> None:
        self.hands, self.sides, self.state_names = list(self.hands), list(self.sides), list(self.state_names)
        if not self.hands:
            raise ValueError("HandLayout needs at least one hand name, e.g. HandLayout(['human'])")
        if self.sides and len(self.sides) != len(self.hands):
            raise ValueError(f"got {len(self.sides)} sides for {len(self.hands)} hands: {self.sides} vs {self.hands}")
        bad = [s for s in self.sides if s not in SIDES]
        if bad:
            raise ValueError(f"sides must be in {SIDES}, got {bad}")
        if self.state_names:
            blocks = find_udhm_blocks(self.state_names)
            if len(blocks) != len(self.hands):
                raise ValueError(
                    f"the state names hold {len(blocks)} UDHM blocks ({[b.side for b in blocks]}) but the layout "
                    f"names {len(self.hands)} hands {self.hands}; give one hand spec per block"
                )
            block_sides = [b.side for b in blocks]
            if self.sides and self.sides != block_sides:
                raise ValueError(f"sides {self.sides} disagree with the state names' blocks {block_sides}")
            self.sides = block_sides

    @property
    def num_hands(self) -> int:
        return len(self.hands)

    @property
    def state_dim(self) -> int:
        """Width of the whole state vector (passthrough + blocks)."""
        return len(self.state_names) if self.state_names else UDHM_DIM * self.num_hands

    @property
    def block_columns(self) -> np.ndarray:
        """(22 * H,) int64: state columns of the UDHM blocks, block after block."""
        if not self.state_names:
            return np.arange(UDHM_DIM * self.num_hands)
        return np.concatenate([np.arange(b.start, b.stop) for b in find_udhm_blocks(self.state_names)])

    @property
    def passthrough_names(self) -> list[str]:
        return [self.state_names[i] for i in passthrough_indices(self.state_names)] if self.state_names else []

    def check_width(self, width: int, key: str = OBS_STATE) -> None:
        """Raise a ValueError naming the fix when `width` is not this layout's state width."""
        if width == self.state_dim:
            return
        if self.state_names:
            raise ValueError(
                f"{key} has width {width}, but this step was set up for {self.state_dim} columns "
                f"({len(self.passthrough_names)} passthrough + {self.num_hands} UDHM blocks for hands {self.hands}); "
                "feed the same state layout as the dataset the step was built from (state_names)"
            )
        known = ", ".join(f"{UDHM_DIM * h} ({h} hand{'s' * (h > 1)})" for h in (1, 2))
        raise ValueError(
            f"{key} has width {width}, which matches no UDHM layout for hands {self.hands} "
            f"(expected {self.state_dim}; known widths: {known}). Convert the dataset to UDHM with "
            "unidextok-convert, or set hand_layout to one hand name per 22-wide block; a whole-robot state "
            "(arms + hands) needs state_names (UniDexTokStateTokenizerStep.from_dataset reads them)"
        )

    @classmethod
    def from_state_names(cls, names: list[str], hands: list[str] | str) -> HandLayout:
        """Layout from feature names holding `<side>_<udhm joint>` blocks; `hands` is one name or one per block."""
        names = list(names)
        blocks = find_udhm_blocks(names)
        if not blocks:
            raise ValueError(
                f"none of the {len(names)} state names is a '<side>_<udhm joint>' UDHM column (e.g. "
                f"{names[:3]}...): is this a dataset written by unidextok-convert?"
            )
        hands = [hands] * len(blocks) if isinstance(hands, str) else list(hands)
        if len(hands) != len(blocks):
            raise ValueError(f"{len(hands)} hand names for {len(blocks)} UDHM blocks ({[b.side for b in blocks]})")
        return cls(hands=hands, sides=[b.side for b in blocks], state_names=names)


def names_summary(names: list[str], head: int = 2) -> str:
    """`a, b, ..., z` for long name lists (error messages): the first `head` names and the last."""
    names = list(names)
    return ", ".join(names) if len(names) <= head + 2 else f"{', '.join(names[:head])}, ..., {names[-1]}"


@dataclass
class NativeLayout:
    """Converted vector (passthrough + UDHM blocks, `names`) <-> the robot's native vector (`native_names`).

    `hands`: one `{"side", "hand", "columns"}` per UDHM block; `columns` are the native names that
    `hands.get(hand).from_udhm(block, side)` fills, in that order. Every other native name must be a
    passthrough column of `names` and is copied unchanged. `mapping` is the converter's native -> UDHM
    mapping ("semantic", or the "append_pad" ablation), recorded in `meta/unidextok_conversion.json`.

    A robot bound into a mix of robots (`unidextok-deploy`) may have fewer hands than the mix has blocks
    (`absent_sides`: blocks that stay zero on the way in and are not decoded on the way out), and a robot's
    vector may hold columns the converted one does not carry (`dropped`: read past on the way in, zero on the
    way out; a hand that was never recorded, or the arms of a hands-only mix).
    """

    names: list[str]
    native_names: list[str]
    hands: list[dict[str, Any]]
    mapping: str = "semantic"
    # hands-only conversions (`--keep=hands`): every column name of the robot's full source vector, in its order
    # (where the native `native_names`, the hand columns, sit in it); [] = the native vector is the full one
    source_names: list[str] = field(default_factory=list)
    source_key: str | None = None  # the source feature of this vector when not the converted key (Dexora `states`)
    absent_sides: list[str] = field(default_factory=list)  # blocks that hold no hand of this robot: zeros
    dropped: list[str] = field(default_factory=list)  # native columns the converted vector does not carry

    def __post_init__(self) -> None:
        self.names, self.native_names = list(self.names), list(self.native_names)
        self.source_names, self.absent_sides, self.dropped = (
            list(self.source_names), list(self.absent_sides), list(self.dropped)
        )  # fmt: skip
        self.hands = [dict(h, columns=list(h["columns"])) for h in self.hands]
        blocks = {b.side: b for b in find_udhm_blocks(self.names)}
        native_index = {n: i for i, n in enumerate(self.native_names)}
        pass_names = [self.names[i] for i in passthrough_indices(self.names)]
        hand_columns = {c for h in self.hands for c in h["columns"]}
        self._decoders = []  # (spec, side, block slice, native indices)
        for h in self.hands:
            spec = _hand_spec(h["hand"])
            if h["side"] not in blocks:
                raise ValueError(f"native layout names a {h['side']} hand, but the vector has blocks {sorted(blocks)}")
            missing = [c for c in h["columns"] if c not in native_index]
            if missing or len(h["columns"]) != spec.num_native:
                raise ValueError(
                    f"native columns of the {h['side']} {h['hand']} ({len(h['columns'])}) must be {spec.num_native} "
                    f"names of the native vector; missing: {missing}"
                )
            self._decoders.append((spec, h["side"], blocks[h["side"]].slice, [native_index[c] for c in h["columns"]]))
        stray = [n for n in self.dropped if n not in native_index or n in hand_columns or n in pass_names]
        if stray:
            raise ValueError(f"dropped columns {stray[:5]} must be native columns that are neither hand nor passthrough")
        copy = [n for n in self.native_names if n not in hand_columns and n not in set(self.dropped)]
        unknown = [n for n in copy if n not in pass_names]
        if unknown:
            raise ValueError(f"native columns {unknown[:5]} are neither a hand column nor a passthrough column")
        self._copy_src = np.array([self.names.index(n) for n in copy], dtype=np.int64)
        self._copy_dst = np.array([native_index[n] for n in copy], dtype=np.int64)
        # the inverse needs every converted column: each block from a hand, each passthrough from a native name
        covered = {h["side"] for h in self.hands}
        both = covered & set(self.absent_sides)
        if both or not set(self.absent_sides) <= set(blocks):
            raise ValueError(f"absent_sides {self.absent_sides} must be blocks of the vector without a hand entry")
        covered |= set(self.absent_sides)
        self._absent = [blocks[s].slice for s in self.absent_sides]
        self._inverse_gaps = [f"the {s} UDHM block has no hand entry" for s in blocks if s not in covered] + [
            f"passthrough column {n!r} is not a native name" for n in pass_names if n not in native_index
        ]

    @property
    def native_dim(self) -> int:
        return len(self.native_names)

    @property
    def converted_dim(self) -> int:
        return len(self.names)

    @property
    def invertible(self) -> bool:
        """Whether `to_converted` can rebuild every converted column from the native vector."""
        return not self._inverse_gaps

    def describe_native(self) -> str:
        """`26 columns: kLeftShoulderPitch, ..., kRightWristYaw (14 passthrough), left inspire_rh56_unitree
        kLeftHandPinky, ..., kLeftHandThumbRotation (6), ...`: the native layout in one line, vector order."""
        hand_of = {c: h for h in self.hands for c in h["columns"]}
        runs: list[tuple[dict | None, list[str]]] = []  # consecutive columns of one hand (or passthrough)
        for n in self.native_names:
            owner = hand_of.get(n)
            if runs and runs[-1][0] is owner:
                runs[-1][1].append(n)
            else:
                runs.append((owner, [n]))
        parts = [
            f"{names_summary(cols)} ({len(cols)} passthrough)"
            if owner is None
            else f"{owner['side']} {owner['hand']} {names_summary(cols)} ({len(cols)})"
            for owner, cols in runs
        ]
        return f"{self.native_dim} columns: {'; '.join(parts)}"

    def describe_converted(self) -> str:
        """`58 columns: 14 passthrough + 2 UDHM blocks (left, right)`."""
        blocks = find_udhm_blocks(self.names)
        return (
            f"{self.converted_dim} columns: {self.converted_dim - UDHM_DIM * len(blocks)} passthrough + "
            f"{len(blocks)} UDHM block{'s' * (len(blocks) != 1)} ({', '.join(b.side for b in blocks)})"
        )

    def to_native(self, x: np.ndarray) -> np.ndarray:
        """(..., len(names)) converted values -> (..., len(native_names)) native values (float64)."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1] != len(self.names):
            raise ValueError(f"expected a vector of width {len(self.names)} (converted action), got {x.shape}")
        out = np.zeros((*x.shape[:-1], self.native_dim), dtype=np.float64)  # dropped columns stay zero
        out[..., self._copy_dst] = x[..., self._copy_src]
        for spec, side, block, dst in self._decoders:
            out[..., dst] = np.asarray(spec.from_udhm(x[..., block], side, mapping=self.mapping))
        return out

    def to_converted(self, native: Any, on_out_of_range: str = "raise") -> Any:
        """(..., len(native_names)) native values -> (..., len(names)) converted values, the inverse of
        `to_native`: passthrough columns copied by name, each hand's native columns through
        `hands.get(hand).to_udhm(values, side, mapping)` into its UDHM block (zero on slots the hand lacks).

        A torch tensor stays a tensor (dtype and device kept); anything else becomes a float64 numpy array.
        `on_out_of_range`: native hand values outside their range "raise" (as the converter does) or "clip".
        """
        if self._inverse_gaps:
            raise ValueError(f"this native layout cannot rebuild the converted vector: {'; '.join(self._inverse_gaps)}")
        is_torch = type(native).__module__.startswith("torch")
        if is_torch:
            import torch  # only for tensor input: `unidextok-convert --help` imports this module without torch

        x = (native if native.is_floating_point() else native.float()) if is_torch else np.asarray(native, np.float64)
        if x.shape[-1] != self.native_dim:
            raise ValueError(f"expected a vector of width {self.native_dim} (native layout), got {tuple(x.shape)}")
        lead = tuple(x.shape[:-1])
        if is_torch:
            out = torch.zeros((*lead, self.converted_dim), dtype=x.dtype, device=x.device)
            src = torch.as_tensor(self._copy_dst, device=x.device)
            dst = torch.as_tensor(self._copy_src, device=x.device)
        else:
            out, src, dst = np.zeros((*lead, self.converted_dim)), self._copy_dst, self._copy_src
        out[..., dst] = x[..., src]
        for spec, side, block, columns in self._decoders:
            idx = torch.as_tensor(columns, device=x.device) if is_torch else np.asarray(columns)
            out[..., block] = spec.to_udhm(x[..., idx], side, mapping=self.mapping, on_out_of_range=on_out_of_range)
        return out

    def to_dict(self) -> dict[str, Any]:
        """The layout's one schema (JSON): `NativeLayout.from_dict(layout.to_dict()) == layout`."""
        out = {"names": self.names, "native_names": self.native_names, "hands": self.hands, "mapping": self.mapping}
        if self.source_names:
            out["source_names"] = self.source_names
        if self.source_key is not None:
            out["source_key"] = self.source_key
        if self.absent_sides:
            out["absent_sides"] = self.absent_sides
        if self.dropped:
            out["dropped"] = self.dropped
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NativeLayout:
        """A layout from `to_dict()`'s schema; a ValueError naming unknown or missing keys."""
        known = {"names", "native_names", "hands", "mapping", "source_names", "source_key", "absent_sides", "dropped"}
        unknown, missing = sorted(set(data) - known), sorted({"names", "native_names", "hands"} - set(data))
        if unknown or missing:
            raise ValueError(f"a native layout has the keys {sorted(known)}; got unknown {unknown}, missing {missing}")
        return cls(**data)

    @classmethod
    def from_hands(
        cls, hands: list[str], sides: list[str], names: list[str] | None = None, mapping: str = "semantic"
    ) -> NativeLayout:
        """Native = passthrough columns of `names` then each hand's native joints (`<side>_<joint>`), block order."""
        names = list(names) if names else udhm_state_names(sides)
        entries = [
            {"side": s, "hand": h, "columns": [f"{s}_{j}" for j in _hand_spec(h).joint_names]}
            for h, s in zip(hands, sides, strict=True)
        ]
        native = [names[i] for i in passthrough_indices(names)] + [c for e in entries for c in e["columns"]]
        return cls(names=names, native_names=native, hands=entries, mapping=mapping)
