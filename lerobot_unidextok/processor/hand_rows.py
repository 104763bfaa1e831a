"""Each row's hands for the steps that treat rows by the hand they hold (`unidextok.hand_normalizer`,
`unidextok.wrist_frame`): where the hand ids come from, and how one entry per row meets a value of other leading
dims (a (B, chunk, A) action chunk, or (B * n_obs) rows of ids for a (B, ...) value); and the slots a zero-shot
hand drives (`unidextok.slot_mask`, `unidextok.hand_normalizer`)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from lerobot_unidextok.constants import UDHM_DIM


def row_hand_ids(
    observation: dict[str, Any] | None, key: str, fixed: list[int], last: torch.Tensor | None, blocks: int, missing: str
) -> torch.Tensor:
    """(R, blocks) hand index per row and block: the observation's `key`, else the bound robot's `fixed` ids, else
    `last` (what the paired pre step saw); none of them: `KeyError(missing)`."""
    ids = observation.get(key) if observation else None
    if ids is None and fixed:
        ids = torch.tensor(fixed)
    if ids is None and last is not None:
        ids = last
    if ids is None:
        raise KeyError(missing)
    return torch.as_tensor(ids).long().reshape(-1, blocks)


def match_rows(per_row: torch.Tensor, lead: tuple[int, ...], step: str) -> tuple[torch.Tensor, tuple[int, ...]]:
    """`per_row` (R, ...), one entry per row, matched to a value of leading dims `lead`: the entries to use and the
    leading shape to view them as (1 row: every row; R = all leading entries: one each; (B * n_obs) rows for a
    (B, ...) value: each batch row's last step)."""
    total = int(np.prod(lead)) if lead else 1
    rows = per_row.shape[0]
    if rows == 1:
        return per_row, (1,) * max(len(lead), 1)
    if rows == total:
        return per_row, (*lead,) if lead else (1,)
    if lead and rows % lead[0] == 0:
        per_row = per_row.reshape(lead[0], -1, *per_row.shape[1:])[:, -1]
        return per_row, (lead[0], *([1] * (len(lead) - 1)))
    raise ValueError(f"{step}: {rows} rows of hand ids for a value of shape {lead}")


def driven_slot_masks(extra_hand_slots: dict[str, list[int]], extra_hands: list[str], step: str) -> dict[str, np.ndarray]:
    """{zero-shot hand: (22,) bool, the UDHM slots it drives} from a step's `extra_hand_slots` (`unidextok-deploy
    --zero_shot_slots=nearest`), checked: only hands of `extra_hands`, slots 0..21."""
    bad = {h: list(s) for h, s in extra_hand_slots.items()
           if h not in extra_hands or any(not 0 <= int(i) < UDHM_DIM for i in s)}  # fmt: skip
    if bad:
        raise ValueError(f"{step}: extra_hand_slots must give slots 0..{UDHM_DIM - 1} of the extra_hands "
                         f"{extra_hands}; got {bad}")  # fmt: skip
    return {h: np.isin(np.arange(UDHM_DIM), [int(i) for i in s]) for h, s in extra_hand_slots.items()}


__all__ = ["driven_slot_masks", "match_rows", "row_hand_ids"]
