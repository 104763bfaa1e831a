"""Per-hand output heads around the shared trunk (`--policy.udt_hand_heads=true`, `act_udt` on a mix).

    lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) --policy.udt_hand_heads=true \
        --dataset.repo_id=local/mix --dataset.root=data/mix

As HPT (a head per domain), CrossFormer (a head per action space) and GR00T (`CategorySpecificMLP`, one MLP per
embodiment) do: the trunk is shared by every hand of the mix, the last layer is not quite. ACT's action head
`Linear(dim_model -> A)` becomes `HandHeads`, the same Linear (its parameters keep their names,
`model.action_head.weight` / `.bias`) plus one residual Linear per hand of the mix's vocabulary
(`model.action_head.hand_weight` (V, A, dim_model), `.hand_bias` (V, A)), zero at the start, so an untrained
policy with heads is exactly the policy without them (the same parameters from the same seed: building the
heads draws no random numbers). A row's action is `shared(x) + hand[h](x)` with `h` the row's hand.

How the model knows a row's hand. Two carriers reach the policy:
- the hand identity the mixed tokenizer step appends per block to `observation.environment_state`
  (`processor/mixed.py`). It is a one-hot over the vocabulary by default, but `udt_hand_identity=morphology`
  makes it the hand's morphology vector, from which no vocabulary index can be read back (two hands may share
  one, an unseen hand has one too); decoding it would tie the heads to one identity encoding;
- the hand ids themselves: `observation.hand_ids` ((B, H) indices into the vocabulary, -1 = no hand), which
  the mixed step reads and leaves in the observation, so it reaches the policy through every pre-processor step
  (LeRobot's batch <-> transition converters keep every `observation.*` key; the device step moves it; the
  normaliser touches only the features it has statistics for: `tests/policies/test_hand_heads.py` checks it);
  and, for a robot bound by `unidextok-deploy`, whose own observation has none, the bound config's
  `udt_fixed_hand_ids`.
We read the ids, by the tokenizer step's own rule (`row_hand_ids`: the observation's, else the fixed ones), so
the head a row goes through and the identity the trunk is told come from the same ids whatever the identity
encoding; nothing is added to the batch or to the saved processors. A pre-hook on the ACT model
(`self.model(batch)`, the one call of `forward`, `predict_action_chunk` and so `select_action`) reads them from
the batch and hands them to the head; a forward hook clears them. A batch with neither raises, as the tokenizer
step does.

Rows with several blocks (a two-hand robot): the row's head is the hand of its FIRST block that holds a hand, in
the state's block order (left before right). A G1 with two Inspire hands uses the Inspire's head; a right-only
L10 in a left+right mix (left block absent) uses the L10's. A robot with two different hands gets its first
hand's head for the whole action (arm and wrist columns included): one head per embodiment, as HPT and
CrossFormer have, not one per block. A row whose hands are all zero-shot hands (`unidextok-deploy
--zero_shot=true`, whose ids come after the vocabulary) goes through the shared head plus the mean of the trained
hands' residual heads: the head of the average trained hand, as a policy without heads learns it (the shared head
alone transferred worse: docs/pooling.md). A row with no hand at all (no block holds one) uses the
shared head alone. Training never sees either: every row of a
mix holds a hand of its vocabulary.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import nn

from lerobot_unidextok.constants import OBS_HAND_IDS, OBS_STATE
from lerobot_unidextok.errors import InvalidInputError

NO_HAND = -1  # a row whose blocks hold no hand: the shared head only
UNSEEN_HAND = -2  # a row whose hands are all zero-shot hands: the shared head plus the mean residual head


class HandHeads(nn.Linear):
    """ACT's action head (this Linear, shared) plus a zero-initialised residual Linear per hand of the mix."""

    def __init__(self, in_features: int, out_features: int, num_hands: int, num_blocks: int,
                 device=None, dtype=None) -> None:  # fmt: skip
        super().__init__(in_features, out_features, device=device, dtype=dtype)
        self.num_hands, self.num_blocks = num_hands, num_blocks
        self.hand_weight = nn.Parameter(torch.zeros(num_hands, out_features, in_features, device=device, dtype=dtype))
        self.hand_bias = nn.Parameter(torch.zeros(num_hands, out_features, device=device, dtype=dtype))
        self.row_hands: torch.Tensor | None = None  # (B,) int64, set by the model's pre-hook for one call

    @classmethod
    def around(cls, shared: nn.Linear, num_hands: int, num_blocks: int) -> HandHeads:
        """Heads whose shared part is `shared`'s parameters (copied; no random numbers drawn), residuals zero."""
        heads = nn.utils.skip_init(cls, shared.in_features, shared.out_features, num_hands, num_blocks,
                                   device=shared.weight.device, dtype=shared.weight.dtype)  # fmt: skip
        with torch.no_grad():
            heads.weight.copy_(shared.weight)
            heads.bias.copy_(shared.bias)
            heads.hand_weight.zero_()
            heads.hand_bias.zero_()
        return heads

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, S, dim_model) decoder output -> (B, S, A) actions, each row through its hand's head."""
        if self.row_hands is None:
            raise RuntimeError(
                "HandHeads was called outside the ACT model's forward (no row hands were read from its batch): call "
                "the policy or `policy.model(batch)`, not the head alone"
            )
        rows = self.row_hands.to(x.device)  # (B,)
        if rows.shape != (x.shape[0],):
            raise ValueError(f"HandHeads: {tuple(rows.shape)} row hands for a batch of {x.shape[0]} rows")
        out = super().forward(x)  # (B, S, A) the shared head
        weight = torch.cat([self.hand_weight, self.hand_weight.mean(0, keepdim=True)])  # (V + 1, A, D): + the mean
        bias = torch.cat([self.hand_bias, self.hand_bias.mean(0, keepdim=True)])  # (V + 1, A)
        # (B,) a row's head: its hand's, the mean (index V) for an unseen hand, head 0 for none (multiplied by 0)
        pick = torch.where(rows == UNSEEN_HAND, self.num_hands, rows.clamp_min(0))
        residual = torch.einsum("bsd,bad->bsa", x, weight[pick]) + bias[pick][:, None]  # (B, S, A)
        return out + residual * (rows != NO_HAND)[:, None, None].to(x.dtype)

    def extra_repr(self) -> str:
        return f"{super().extra_repr()}, num_hands={self.num_hands}, num_blocks={self.num_blocks}"


