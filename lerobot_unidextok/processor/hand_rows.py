"""Each row's hands for the steps that treat rows by the hand they hold (`unidextok.hand_normalizer`,
`unidextok.wrist_frame`): where the hand ids come from, and how one entry per row meets a value of other leading
dims (a (B, chunk, A) action chunk, or (B * n_obs) rows of ids for a (B, ...) value)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch


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


__all__ = ["match_rows", "row_hand_ids"]
