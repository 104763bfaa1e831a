"""The factor of each loss entry of a `<type>_udt` policy trained on a mix: no loss on the slots a row's hand lacks
(`unidextok.slot_mask`), each row weighted by its input's share (`unidextok.share_weights`)."""

import torch


def row_weights(err: torch.Tensor, slot_pad: torch.Tensor | None, weight: torch.Tensor | None) -> torch.Tensor:
    """(B, 1, A) factor of each loss entry of a (B, T, A) error: 0 on the slots `slot_pad` marks, each row's
    `weight` (its input's share, `unidextok.share_weights`) elsewhere; 1 where neither is given."""
    out = torch.ones(err.shape[0], 1, err.shape[-1], device=err.device, dtype=err.dtype)
    if slot_pad is not None:
        out = out * ~slot_pad.reshape(err.shape[0], 1, err.shape[-1])
    if weight is not None:
        out = out * weight.reshape(err.shape[0], 1, 1).to(err.dtype)
    return out


__all__ = ["row_weights"]
