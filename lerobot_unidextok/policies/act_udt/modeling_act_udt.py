"""`act_udt` policy: LeRobot's `ACTPolicy` under `ACTUdtConfig` (LeRobot's factory finds it here by name), with one
override: `forward` leaves the action slots a row's hand lacks out of the L1 loss.

Why an override: ACT's loss (`ACTPolicy.forward`, LeRobot 0.6.1) masks padded time steps (`action_is_pad`) and
nothing else, and no flag or batch key lets it mask action dimensions, so the zero-filled UDHM slots of a hand
would be trained as real targets. When the batch carries `action_slot_is_pad` ((B, A) bool, written by the
pre-processor's `unidextok.slot_mask` step), `forward` computes ACT's own loss with those entries multiplied by
zero: the same sum over the valid steps and the same divisor (valid steps x action width) as the stock loss,
so every real slot gets exactly the stock gradient and a lacking slot none. When the batch carries
`unidextok_sample_weight` ((B,), `unidextok.share_weights`: a mix's recorded shares as loss weights, since
`lerobot-train` takes no sampler) each row's terms are multiplied by it. Without either key (checkpoints and
pre-processors saved before them, `udt_mask_slots=false`) it is the stock `forward`. Inference is unchanged.

With `udt_hand_heads` on a mix, `model.action_head` is `HandHeads` (`policies/hand_heads.py`): the shared head
plus a zero-initialised residual head per hand of the mix, each row through its own hand's, which a hook on the
model reads from the batch's `observation.hand_ids` (a bound robot: `udt_fixed_hand_ids`) on every
`self.model(batch)` (training, `predict_action_chunk`, `select_action`). Without the flag the model is ACT's, parameter for parameter.
"""

import torch
import torch.nn.functional as F  # noqa: N812
from lerobot.policies.act.modeling_act import ACTPolicy
from lerobot.utils.constants import OBS_IMAGES

from lerobot_unidextok.constants import ACTION
from lerobot_unidextok.policies.act_udt.configuration_act_udt import ACTUdtConfig
from lerobot_unidextok.policies.hand_heads import install_hand_heads
from lerobot_unidextok.policies.udt_loss import own_share_weights, row_weights, share_weight
from lerobot_unidextok.processor.slot_mask import ACTION_SLOT_PAD_KEY


class ACTUdtPolicy(ACTPolicy):
    """ACTPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=act_udt`)."""

    config_class = ACTUdtConfig
    name = "act_udt"

    def __init__(self, config: ACTUdtConfig, **kwargs):
        super().__init__(config, **kwargs)
        self._own_shares = own_share_weights(config)  # when the saved pre-processor weighs by another dataset's map
        if config.udt_hand_heads and config.udt_hand_vocabulary:  # a residual head per hand of the mix, zero
            install_hand_heads(self.model, len(config.udt_hand_vocabulary), config.num_udt_blocks,
                               lambda: self.config.udt_fixed_hand_ids)  # fmt: skip
        if config.udt_relative_actions and config.udt_copy_start:  # the untrained policy copies the state
            torch.nn.init.zeros_(self.model.action_head.weight)
            torch.nn.init.zeros_(self.model.action_head.bias)

    def forward(self, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict]:
        """ACT's loss without the action slots `batch["action_slot_is_pad"]` marks (module docstring)."""
        # a plain ACTPolicy given this loss (experiments/policy_training.py's masked ACT) has no shares of its own
        own = getattr(self, "_own_shares", None)
        slot_pad, weight = batch.get(ACTION_SLOT_PAD_KEY), share_weight(batch, self.config, own)
        if slot_pad is None and weight is None:
            return super().forward(batch)
        if self.config.image_features:
            batch = dict(batch)
            batch[OBS_IMAGES] = [batch[key] for key in self.config.image_features]
        actions_hat, (mu_hat, log_sigma_x2_hat) = self.model(batch)
        abs_err = F.l1_loss(batch[ACTION], actions_hat, reduction="none")  # (B, chunk, A)
        valid_steps = ~batch["action_is_pad"].unsqueeze(-1)  # (B, chunk, 1)
        keep = valid_steps * row_weights(abs_err, slot_pad, weight)  # (B, chunk, A)
        num_valid = valid_steps.sum() * abs_err.shape[-1]  # the stock divisor
        l1_loss = (abs_err * keep).sum() / num_valid.clamp_min(1)
        loss_dict = {"l1_loss": l1_loss.item()}
        if self.config.use_vae and log_sigma_x2_hat is not None:
            mean_kld = (-0.5 * (1 + log_sigma_x2_hat - mu_hat.pow(2) - log_sigma_x2_hat.exp())).sum(-1).mean()
            loss_dict["kld_loss"] = mean_kld.item()
            return l1_loss + mean_kld * self.config.kl_weight, loss_dict
        return l1_loss, loss_dict
