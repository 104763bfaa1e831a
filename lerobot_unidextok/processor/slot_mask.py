"""Which action slots a row's hand lacks, for a loss that does not train them (`unidextok.slot_mask`).

A UDHM block has 22 slots; an Inspire has 6 of them, a LinkerHand L10 10. The slots a hand lacks hold zero in its
rows (the dataset's `udhm_mask` is false there), and a stock loss trains the policy to predict those zeros, for
joints the hand does not have. This pre-processor step writes, for each training batch, a (B, A) bool
`action_slot_is_pad` into the batch (LeRobot's complementary data, beside `action_is_pad`): true on every action
slot the row's hand lacks and on every slot of a block without a hand (id -1); false on the hands' own slots and on
the passthrough columns. The `<type>_udt` policies (ACT, Diffusion) leave those entries out of their loss.

A row's hands come from `observation.hand_ids` (a mix) or `fixed_hand_ids` (one robot); which slots a hand has
from its spec (`hands.get(name).active_mask`), the mask the converters write as `udhm_mask` for a present hand
(LeRobot's batch conversion keeps only `observation.*`, `action*`, `*_is_pad` and a few named keys, so the
dataset's own `udhm_mask` column never reaches a processor step or the policy). Without an action (inference)
the step writes no mask.

A hand the policy never trained on (`extra_hands`, after the vocabulary: `unidextok-deploy --zero_shot=true`)
can have slots that none of the trained hands has. Every training row held 0 there, and LeRobot's statistics of
such a column have std 0, so its normaliser divides the new hand's angle by 1e-8. For that hand's blocks the step
holds those state slots at 0, the value the policy learnt with (the input side of the mask); a trained hand's
rows are left as they are. `extra_hand_slots` can narrow what a zero-shot hand drives further (`unidextok-deploy
--zero_shot_slots=nearest`: the slots of the trained hand nearest it in morphology): its other slots are held at
0 too, as in the rows of that trained hand, which lacks them (the hand normaliser commands them 0).
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
from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import OBS_HAND_IDS, OBS_STATE, UDHM_DIM
from lerobot_unidextok.processor.hand_rows import driven_slot_masks

SLOT_MASK_STEP_NAME = "unidextok.slot_mask"
ACTION_SLOT_PAD_KEY = "action_slot_is_pad"  # (B, A) bool in the batch: true = no loss on that action slot


@ProcessorStepRegistry.register(SLOT_MASK_STEP_NAME)
@dataclass
class SlotMaskStep(ProcessorStep):
    """Write `action_slot_is_pad` (B, A): the action slots each row's hand lacks (module docstring)."""

    state_names: list[str] = field(default_factory=list)  # the blocks the hand ids describe
    action_names: list[str] = field(default_factory=list)
    hand_vocabulary: list[str] = field(default_factory=list)
    fixed_hand_ids: list[int] = field(default_factory=list)  # one robot's hand per block ([] = per row)
    hand_ids_key: str = OBS_HAND_IDS
    # the vocabulary's last hands, never trained on (zero-shot): their state slots no trained hand has held at 0
    extra_hands: list[str] = field(default_factory=list)
    # per zero-shot hand, the UDHM slots (0..21) it drives (absent: every slot of its own); its others held at 0
    extra_hand_slots: dict[str, list[int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._state_blocks = find_udhm_blocks(self.state_names)
        self._sides = [b.side for b in self._state_blocks]
        self._blocks = find_udhm_blocks(self.action_names)
        if not self._sides or not self._blocks or not self.hand_vocabulary:
            raise ValueError(f"{SLOT_MASK_STEP_NAME} needs state and action names with UDHM blocks and the hands")
        self.fixed_hand_ids = [int(i) for i in self.fixed_hand_ids]
        if self.fixed_hand_ids and len(self.fixed_hand_ids) != len(self._sides):
            raise ValueError(f"{SLOT_MASK_STEP_NAME}: fixed_hand_ids {self.fixed_hand_ids} must give one hand per "
                             f"block {self._sides}")  # fmt: skip
        active = np.stack([hands.get(h).active_mask for h in self.hand_vocabulary] + [np.zeros(UDHM_DIM, bool)])
        self._lacks = ~torch.as_tensor(active)  # (V + 1, 22): row V = no hand, every slot lacking
        self.extra_hands = list(self.extra_hands)
        self._first_extra = len(self.hand_vocabulary) - len(self.extra_hands)
        if self._first_extra < 0 or self.hand_vocabulary[self._first_extra :] != self.extra_hands:
            raise ValueError(f"{SLOT_MASK_STEP_NAME}: extra_hands {self.extra_hands} must end hand_vocabulary "
                             f"{self.hand_vocabulary}")  # fmt: skip
        untrained = ~active[: self._first_extra].any(axis=0)  # (22,) slots no trained hand has
        driven = driven_slot_masks(self.extra_hand_slots, self.extra_hands, SLOT_MASK_STEP_NAME)
        self.extra_hand_slots = {h: [int(i) for i in np.flatnonzero(m)] for h, m in driven.items()}
        hold = np.zeros((len(self.hand_vocabulary) + 1, UDHM_DIM), bool)  # (V + 1, 22): the last row, no hand
        for i, name in enumerate(self.extra_hands, start=self._first_extra):
            hold[i] = untrained | ~driven.get(name, np.ones(UDHM_DIM, bool))
        self._hold = torch.as_tensor(hold)

    def pad_mask(self, ids: torch.Tensor, batch: int) -> torch.Tensor:
        """(batch, A) bool from (R, H) hand ids (R = batch, or 1 for a robot's fixed hands)."""
        ids = ids.reshape(-1, len(self._sides))
        if ids.shape[0] not in (1, batch):  # (B * n_obs) rows of a multi-step observation: the last step's hands
            ids = ids.reshape(batch, -1, len(self._sides))[:, -1]
        ids = ids.expand(batch, -1)
        index = torch.where(ids < 0, len(self.hand_vocabulary), ids)
        mask = torch.zeros(batch, len(self.action_names), dtype=torch.bool)
        for b in self._blocks:
            mask[:, b.slice] = self._lacks[index[:, self._sides.index(b.side)].cpu()]
        return mask

    def held_state(self, state: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
        """`state` (..., D) with the slots no trained hand has (and those an extra hand does not drive,
        `extra_hand_slots`) at 0 in every block an extra hand holds; `ids` (R, H) hand ids, R = 1 (fixed) or the
        rows of `state` flattened over its leading dimensions."""
        rows = state.reshape(-1, state.shape[-1])
        ids = ids.reshape(-1, len(self._sides))
        ids = ids.expand(rows.shape[0], -1) if ids.shape[0] == 1 else ids
        out = rows.clone()
        for block in self._state_blocks:
            hand = ids[:, self._sides.index(block.side)]  # (R,)
            hold = self._hold[torch.where(hand < 0, len(self.hand_vocabulary), hand).cpu()].to(rows.device)  # (R, 22)
            out[:, block.slice] = torch.where(hold, torch.zeros((), dtype=rows.dtype, device=rows.device),
                                              rows[:, block.slice])  # fmt: skip
        return out.reshape(state.shape)

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        action = transition.get(TransitionKey.ACTION)
        observation = transition.get(TransitionKey.OBSERVATION) or {}
        if action is None and not (self.extra_hands and OBS_STATE in observation):
            return transition
        ids = observation.get(self.hand_ids_key)
        if ids is None:
            if not self.fixed_hand_ids:
                raise KeyError(f"{SLOT_MASK_STEP_NAME} needs '{self.hand_ids_key}' in a training batch of a mix")
            ids = torch.tensor(self.fixed_hand_ids)
        ids = torch.as_tensor(ids).long()
        new = transition.copy()
        if self.extra_hands and OBS_STATE in observation:
            state = torch.as_tensor(observation[OBS_STATE])
            new[TransitionKey.OBSERVATION] = {**observation, OBS_STATE: self.held_state(state, ids)}
        if action is None:
            return new
        action = torch.as_tensor(action)
        batch = action.shape[0] if action.ndim > 1 else 1
        mask = self.pad_mask(ids, batch).to(action.device)
        new[TransitionKey.COMPLEMENTARY_DATA] = {**(transition.get(TransitionKey.COMPLEMENTARY_DATA) or {}),
                                                 ACTION_SLOT_PAD_KEY: mask if action.ndim > 1 else mask[0]}  # fmt: skip
        return new

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {
            "state_names": list(self.state_names),
            "action_names": list(self.action_names),
            "hand_vocabulary": list(self.hand_vocabulary),
            "fixed_hand_ids": list(self.fixed_hand_ids),
            "hand_ids_key": self.hand_ids_key,
            "extra_hands": list(self.extra_hands),
            "extra_hand_slots": {h: list(slots) for h, slots in self.extra_hand_slots.items()},
        }


__all__ = ["ACTION_SLOT_PAD_KEY", "SLOT_MASK_STEP_NAME", "SlotMaskStep"]
