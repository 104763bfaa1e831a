"""The factor of each loss entry of a `<type>_udt` policy trained on a mix: no loss on the slots a row's hand lacks
(`unidextok.slot_mask`), each row weighted by its input's share (`unidextok.share_weights`)."""

import torch

from lerobot_unidextok.processor.share_weights import SAMPLE_WEIGHT_KEY, SAMPLE_WEIGHT_MAP_KEY, ShareWeightStep


def own_share_weights(config) -> ShareWeightStep | None:
    """The share weights a policy computes itself from its config's episode map (None without shares): used when the
    pre-processor's step weighs by the map of another dataset (`share_weight`)."""
    if not (getattr(config, "udt_share_weights", False) and getattr(config, "udt_input_shares", None)):
        return None
    return ShareWeightStep(episode_inputs=list(config.udt_episode_inputs), shares=list(config.udt_input_shares),
                           map_of=config.udt_episode_map_of)  # fmt: skip


def share_weight(batch: dict, config, own: ShareWeightStep | None) -> torch.Tensor | None:
    """(B,) each row's share weight: the pre-processor's when its step weighs by the map of the dataset this config's
    map is for, else this config's own (a checkpoint trained further on another dataset: LeRobot reloads the saved
    step unchanged, while the config's map was made anew, `policies/udt_config.py`); None when neither weighs."""
    if batch.get(SAMPLE_WEIGHT_MAP_KEY, "") == getattr(config, "udt_episode_map_of", ""):
        return batch.get(SAMPLE_WEIGHT_KEY)
    episodes = batch.get("episode_index")
    if own is None or episodes is None:
        return None
    return own.weights(torch.as_tensor(episodes)).to(torch.as_tensor(episodes).device)


def row_weights(err: torch.Tensor, slot_pad: torch.Tensor | None, weight: torch.Tensor | None) -> torch.Tensor:
    """(B, 1, A) factor of each loss entry of a (B, T, A) error: 0 on the slots `slot_pad` marks, each row's
    `weight` (its input's share, `unidextok.share_weights`) elsewhere; 1 where neither is given."""
    out = torch.ones(err.shape[0], 1, err.shape[-1], device=err.device, dtype=err.dtype)
    if slot_pad is not None:
        out = out * ~slot_pad.reshape(err.shape[0], 1, err.shape[-1])
    if weight is not None:
        out = out * weight.reshape(err.shape[0], 1, 1).to(err.dtype)
    return out


__all__ = ["own_share_weights", "row_weights", "share_weight"]
