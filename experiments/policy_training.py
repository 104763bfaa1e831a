"""A small stock LeRobot ACT trained on arrays: the arms as `observation.state`, a hand input as
`observation.environment_state` (as `act_udt` feeds its token view), z-scored with training statistics, the
converted action chunk as target (L1 on unpadded steps, ACT's own loss; with `slot_pad`, `act_udt`'s loss, which
leaves the marked action entries out).

The model is LeRobot's `ACTPolicy` unchanged; what is left out is `lerobot-train`'s data loader, so every input
variant trains on exactly the same rows, batches and initialisation for a seed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np


@dataclass
class SmallACT:
    """ACT sizes and optimisation: the values of configs/lerobot/act_udt_cpu.yaml."""

    dim_model: int = 64
    pre_norm: bool = False
    n_heads: int = 4
    dim_feedforward: int = 256
    n_encoder_layers: int = 2
    n_decoder_layers: int = 1
    n_vae_encoder_layers: int = 1
    latent_dim: int = 16
    use_vae: bool = True
    kl_weight: float = 10.0
    dropout: float = 0.1
    chunk_size: int = 10
    lr: float = 1e-3
    weight_decay: float = 1e-4
    grad_clip_norm: float = 10.0
    batch_size: int = 32
    steps: int = 5000


@dataclass
class Standardiser:
    """Per-column z-score from training rows (columns that never change map to 0)."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray) -> Standardiser:
        return cls.of(x.mean(0), x.std(0))

    @classmethod
    def of(cls, mean: np.ndarray, std: np.ndarray) -> Standardiser:
        """From given statistics; a column with (near) zero spread maps to 0, as `fit` does."""
        std = np.asarray(std, np.float64)
        return cls(np.asarray(mean, np.float64), np.where(std > 1e-6, std, 1.0))

    @classmethod
    def identity(cls, width: int) -> Standardiser:
        return cls(np.zeros(width), np.ones(width))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return ((x - self.mean) / self.std).astype(np.float32)

    def inverse(self, z: np.ndarray) -> np.ndarray:
        return z * self.std + self.mean


def act_config(size: SmallACT, arms_dim: int, hands_dim: int, action_dim: int):
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig

    return ACTConfig(
        input_features={"observation.state": PolicyFeature(FeatureType.STATE, (arms_dim,)),
                        "observation.environment_state": PolicyFeature(FeatureType.ENV, (hands_dim,))},
        output_features={"action": PolicyFeature(FeatureType.ACTION, (action_dim,))},
        chunk_size=size.chunk_size, n_action_steps=size.chunk_size, dim_model=size.dim_model, pre_norm=size.pre_norm, n_heads=size.n_heads,
        dim_feedforward=size.dim_feedforward, n_encoder_layers=size.n_encoder_layers,
        n_decoder_layers=size.n_decoder_layers, n_vae_encoder_layers=size.n_vae_encoder_layers,
        latent_dim=size.latent_dim, use_vae=size.use_vae, kl_weight=size.kl_weight, dropout=size.dropout,
        pretrained_backbone_weights=None, device="cpu", push_to_hub=False,
    )  # fmt: skip


@dataclass
class TrainedACT:
    policy: object  # lerobot ACTPolicy
    arms: Standardiser
    hands: Standardiser
    action: Standardiser
    cpu_s: float
    steps_per_s: float
    final_loss: float

    def predict(self, arms: np.ndarray, hands: np.ndarray, batch: int = 1024) -> np.ndarray:
        """(R, chunk, A) action chunks in the action's own units."""
        import torch

        out = []
        self.policy.eval()
        with torch.no_grad():
            for i in range(0, len(arms), batch):
                obs = {"observation.state": torch.from_numpy(self.arms(arms[i : i + batch])),
                       "observation.environment_state": torch.from_numpy(self.hands(hands[i : i + batch]))}  # fmt: skip
                out.append(self.policy.predict_action_chunk(obs).numpy())
        return self.action.inverse(np.concatenate(out).astype(np.float64))


def train_act(size: SmallACT, arms: np.ndarray, hands: np.ndarray, actions: np.ndarray, is_pad: np.ndarray,
              seed: int, slot_pad: np.ndarray | None = None, order: np.ndarray | None = None,
              hands_prescaled: bool = False, actions_prescaled: bool = False) -> TrainedACT:  # fmt: skip
    """Train on (N, arms) + (N, hands) inputs and (N, chunk, A) action chunks with (N, chunk) padding flags.
    `slot_pad` (N, A) bool: no loss (and no gradient) on those action entries of a row, through `act_udt`'s loss
    (`ACTUdtPolicy.forward`, which reads only the model and ACT's fields). `order`: the rows of the batches in
    turn (e.g. a share sampler's draw, at least steps x batch_size of them) instead of shuffled epochs.
    `hands_prescaled` / `actions_prescaled`: the caller z-scored them already (e.g. per source); this function's
    own z-score of them is then the identity, not a pooled one on top."""
    import torch
    from lerobot.policies.act.modeling_act import ACTPolicy

    from lerobot_unidextok.policies.act_udt.modeling_act_udt import ACTUdtPolicy
    from lerobot_unidextok.processor.slot_mask import ACTION_SLOT_PAD_KEY

    if order is not None and len(order) < size.steps * size.batch_size:
        raise ValueError(f"order has {len(order)} rows, the training needs {size.steps * size.batch_size}")

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    arm_s = Standardiser.fit(arms)
    hand_s = Standardiser.identity(hands.shape[1]) if hands_prescaled else Standardiser.fit(hands)
    act_s = Standardiser.identity(actions.shape[2]) if actions_prescaled else Standardiser.fit(actions[:, 0])
    x_arms, x_hands = torch.from_numpy(arm_s(arms)), torch.from_numpy(hand_s(hands))
    y, pad = torch.from_numpy(act_s(actions)), torch.from_numpy(is_pad)
    slots = None if slot_pad is None else torch.from_numpy(np.asarray(slot_pad, bool))
    policy = ACTPolicy(act_config(size, arms.shape[1], hands.shape[1], actions.shape[2]))
    policy.train()
    optim = torch.optim.AdamW(policy.parameters(), lr=size.lr, weight_decay=size.weight_decay)
    cpu0, loss = time.process_time(), float("nan")
    order = np.empty(0, dtype=np.int64) if order is None else np.asarray(order, dtype=np.int64)
    for _ in range(size.steps):
        if len(order) < size.batch_size:  # epochs of shuffled rows, as a shuffling data loader
            order = np.concatenate([order, rng.permutation(len(arms))])
        idx, order = torch.from_numpy(order[: size.batch_size]), order[size.batch_size :]
        batch = {"observation.state": x_arms[idx], "observation.environment_state": x_hands[idx], "action": y[idx],
                 "action_is_pad": pad[idx]}  # fmt: skip
        if slots is None:
            loss_t, _ = policy.forward(batch)
        else:
            loss_t, _ = ACTUdtPolicy.forward(policy, {**batch, ACTION_SLOT_PAD_KEY: slots[idx]})
        optim.zero_grad()
        loss_t.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), size.grad_clip_norm)
        optim.step()
        loss = float(loss_t.detach())
    cpu = time.process_time() - cpu0
    return TrainedACT(policy, arm_s, hand_s, act_s, cpu, size.steps / max(cpu, 1e-9), loss)