def row_hands(batch: dict, num_hands: int, num_blocks: int, fixed_hand_ids: Sequence[int]) -> torch.Tensor:
    """Each row's hand for the heads: (B,) int64, the hand of the row's first block holding a hand of the V =
    `num_hands` vocabulary, NO_HAND (-1) for none. The ids are the batch's `observation.hand_ids` ((B, H), (B, T, H):
    the last step; (B,) with one block; one (H,) frame for every row), else `fixed_hand_ids` (a bound robot);
    a row whose only hands are ids >= V (a bound robot's zero-shot hands): UNSEEN_HAND (-2)."""
    rows = batch[OBS_STATE].shape[0]
    ids = batch.get(OBS_HAND_IDS)
    if ids is None:
        if not fixed_hand_ids:
            raise InvalidInputError(
                f"per-hand heads need '{OBS_HAND_IDS}' (each block's hand) in the batch: this policy was trained on a "
                "mix of hands. Bind it to your robot with `unidextok-deploy --checkpoint=... --robot=<its converted "
                "dataset> --output=...`"
            )
        ids = torch.as_tensor(list(fixed_hand_ids)).expand(rows, num_blocks)
    ids = torch.as_tensor(ids).long()
    if ids.ndim == 3:
        ids = ids[:, -1]  # (B, T, H): the current step's
    elif ids.ndim == 1 and num_blocks == 1 and ids.shape[0] == rows:
        ids = ids[:, None]  # one block: LeRobot's dataset gives a (1,) feature as a scalar per row
    elif ids.ndim == 1:
        ids = ids[None].expand(rows, -1)  # one frame's ids beside a batched state
    if tuple(ids.shape) != (rows, num_blocks):
        raise InvalidInputError(f"{OBS_HAND_IDS} has shape {tuple(ids.shape)}, expected ({rows}, {num_blocks})")
    present = (ids >= 0) & (ids < num_hands)  # (B, H) blocks holding a hand of the vocabulary
    first = present.to(torch.int8).argmax(-1)  # (B,) the first such block (argmax: the first maximum)
    picked = ids.gather(1, first[:, None]).squeeze(1)  # (B,)
    unseen = torch.where((ids >= num_hands).any(-1), UNSEEN_HAND, NO_HAND)  # (B,) for rows without a known hand
    return torch.where(present.any(-1), picked, unseen)


def install_hand_heads(model: nn.Module, num_hands: int, num_blocks: int,
                       fixed_hand_ids: Callable[[], Sequence[int]]) -> HandHeads:  # fmt: skip
    """Replace ACT `model.action_head` by `HandHeads` around it, and hook `model` so each call reads its batch's
    row hands for the head (`fixed_hand_ids()`: the bound robot's, read at each call) and clears them after."""
    heads = HandHeads.around(model.action_head, num_hands, num_blocks)
    model.action_head = heads

    def read(_module: nn.Module, args: tuple) -> None:
        heads.row_hands = row_hands(args[0], num_hands, num_blocks, fixed_hand_ids())

    def clear(_module: nn.Module, _args: tuple, _output) -> None:
        heads.row_hands = None

    model.register_forward_pre_hook(read)
    model.register_forward_hook(clear)
    return heads


__all__ = ["NO_HAND", "UNSEEN_HAND", "HandHeads", "install_hand_heads", "row_hands"]
