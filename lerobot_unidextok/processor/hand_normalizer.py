"""Per-hand normalisation of a `<type>_udt` policy's state and actions: each UDHM block of each row with the
statistics of the hand it holds there (`unidextok.hand_normalizer`).

LeRobot's normaliser keeps one set of statistics per feature. In a mix a block holds a different hand in
different rows: the slots a hand lacks are zero in its rows, which halves those columns' std for the hands that
have them, and one hand's range sets another's scale. So, before LeRobot's normaliser (which is then IDENTITY for
`observation.state` and `action`) and after its unnormaliser, this step does their normalisation itself:

- each UDHM block of each row with the statistics of that block's hand (`conversion/hand_stats.py`: per block
  side and hand, over the training frames where the block holds that hand), selected per row by
  `observation.hand_ids` (a mix) or `fixed_hand_ids` (one robot, or a mix bound to one by `unidextok-deploy`);
- the passthrough columns (arms, wrist, task columns) with their own statistics (LeRobot's dataset statistics of
  those columns), as LeRobot would;
- in LeRobot's modes: MEAN_STD `(x - mean) / std`, MIN_MAX / QUANTILES / QUANTILE10 `2 (x - lo) / (hi - lo) - 1`
  (lo, hi = min/max, q01/q99, q10/q90). A column that never varies (std or range at most 1e-6) is normalised by 1
  and unnormalised to its center whatever the prediction, as LeRobot's MEAN_STD does with a zero std;
- relative actions (after LeRobot's RelativeActionsProcessorStep, `relative_actions`): the blocks' offsets are
  scaled, not shifted (MEAN_STD by their root mean square, range modes by max(|lo|, |hi|)), so an output of zero
  still means "hold the state" (`udt_copy_start`); the passthrough offsets pass unscaled (LeRobot's IDENTITY);
- `unnormalize` also sets the action slots the row's hand lacks (and a block without a hand) to 0: the policy is
  not trained on them (`action_slot_is_pad`, `slot_mask.py`), so its output there means nothing.

A hand without statistics (a zero-shot hand bound by `unidextok-deploy --zero_shot=true`, `extra_hands`) is
normalised per slot with the pooled statistics of the known hands that have that slot (MEAN_STD: the pooled mean
and std over their frames; range modes: the lowest low and highest high); a slot no known hand has passes
unscaled. A block without a hand (id -1) passes unscaled. `extra_hand_slots` narrows the slots such a hand drives
(`unidextok-deploy --zero_shot_slots=nearest`): `unnormalize` sets its others to 0 as it does the slots it lacks
(with relative actions an offset of 0).

The statistics are checked where they enter (`utils/number_checks.py`: finite, a std and frames >= 0, every hand
of the vocabulary with statistics and no other), when the step is built and in `load_state_dict`, so a damaged
checkpoint is one error naming the tensor, not a policy that never moves a hand. They are the step's state
(`state_dict`: per key, the two statistics of its mode per block, hand and
slot, the frames per block and hand, and the passthrough columns' two statistics), so they are saved with the
policy's processors and reloaded bit-exactly; `get_config` holds the layout and the modes. The post step of an
unbound mix checkpoint reads the hand ids its paired pre step saw last (`pair`); reloaded unbound it has neither
and says to bind the checkpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor import ProcessorStep, ProcessorStepRegistry

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import find_udhm_blocks, passthrough_indices
from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE, UDHM_DIM
from lerobot_unidextok.processor.hand_rows import driven_slot_masks, match_rows, row_hand_ids
from lerobot_unidextok.utils.number_checks import MAX_STAT_RAD, NumberError, checked_hand_stats, checked_tensor

HAND_NORMALIZER_STEP_NAME = "unidextok.hand_normalizer"
MODES = ("normalize", "unnormalize")
# LeRobot's normalisation modes and the two statistics each reads
STATS_OF_MODE = {"MEAN_STD": ("mean", "std"), "MIN_MAX": ("min", "max"), "QUANTILES": ("q01", "q99"),
                 "QUANTILE10": ("q10", "q90")}  # fmt: skip
KEYS = (OBS_STATE, ACTION)
# a column whose std / half range is at most this never varies in the data: normalised by 1 (x - center), and
# unnormalised to its center whatever the policy predicts (as LeRobot's MEAN_STD does with std 0: a prediction's
# noise on a constant column, e.g. a wrist roll the demonstrations never moved, would otherwise become a real
# command, and a state column of tiny std then reads it 1000s of stds away)
MIN_SPREAD = 1e-6


def _pooled(mode: str, lo: torch.Tensor, hi: torch.Tensor, frames: torch.Tensor, has: torch.Tensor):
    """Per slot, the statistics pooled over the hands that have it. lo, hi: (V, 22); frames: (V,); has: (V, 22)
    bool. -> (22,), (22,) and a (22,) bool: some known hand has the slot."""
    weight = frames[:, None].double() * has  # (V, 22)
    total = weight.sum(0)
    known = total > 0
    if mode == "MEAN_STD":
        mean = (weight * lo).sum(0) / total.clamp_min(1)
        second = (weight * (hi.double() ** 2 + lo.double() ** 2)).sum(0) / total.clamp_min(1)
        return mean.float(), (second - mean**2).clamp_min(0).sqrt().float(), known
    big = torch.finfo(torch.float32).max
    low = torch.where(has, lo, torch.full_like(lo, big)).min(0).values
    high = torch.where(has, hi, torch.full_like(hi, -big)).max(0).values
    return low, high, known


@ProcessorStepRegistry.register(HAND_NORMALIZER_STEP_NAME)
@dataclass
class HandNormalizerStep(ProcessorStep):
    """`normalize` (pre) or `unnormalize` (post) `observation.state` and `action` with per-hand statistics for
    their UDHM blocks and the dataset's for their passthrough columns (module docstring)."""

    mode: str = "normalize"
    # LeRobot mode per key ("observation.state", "action"): MEAN_STD | MIN_MAX | QUANTILES | QUANTILE10; a key
    # absent here is left to LeRobot's normaliser
    modes: dict[str, str] = field(default_factory=dict)
    state_names: list[str] = field(default_factory=list)  # the converted state's columns (they locate the blocks)
    action_names: list[str] = field(default_factory=list)  # the action's columns
    hand_vocabulary: list[str] = field(default_factory=list)  # what the hand ids index (with statistics)
    extra_hands: list[str] = field(default_factory=list)  # ids after the vocabulary: zero-shot, pooled statistics
    # per zero-shot hand, the UDHM slots (0..21) it drives (absent: every slot of its own); unnormalize commands
    # its other slots 0 (`unidextok-deploy --zero_shot_slots=nearest`, `slot_mask.py`)
    extra_hand_slots: dict[str, list[int]] = field(default_factory=dict)
    fixed_hand_ids: list[int] = field(default_factory=list)  # the hand per state block ([] = per row)
    relative_actions: bool = False  # the action is an offset from the state (scaled, not shifted)
    hand_ids_key: str = OBS_HAND_IDS
    # per key: {side: {hand: {<the mode's two statistics>: [22], "frames": n}}}; read when the step is built,
    # then held as tensors (state_dict), not in get_config
    stats: dict[str, dict[str, dict[str, dict[str, Any]]]] = field(default_factory=dict, repr=False)
    # per key: {<statistic>: [per column]} of the dataset (LeRobot's): their passthrough columns are used
    dataset_stats: dict[str, dict[str, Any]] = field(default_factory=dict, repr=False)
    pair: HandNormalizerStep | None = field(default=None, repr=False)  # post: the pre step whose hand ids it reuses

    _last_ids: torch.Tensor | None = field(default=None, init=False, repr=False)
    _tensors: dict[str, torch.Tensor] = field(default_factory=dict, init=False, repr=False)
    _cache: dict[tuple[str, str], tuple] = field(default_factory=dict, init=False, repr=False)  # (key, device)

    def __post_init__(self) -> None:
        name = HAND_NORMALIZER_STEP_NAME
        if self.mode not in MODES:
            raise ValueError(f"{name}: mode must be one of {MODES}, got {self.mode!r}")
        bad = {k: m for k, m in self.modes.items() if k not in KEYS or m not in STATS_OF_MODE}
        if bad:
            raise ValueError(f"{name}: modes {bad}: keys must be {KEYS}, modes {tuple(STATS_OF_MODE)}")
        self.hand_vocabulary, self.extra_hands = list(self.hand_vocabulary), list(self.extra_hands)
        self.fixed_hand_ids = [int(i) for i in self.fixed_hand_ids]
        self._sides = [b.side for b in find_udhm_blocks(self.state_names)]
        if not self._sides or not self.hand_vocabulary:
            raise ValueError(f"{name} needs state_names with UDHM blocks and the hand_vocabulary")
        if self.fixed_hand_ids and len(self.fixed_hand_ids) != len(self._sides):
            raise ValueError(f"{name}: fixed_hand_ids {self.fixed_hand_ids} must give one hand per block {self._sides}")
        names = self.hand_names
        active = np.stack([hands.get(h).active_mask for h in names])  # (V + E, 22)
        driven = driven_slot_masks(self.extra_hand_slots, self.extra_hands, name)
        self.extra_hand_slots = {h: [int(i) for i in np.flatnonzero(m)] for h, m in driven.items()}
        for h, mask in driven.items():
            active[names.index(h)] &= mask
        self._active = torch.as_tensor(active)
        fix = "compute them again (lerobot-train fills udt_hand_stats from the dataset)"
        for key in self.modes:
            if self.stats.get(key):
                self.stats[key] = checked_hand_stats({key: self.stats[key]}, f"{name} stats", fix=fix,
                                                     hands=self.hand_vocabulary, sides=self._sides,
                                                     required=STATS_OF_MODE[self.modes[key]])[key]  # fmt: skip
            self._build(key)
        # a post step is built without stats and loads its pre step's (`load_state_dict` checks every hand's)
        self._check_tensors(self._tensors, f"{name}: the statistics built from stats / dataset_stats", fix, False)

    # ----------------------------------------------------------------------------------------- statistics
    @property
    def hand_names(self) -> list[str]:
        return [*self.hand_vocabulary, *self.extra_hands]

    def _names(self, key: str) -> list[str]:
        return self.state_names if key == OBS_STATE else self.action_names

    def _build(self, key: str) -> None:
        """The key's tensors from `stats` / `dataset_stats` (identity where none are given)."""
        lo_name, hi_name = STATS_OF_MODE[self.modes[key]]
        names = self._names(key)
        blocks = find_udhm_blocks(names)
        unknown = sorted({b.side for b in blocks} - set(self._sides))
        if unknown:
            raise ValueError(f"{HAND_NORMALIZER_STEP_NAME}: {key} has blocks {unknown} the state {self._sides} lacks")
        num = len(self.hand_vocabulary)
        lo, hi = self._identity(key, (len(blocks), num, UDHM_DIM))
        frames = torch.zeros(len(blocks), num)
        given = self.stats.get(key, {})
        for j, block in enumerate(blocks):
            for v, hand in enumerate(self.hand_vocabulary):
                entry = given.get(block.side, {}).get(hand)
                if entry is not None:
                    lo[j, v] = torch.tensor(entry[lo_name], dtype=torch.float32)
                    hi[j, v] = torch.tensor(entry[hi_name], dtype=torch.float32)
                    frames[j, v] = float(entry.get("frames", 1))
        columns = list(passthrough_indices(names))
        plo, phi = self._identity(key, (len(columns),))
        own = self.dataset_stats.get(key) or {}
        if columns and lo_name in own and hi_name in own and not (key == ACTION and self.relative_actions):
            plo = torch.as_tensor(np.asarray(own[lo_name], dtype=np.float32).reshape(-1)[columns])
            phi = torch.as_tensor(np.asarray(own[hi_name], dtype=np.float32).reshape(-1)[columns])
        self._tensors.update({f"{key}.{lo_name}": lo, f"{key}.{hi_name}": hi, f"{key}.frames": frames,
                              f"{key}.passthrough.{lo_name}": plo, f"{key}.passthrough.{hi_name}": phi})  # fmt: skip

    def _identity(self, key: str, shape: tuple[int, ...]) -> tuple[torch.Tensor, torch.Tensor]:
        """The two statistics that make the mode the identity (center 0, scale 1)."""
        if self.modes[key] == "MEAN_STD":
            return torch.zeros(shape), torch.ones(shape)
        return -torch.ones(shape), torch.ones(shape)

    def _center_scale(self, key: str, lo: torch.Tensor, hi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The affine map x -> (x - center) / scale of the mode's two statistics."""
        relative = key == ACTION and self.relative_actions
        if self.modes[key] == "MEAN_STD":
            center, scale = lo, hi
            if relative:
                center, scale = torch.zeros_like(lo), (lo**2 + hi**2).sqrt()
        else:
            center, scale = (lo + hi) / 2, (hi - lo) / 2
            if relative:
                center, scale = torch.zeros_like(lo), torch.maximum(lo.abs(), hi.abs())
        return center, torch.where(scale > MIN_SPREAD, scale, torch.zeros_like(scale))  # 0: a constant column

    def _block_tables(self, key: str) -> tuple[torch.Tensor, torch.Tensor]:
        """(blocks, V + E + 1, 22) center and scale: the vocabulary's, the zero-shot hands' (pooled), identity."""
        lo_name, hi_name = STATS_OF_MODE[self.modes[key]]
        lo, hi, frames = (self._tensors[f"{key}.{s}"] for s in (lo_name, hi_name, "frames"))
        blocks, num = lo.shape[0], len(self.hand_vocabulary)
        extra = len(self.extra_hands)
        id_lo, id_hi = self._identity(key, (blocks, extra + 1, UDHM_DIM))
        lo, hi = torch.cat([lo, id_lo], 1), torch.cat([hi, id_hi], 1)
        for j in range(blocks):
            if not extra:
                break
            has = self._active[:num] & (frames[j] > 0)[:, None]
            plo, phi, known = _pooled(self.modes[key], lo[j, :num], hi[j, :num], frames[j], has)
            for e in range(extra):
                lo[j, num + e] = torch.where(known, plo, id_lo[j, 0])
                hi[j, num + e] = torch.where(known, phi, id_hi[j, 0])
        return self._center_scale(key, lo, hi)

    # ----------------------------------------------------------------------------------------- hands per row
    def _ids(self, observation: dict[str, Any] | None) -> torch.Tensor:
        """(R, H) hand index per state block: the observation's, the bound robot's, or the pair's last."""
        last = self.pair._last_ids if self.mode == "unnormalize" and self.pair is not None else None
        ids = row_hand_ids(observation, self.hand_ids_key, self.fixed_hand_ids, last, len(self._sides),
            f"{HAND_NORMALIZER_STEP_NAME} ({self.mode}) needs each block's hand ('{self.hand_ids_key}'): this "
            "policy was trained on a mix of hands, normalised per hand. Bind it to your robot with "
            "`unidextok-deploy --checkpoint=... --robot=<its converted dataset> --output=...`")  # fmt: skip
        if bool(((ids < -1) | (ids >= len(self.hand_names))).any()):
            raise ValueError(f"{self.hand_ids_key} holds {sorted(set(ids.unique().tolist()))}, outside -1 .. "
                             f"{len(self.hand_names) - 1} (hands {self.hand_names})")  # fmt: skip
        return ids

    def _apply(self, key: str, x: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
        names = self._names(key)
        if x.shape[-1] != len(names):
            raise ValueError(f"{HAND_NORMALIZER_STEP_NAME}: {key} is {x.shape[-1]} wide, expected {len(names)} "
                             f"({len(find_udhm_blocks(names))} UDHM blocks and the passthrough columns)")  # fmt: skip
        lead = tuple(x.shape[:-1])
        ids, view = match_rows(ids, lead, HAND_NORMALIZER_STEP_NAME)
        ids = ids.to(x.device)
        blocks = find_udhm_blocks(names)
        block_of_state = torch.tensor([self._sides.index(b.side) for b in blocks], device=x.device)
        hand = ids[:, block_of_state]  # (R, blocks of this key)
        none = len(self.hand_names)  # the identity row
        index = torch.where(hand < 0, none, hand)
        cached = self._cache.get((key, str(x.device)))
        if cached is None:  # the tables change only with the statistics (load_state_dict clears this)
            cached = self._cache[(key, str(x.device))] = tuple(t.to(x.device) for t in self._block_tables(key))
        center_t, scale_t = cached  # (blocks, V + E + 1, 22)
        at = torch.arange(len(blocks), device=x.device)
        center_b, scale_b = center_t[at, index], scale_t[at, index]  # (R, blocks, 22)
        lo_name, hi_name = STATS_OF_MODE[self.modes[key]]
        pc, ps = self._center_scale(key, self._tensors[f"{key}.passthrough.{lo_name}"],
                                    self._tensors[f"{key}.passthrough.{hi_name}"])  # fmt: skip
        rows = hand.shape[0]
        center = torch.zeros(rows, len(names), device=x.device)
        scale = torch.ones(rows, len(names), device=x.device)
        columns = list(passthrough_indices(names))
        if columns:
            center[:, columns], scale[:, columns] = pc.to(x.device), ps.to(x.device)
        for j, b in enumerate(blocks):
            center[:, b.slice], scale[:, b.slice] = center_b[:, j], scale_b[:, j]
        center, scale = center.reshape(*view, len(names)), scale.reshape(*view, len(names))
        if self.mode == "normalize":
            return (x - center) / torch.where(scale > 0, scale, torch.ones_like(scale))
        out = x * scale + center  # a constant column (scale 0): its center
        if key == ACTION:  # the slots the row's hand lacks (and absent blocks): 0, they were never trained
            active = torch.cat([self._active, torch.zeros(1, UDHM_DIM, dtype=torch.bool)]).to(x.device)
            keep = torch.ones(rows, len(names), dtype=torch.bool, device=x.device)
            for j, b in enumerate(blocks):
                keep[:, b.slice] = active[index[:, j]]
            out = torch.where(keep.reshape(*view, len(names)), out, torch.zeros_like(out))
        return out

    # ----------------------------------------------------------------------------------------- the step
    def __call__(self, transition: EnvTransition) -> EnvTransition:
        observation = transition.get(TransitionKey.OBSERVATION) or {}
        action = transition.get(TransitionKey.ACTION)
        new = transition.copy()
        ids = None
        if self.mode == "normalize":
            state = observation.get(OBS_STATE)
            if state is not None or action is not None:
                ids = self._ids(observation)
                self._last_ids = ids
            if state is not None and OBS_STATE in self.modes:
                observation = dict(observation)
                observation[OBS_STATE] = self._apply(OBS_STATE, torch.as_tensor(state), ids)
                new[TransitionKey.OBSERVATION] = observation
        if action is not None and ACTION in self.modes:
            ids = ids if ids is not None else self._ids(observation)
            new[TransitionKey.ACTION] = self._apply(ACTION, torch.as_tensor(action), ids)
        return new

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "modes": dict(self.modes),
            "state_names": list(self.state_names),
            "action_names": list(self.action_names),
            "hand_vocabulary": list(self.hand_vocabulary),
            "extra_hands": list(self.extra_hands),
            "extra_hand_slots": {h: list(slots) for h, slots in self.extra_hand_slots.items()},
            "fixed_hand_ids": list(self.fixed_hand_ids),
            "relative_actions": self.relative_actions,
            "hand_ids_key": self.hand_ids_key,
        }

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {k: v.detach().cpu().contiguous() for k, v in self._tensors.items()}

    def _check_tensors(self, tensors: dict[str, torch.Tensor], where: str, fix: str, every_hand: bool = True) -> None:
        """Every statistic finite, each scale (std, frames) >= 0, and (`every_hand`) each hand of the vocabulary
        with frames in some block of each key (a hand without them would pass unnormalised): a NumberError naming
        the tensor."""
        for k in self._tensors:  # "<key>.<statistic>" of the blocks (rad), "<key>.passthrough.<statistic>", frames
            scale, block = k.endswith((".std", ".frames")), ".passthrough." not in k and not k.endswith(".frames")
            checked_tensor(tensors[k], f"{where}: tensor {k!r}", sign="non_negative" if scale else None, fix=fix,
                           max_abs=MAX_STAT_RAD if block else None, unit="rad" if block else "")  # fmt: skip
        for key in self.modes if every_hand else ():
            frames = tensors[f"{key}.frames"]  # (blocks, V)
            none = [h for v, h in enumerate(self.hand_vocabulary) if frames.shape[0] and not bool(frames[:, v].any())]
            if none:
                raise NumberError(f"{where}: tensor '{key}.frames' gives hands {none} no frames in any block: they "
                                  f"would pass unnormalised; {fix}")  # fmt: skip

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        missing = sorted(set(self._tensors) - set(state))
        if missing:
            raise KeyError(f"{HAND_NORMALIZER_STEP_NAME}: the saved statistics lack {missing[:3]}")
        for k, v in self._tensors.items():
            if tuple(state[k].shape) != tuple(v.shape):
                raise ValueError(f"{HAND_NORMALIZER_STEP_NAME}: saved {k} has shape {tuple(state[k].shape)}, "
                                 f"this step's layout {tuple(v.shape)}")  # fmt: skip
        self._check_tensors(state, f"{HAND_NORMALIZER_STEP_NAME}: the saved statistics",
                            "the checkpoint's processor file was edited or damaged: use the one lerobot-train saved "
                            "with it, or train again")  # fmt: skip
        for k in self._tensors:
            self._tensors[k] = state[k].clone().float()
        self._cache.clear()


__all__ = ["HAND_NORMALIZER_STEP_NAME", "STATS_OF_MODE", "HandNormalizerStep"]
