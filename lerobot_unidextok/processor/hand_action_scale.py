"""Relative hand actions scaled per hand, for a policy trained on a mix of robots and people (`unidextok-mix`).

With relative actions (`udt_relative_actions`) a policy predicts each action as an offset from the current
state. One hand's offsets are not another's: a G1's Inspire fingers move a few hundredths of a radian per
frame, a person's hand or a LinkerHand moving between presets many times that. Unscaled, the larger moves set
the loss and a few target episodes are drowned (the policy learns to hold still; `experiments/cross_embodiment.py`
measured it with one pooled scale). So each UDHM block of each row is z-scored with the statistics of the
hand it holds there:

    pre  (after LeRobot's RelativeActionsProcessorStep):  delta <- (delta - mean[side, hand]) / std[side, hand]
    post (before its AbsoluteActionsProcessorStep):       delta <- delta * std[side, hand] + mean[side, hand]

`stats` are the mix's own (`meta/unidextok_conversion.json` "action_delta_stats": per block side and hand,
mean and std of `action - state` over the training episodes, `conversion/mix.py`). A block without a hand
(`observation.hand_ids` -1) and the passthrough columns before the blocks pass unchanged; a slot a hand never
moves has std 1. A hand with no statistics (a zero-shot hand bound by `unidextok-deploy --zero_shot=true`) is
scaled with the block's mean std over the mix's hands.

The hands of each row come from `observation.hand_ids` (training batches) or from `fixed_hand_ids` (a
checkpoint bound to one robot by `unidextok-deploy`). The post step of an unbound checkpoint reads the hand
ids its paired pre step saw last (`pair`, set when the processors are built for training); reloaded unbound
it has neither and says to bind the checkpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor import ProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.constants import OBS_HAND_IDS, UDHM_DIM

HAND_ACTION_SCALE_STEP_NAME = "unidextok.hand_action_scale"
MODES = ("normalize", "unnormalize")
MIN_STD = 1e-6  # a slot whose offsets vary less than this never moves: std 1


@ProcessorStepRegistry.register(HAND_ACTION_SCALE_STEP_NAME)
@dataclass
class HandActionScaleStep(ProcessorStep):
    """Each UDHM block of a relative action z-scored (`normalize`) or restored (`unnormalize`) with the
    statistics of the hand that row's block holds. Actions (..., A): `action_offset` passthrough columns, then
    one 22-wide block per entry of `sides`."""

    mode: str = "normalize"
    sides: list[str] = field(default_factory=list)  # the blocks' sides, in the action's order
    hand_vocabulary: list[str] = field(default_factory=list)  # what `observation.hand_ids` indexes
    # {side: {hand: {"mean": [22], "std": [22], "frames": n}}}: the mix's action_delta_stats
    stats: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)
    action_offset: int = 0  # passthrough action columns before the first block (unscaled)
    fixed_hand_ids: list[int] = field(default_factory=list)  # a bound robot's hand per block ([] = per row)
    hand_ids_key: str = OBS_HAND_IDS
    pair: HandActionScaleStep | None = field(default=None, repr=False)  # post: the pre step whose ids it reuses

    _last_ids: torch.Tensor | None = field(default=None, init=False, repr=False)  # pre: (rows, H) last seen

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"{HAND_ACTION_SCALE_STEP_NAME}: mode must be one of {MODES}, got {self.mode!r}")
        unknown = sorted(set(self.stats) - set(self.sides))
        if unknown:
            raise ValueError(f"{HAND_ACTION_SCALE_STEP_NAME}: stats for sides {unknown} the blocks {self.sides} lack")
        if self.fixed_hand_ids and len(self.fixed_hand_ids) != len(self.sides):
            raise ValueError(
                f"{HAND_ACTION_SCALE_STEP_NAME}: fixed_hand_ids {self.fixed_hand_ids} must give one hand per block "
                f"({self.sides})"
            )
        self.fixed_hand_ids = [int(i) for i in self.fixed_hand_ids]
        # (H, V + 1, 22) tables; row V is the fallback for a hand without statistics (ids >= V), and an absent
        # block (-1) is never scaled
        num = len(self.hand_vocabulary)
        mean = torch.zeros(len(self.sides), num + 1, UDHM_DIM)
        std = torch.ones(len(self.sides), num + 1, UDHM_DIM)
        for k, side in enumerate(self.sides):
            known = self.stats.get(side, {})
            for v, hand in enumerate(self.hand_vocabulary):
                if hand in known:
                    mean[k, v] = torch.tensor(known[hand]["mean"], dtype=torch.float32)
                    s = torch.tensor(known[hand]["std"], dtype=torch.float32)
                    std[k, v] = torch.where(s > MIN_STD, s, 1.0)
            rows = [v for v, hand in enumerate(self.hand_vocabulary) if hand in known]
            if rows:
                std[k, num] = std[k, rows].mean(0)
        self._mean, self._std = mean, std

    @property
    def num_blocks(self) -> int:
        return len(self.sides)

    def _ids(self, observation: dict[str, Any], rows: int, device) -> torch.Tensor | None:
        """(rows, H) hand index per block, or None when no row holds a known hand (nothing to scale)."""
        ids = observation.get(self.hand_ids_key) if observation else None
        if ids is None and self.fixed_hand_ids:
            ids = torch.tensor(self.fixed_hand_ids, device=device)
        if ids is None and self.mode == "unnormalize" and self.pair is not None:
            ids = self.pair._last_ids
        if ids is None:
            raise KeyError(
                f"{HAND_ACTION_SCALE_STEP_NAME} ({self.mode}) needs each block's hand ('{self.hand_ids_key}'): this "
                "policy was trained on a mix of hands with actions scaled per hand. Bind it to your robot with "
                "`unidextok-deploy --checkpoint=... --robot=<its converted dataset> --output=...`"
            )
        ids = torch.as_tensor(ids, device=device).long().reshape(-1, self.num_blocks)
        if ids.shape[0] == 1 and rows != 1:
            ids = ids.expand(rows, self.num_blocks)
        if ids.shape[0] != rows:
            raise ValueError(
                f"{HAND_ACTION_SCALE_STEP_NAME}: {ids.shape[0]} rows of hand ids for {rows} rows of actions"
            )
        return ids

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        observation = transition.get(TransitionKey.OBSERVATION) or {}
        action = transition.get(TransitionKey.ACTION)
        if self.mode == "normalize" and observation:
            ids = observation.get(self.hand_ids_key)
            if ids is None and self.fixed_hand_ids:
                ids = torch.tensor(self.fixed_hand_ids)
            if ids is not None:
                self._last_ids = torch.as_tensor(ids).long().reshape(-1, self.num_blocks)
        if action is None:
            return transition
        action = torch.as_tensor(action)
        end = self.action_offset + UDHM_DIM * self.num_blocks
        if action.shape[-1] < end:
            raise ValueError(
                f"{HAND_ACTION_SCALE_STEP_NAME}: action is {action.shape[-1]} wide, expected at least {end} "
                f"({self.action_offset} passthrough columns + {self.num_blocks} UDHM blocks)"
            )
        rows = action.shape[0] if action.ndim > 1 else 1
        ids = self._ids(observation, rows, action.device)  # (rows, H)
        index = torch.where(ids < 0, 0, ids.clamp_max(len(self.hand_vocabulary)))  # (rows, H)
        blocks = torch.arange(self.num_blocks, device=action.device)
        mean = self._mean.to(action.device)[blocks, index]  # (rows, H, 22)
        std = self._std.to(action.device)[blocks, index]
        present = (ids >= 0)[..., None]  # (rows, H, 1)
        mean = torch.where(present, mean, 0.0).reshape(rows, -1)  # (rows, H * 22)
        std = torch.where(present, std, 1.0).reshape(rows, -1)
        if action.ndim == 3:  # (B, chunk, A): one scale per row over its chunk
            mean, std = mean[:, None], std[:, None]
        elif action.ndim == 1:
            mean, std = mean[0], std[0]
        out = action.clone()
        hands = out[..., self.action_offset : end]
        out[..., self.action_offset : end] = (hands - mean) / std if self.mode == "normalize" else hands * std + mean
        new = transition.copy()
        new[TransitionKey.ACTION] = out
        return new

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "sides": list(self.sides),
            "hand_vocabulary": list(self.hand_vocabulary),
            "stats": self.stats,
            "action_offset": self.action_offset,
            "fixed_hand_ids": list(self.fixed_hand_ids),
            "hand_ids_key": self.hand_ids_key,
        }


__all__ = ["HAND_ACTION_SCALE_STEP_NAME", "HandActionScaleStep"]
