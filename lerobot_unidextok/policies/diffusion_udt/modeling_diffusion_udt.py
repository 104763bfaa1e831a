"""`diffusion_udt` policy: LeRobot's `DiffusionPolicy` under `DiffusionUdtConfig` (LeRobot's factory finds it here by
name), with one override: `forward` leaves the action slots a row's hand lacks out of the denoising loss.

Why an override: Diffusion's loss (`DiffusionModel.compute_loss`, LeRobot 0.6.1) masks padded time steps
(`action_is_pad`, with `do_mask_loss_for_padding`) and returns the mean, so no batch key can mask action
dimensions from outside. When the batch carries `action_slot_is_pad` ((B, A) bool, written by the
pre-processor's `unidextok.slot_mask` step), `forward` runs `masked_denoising_loss`: the stock steps of
`compute_loss` (global conditioning, noise, timesteps, the U-Net's prediction, the epsilon or sample target) on
the policy's own `DiffusionModel`, and the squared error with those entries multiplied by zero, divided as the
stock loss divides (the valid steps x action width with `do_mask_loss_for_padding`, else every element), so a real
slot gets exactly the stock gradient and a lacking slot none; `unidextok_sample_weight` ((B,), a mix's recorded shares)
multiplies each row's terms. Without either key it is the stock `forward`.
"""

import torch
import torch.nn.functional as F  # noqa: N812
from lerobot.policies.diffusion.modeling_diffusion import DiffusionModel, DiffusionPolicy
from lerobot.utils.constants import OBS_IMAGES

from lerobot_unidextok.constants import ACTION
from lerobot_unidextok.policies.diffusion_udt.configuration_diffusion_udt import DiffusionUdtConfig
from lerobot_unidextok.policies.udt_loss import own_share_weights, row_weights, share_weight
from lerobot_unidextok.processor.slot_mask import ACTION_SLOT_PAD_KEY


def masked_denoising_loss(model: DiffusionModel, batch: dict[str, torch.Tensor], slot_pad: torch.Tensor | None,
                          weight: torch.Tensor | None = None) -> torch.Tensor:  # fmt: skip
    """`DiffusionModel.compute_loss` (LeRobot 0.6.1) with the (B, A) `slot_pad` entries out of the loss and each
    row's terms times its `weight` (B,) when given."""
    config = model.config
    global_cond = model._prepare_global_conditioning(batch)  # (B, global_cond_dim)
    trajectory = batch[ACTION]  # (B, horizon, A)
    eps = torch.randn(trajectory.shape, device=trajectory.device)
    timesteps = torch.randint(0, model.noise_scheduler.config.num_train_timesteps, (trajectory.shape[0],),
                              device=trajectory.device).long()  # fmt: skip
    noisy = model.noise_scheduler.add_noise(trajectory, eps, timesteps)
    pred = model.unet(noisy, timesteps, global_cond=global_cond)
    if config.prediction_type == "epsilon":
        target = eps
    elif config.prediction_type == "sample":
        target = trajectory
    else:
        raise ValueError(f"Unsupported prediction type {config.prediction_type}")
    loss = F.mse_loss(pred, target, reduction="none")
    real_slots = row_weights(loss, slot_pad, weight)
    if config.do_mask_loss_for_padding:
        valid = ~batch["action_is_pad"].unsqueeze(-1)
        return (loss * valid * real_slots).sum() / (valid.sum() * loss.shape[-1]).clamp_min(1)
    return (loss * real_slots).sum() / loss.numel()


class DiffusionUdtPolicy(DiffusionPolicy):
    """DiffusionPolicy reading the UniDexTok token view as `observation.environment_state` (`--policy.type=diffusion_udt`)."""

    config_class = DiffusionUdtConfig
    name = "diffusion_udt"

    def __init__(self, config: DiffusionUdtConfig, **kwargs):
        super().__init__(config, **kwargs)
        self._own_shares = own_share_weights(config)  # when the saved pre-processor weighs by another dataset's map

    def forward(self, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, None]:
        """Diffusion's loss without the action slots `batch["action_slot_is_pad"]` marks (module docstring)."""
        slot_pad, weight = batch.get(ACTION_SLOT_PAD_KEY), share_weight(batch, self.config, self._own_shares)
        if slot_pad is None and weight is None:
            return super().forward(batch)
        if self.config.image_features:
            batch = dict(batch)
            for key in self.config.image_features:
                if self.config.n_obs_steps == 1 and batch[key].ndim == 4:
                    batch[key] = batch[key].unsqueeze(1)
            batch[OBS_IMAGES] = torch.stack([batch[key] for key in self.config.image_features], dim=-4)
        return masked_denoising_loss(self.diffusion, batch, slot_pad, weight), None
