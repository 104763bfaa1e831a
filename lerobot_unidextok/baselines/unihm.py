"""UniHM-style baseline: per-hand encoders and decoders around one single (non-factorised) codebook.

Follows Zhenhao-Zhang/UniHM (`vqvae/encoder.py`, `decoder.py`, `quantizer.py`, `multi_vqvae.py`,
`train_vqvae_muti_encoder.py`), re-implemented for 22-D UDHM states; every deviation and every
choice where the original is unclear is listed in `docs/baselines.md`.

Schedule (`UniHMTokenizer.fit`):
1. teacher: one Conv1d encoder over the UDHM vector (1-channel sequence), shared codebook, one decoder
   per hand; loss = sum over decoders of L1 + UniHM's VQ loss. Human states are also decoded into every
   robot hand: into the robot state retargeted from the same human frame when `paired` is given (UniHM's
   recipe: DexYCB retargeted to each robot with dex-retargeting), else into the human state semantically
   inserted into the robot's slots (a stand-in when no retargeted pairs exist).
2. students (every hand but the teacher hand): distil L1(z_student, z_teacher), then code alignment
   L1(q(z_s), q(z_t)) + VQ loss with a frozen codebook, repeated in rounds with LR x 0.8^i.
3. fine-tune each student inside the frozen codebook + decoder with L1 reconstruction.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace

import torch
import torch.nn.functional as F
from torch import nn

from lerobot_unidextok.baselines.base import ArrayLike, Rate, as_mask, as_states, check_hand, infer_masks
from lerobot_unidextok.constants import ANGLE_SCALE_RAD, UDHM_DIM
from lerobot_unidextok.utils.cli import progress_bar

logger = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------
# config
# ---------------------------------------------------------------------------------------------
@dataclass
class UniHMConfig:
    """UniHM-style VQ-VAE. Defaults = the `cpu` preset (a few minutes on 2 cores)."""

    # --- architecture (UniHM: h_dim 128, res_h_dim 128, n_res_layers 2, codebook 8192 x 512, beta 0.25)
    h_dim: int = 32  # Conv1d channels
    res_h_dim: int = 32  # residual block hidden channels
    n_res_layers: int = 2
    codebook_size: int = 1024  # entries of the single codebook (one token per state)
    embedding_dim: int = 64  # codebook vector width = bottleneck width
    beta: float = 0.25  # weights the codebook term of the VQ loss, as in UniHM's code
    teacher_hand: str = "human"  # hand whose encoder is the teacher; others get students

    # --- optimisation (UniHM: AdamW 5e-4 wd 1e-4; codebook SGD 1e-3 momentum 0.9; batch 1024)
    batch_size: int = 256  # per hand and step
    lr: float = 5e-4
    weight_decay: float = 1e-4
    codebook_lr: float = 1e-3
    codebook_momentum: float = 0.9
    teacher_steps: int = 1200
    # k-means codebook resets (UniHM: epoch 5, then every 40 epochs; only cold codes late in training)
    kmeans_first_step: int = 100
    kmeans_every: int = 250
    kmeans_cold_after: float = 0.6  # fraction of teacher_steps after which only cold codes are reset
    kmeans_cold_ratio: float = 0.2
    kmeans_iters: int = 10
    # students (UniHM: distil AdamW 5e-3, align AdamW 1e-3, fine-tune AdamW 5e-4; 1 + 4 rounds x 0.8^i)
    distill_steps: int = 60  # per round
    distill_lr: float = 5e-3
    align_steps: int = 60  # per round
    align_lr: float = 1e-3
    rounds: int = 5
    round_lr_decay: float = 0.8
    finetune_steps: int = 300
    finetune_lr: float = 5e-4
    seed: int = 0
    progress: bool = True  # tqdm bars during fit

    def __post_init__(self) -> None:
        if self.h_dim < 2 or self.h_dim % 2:
            raise ValueError(
                f"h_dim must be an even number >= 2 (the first conv has h_dim/2 channels); got {self.h_dim}"
            )
        if self.codebook_size < 2:
            raise ValueError(f"codebook_size must be >= 2; got {self.codebook_size}")
        if not 0.0 <= self.kmeans_cold_after <= 1.0:
            raise ValueError(
                f"kmeans_cold_after is a fraction of teacher_steps in [0, 1]; got {self.kmeans_cold_after}"
            )
        if self.batch_size < 1 or self.rounds < 1:
            raise ValueError(f"batch_size and rounds must be >= 1; got {self.batch_size}, {self.rounds}")

    @classmethod
    def from_preset(cls, name: str, **overrides) -> UniHMConfig:
        if name not in UNIHM_PRESETS:
            raise ValueError(f"unknown UniHM preset {name!r}; choose one of {sorted(UNIHM_PRESETS)}")
        return replace(UNIHM_PRESETS[name], **overrides)


UNIHM_PRESETS: dict[str, UniHMConfig] = {
    # UniHM's published sizes and batch; far beyond a CPU budget.
    "paper": UniHMConfig(
        h_dim=128, res_h_dim=128, codebook_size=8192, embedding_dim=512, batch_size=1024,
        teacher_steps=20000, kmeans_first_step=500, kmeans_every=4000, distill_steps=1000, align_steps=1000,
        finetune_steps=5000,
    ),
    "cpu": UniHMConfig(),
    # Unit tests: seconds.
    "tiny": UniHMConfig(
        h_dim=16, res_h_dim=16, n_res_layers=1, codebook_size=32, embedding_dim=16, batch_size=64,
        teacher_steps=40, kmeans_first_step=10, kmeans_every=20, distill_steps=5, align_steps=5, rounds=2,
        finetune_steps=10, progress=False,
    ),
}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# modules (UniHM's Conv1d encoder / ConvTranspose1d decoder, sized for a 22-slot input)
# ---------------------------------------------------------------------------------------------
class ResidualLayer(nn.Module):
    """ReLU -> Conv3 -> ReLU -> Conv1, added to the input."""

    def __init__(self, h_dim: int, res_h_dim: int) -> None:
        super().__init__()
        self.block = nn.Sequential(
            nn.ReLU(),
            nn.Conv1d(h_dim, res_h_dim, kernel_size=3, padding=1, bias=False),
            nn.ReLU(),
            nn.Conv1d(res_h_dim, h_dim, kernel_size=1, bias=False),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.block(x)  # (B, C, L)


def residual_stack(config: UniHMConfig) -> nn.Sequential:
    layers = [ResidualLayer(config.h_dim, config.res_h_dim) for _ in range(config.n_res_layers)]
    return nn.Sequential(*layers, nn.ReLU())


def _conv_len(length: int, kernel: int, stride: int, padding: int) -> int:
    return (length + 2 * padding - kernel) // stride + 1


class UniHMEncoder(nn.Module):
    """UDHM vector as a 1-channel sequence -> Conv1d stack -> Linear -> `(B, D)` pre-quantisation latent."""

    def __init__(self, config: UniHMConfig) -> None:
        super().__init__()
        h = config.h_dim
        length = _conv_len(_conv_len(UDHM_DIM, 4, 2, 1), 4, 2, 1)  # 22 -> 11 -> 5
        self.net = nn.Sequential(
            nn.Conv1d(1, h // 2, kernel_size=4, stride=2, padding=1),
            nn.ReLU(),
            nn.Conv1d(h // 2, h, kernel_size=4, stride=2, padding=1),
            nn.ReLU(),
            nn.Conv1d(h, h, kernel_size=3, stride=1, padding=1),
            residual_stack(config),
            nn.Flatten(start_dim=1),
            nn.Linear(h * length, config.embedding_dim),
        )
        self.pre_quantization = nn.Linear(config.embedding_dim, config.embedding_dim)

    def forward(self, x_norm: torch.Tensor) -> torch.Tensor:
        z = self.net(x_norm[:, None, :])  # (B, 1, 22) -> (B, D)
        return self.pre_quantization(z)  # (B, D)


class UniHMDecoder(nn.Module):
    """`(B, D)` code vector as a 1-channel sequence -> ConvTranspose1d stack -> Linear(4D -> 22)."""

    def __init__(self, config: UniHMConfig) -> None:
        super().__init__()
        h = config.h_dim
        self.net = nn.Sequential(
            nn.ConvTranspose1d(1, h, kernel_size=3, stride=1, padding=1),  # (B, h, D)
            residual_stack(config),
            nn.ConvTranspose1d(h, h // 2, kernel_size=4, stride=2, padding=1),  # (B, h/2, 2D)
            nn.ReLU(),
            nn.ConvTranspose1d(h // 2, 1, kernel_size=4, stride=2, padding=1),  # (B, 1, 4D)
            nn.Flatten(start_dim=1),
            nn.Linear(4 * config.embedding_dim, UDHM_DIM),
        )

    def forward(self, z_q: torch.Tensor) -> torch.Tensor:
        return self.net(z_q[:, None, :])  # (B, D) -> (B, 22) normalised angles


class VectorQuantizer(nn.Module):
    """One codebook, nearest entry by L2; UniHM's VQ loss and straight-through estimator."""

    def __init__(self, config: UniHMConfig) -> None:
        super().__init__()
        self.beta = config.beta
        self.codebook = nn.Embedding(config.codebook_size, config.embedding_dim)
        self.codebook.weight.data.uniform_(-1.0 / config.codebook_size, 1.0 / config.codebook_size)
        self.register_buffer("usage_counts", torch.zeros(config.codebook_size, dtype=torch.long), persistent=False)

    def indices(self, z: torch.Tensor) -> torch.Tensor:
        weight = self.codebook.weight  # (K, D)
        dist = z.pow(2).sum(1, keepdim=True) + weight.pow(2).sum(1) - 2 * z @ weight.t()  # (B, K)
        return dist.argmin(dim=1)  # (B,)

    def forward(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        idx = self.indices(z)  # (B,)
        z_q = self.codebook(idx)  # (B, D)
        # UniHM code: beta weights the codebook term, not the commitment term its docstring names
        loss = F.mse_loss(z_q.detach(), z) + self.beta * F.mse_loss(z_q, z.detach())
        if self.training:
            self.usage_counts += torch.bincount(idx, minlength=self.usage_counts.numel())
        return z + (z_q - z).detach(), idx, loss  # (B, D), (B,), ()

    @torch.no_grad()
    def kmeans_reset(
        self, latents: torch.Tensor, iters: int, cold_ratio: float | None, generator: torch.Generator
    ) -> None:
        """Re-initialise the codebook (or only its coldest `cold_ratio` entries) with k-means on `latents`."""
        num_codes = self.codebook.num_embeddings
        replace_init = latents.shape[0] < num_codes
        centres = (
            latents[torch.randint(latents.shape[0], (num_codes,), generator=generator)]
            if replace_init
            else (latents[torch.randperm(latents.shape[0], generator=generator)[:num_codes]]).clone()
        )  # (K, D)
        for _ in range(iters):
            labels = torch.cdist(latents, centres).argmin(dim=1)  # (M,)
            sums = torch.zeros_like(centres).index_add_(0, labels, latents)
            counts = torch.bincount(labels, minlength=num_codes)
            empty = counts == 0
            centres = torch.where(empty[:, None], latents[torch.randint(latents.shape[0], (num_codes,), generator=generator)],
                                  sums / counts.clamp(min=1)[:, None])  # fmt: skip
        if cold_ratio is None:
            self.codebook.weight.data.copy_(centres)
        else:
            num_cold = max(1, round(num_codes * cold_ratio))
            cold = torch.topk(-self.usage_counts.float(), k=num_cold).indices
            self.codebook.weight.data[cold] = centres[cold]
        self.usage_counts.zero_()


# ---------------------------------------------------------------------------------------------
# tokenizer
# ---------------------------------------------------------------------------------------------
class UniHMTokenizer(nn.Module):
    """Per-hand encoders and decoders, one shared codebook; codes `(B, 1)` in [0, codebook_size)."""

    name = "unihm"

    def __init__(self, config: UniHMConfig | None = None) -> None:
        super().__init__()
        self.config = config or UniHMConfig()
        self.quantizer = VectorQuantizer(self.config)
        self.teacher = UniHMEncoder(self.config)
        self.students = nn.ModuleDict()
        self.decoders = nn.ModuleDict()
        self.masks: dict[str, torch.Tensor] = {}
        self._paired: dict[str, torch.Tensor] = {}  # retargeted robot states paired with teacher rows (fit)

    # --- public API -------------------------------------------------------------------------
    def rate(self, hand: str) -> Rate:
        return Rate(1, 1, self.config.codebook_size)

    def encoder_for(self, hand: str) -> UniHMEncoder:
        check_hand(hand, self.decoders, self.name)
        return self.students[hand] if hand in self.students else self.teacher

    @torch.no_grad()
    def embed(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        """Continuous pre-quantisation latent `(B, D)` of the hand's encoder."""
        return self.encoder_for(hand)(self._normalise(as_states(states_rad), hand))

    @torch.no_grad()
    def encode(self, states_rad: ArrayLike, hand: str) -> torch.Tensor:
        return self.quantizer.indices(self.embed(states_rad, hand))[:, None]  # (B, 1) int64

    @torch.no_grad()
    def decode(self, codes: torch.Tensor, hand: str) -> torch.Tensor:
        check_hand(hand, self.decoders, self.name)
        codes = torch.as_tensor(codes)
        if codes.ndim != 2 or codes.shape[1] != 1:
            raise ValueError(f"UniHM codes must have shape (B, 1); got {tuple(codes.shape)}")
        if codes.numel() and (codes.min() < 0 or codes.max() >= self.config.codebook_size):
            raise ValueError(
                f"UniHM codes must lie in [0, {self.config.codebook_size}); got [{codes.min()}, {codes.max()}]"
            )
        x_norm = self.decoders[hand](self.quantizer.codebook(codes[:, 0]))  # (B, 22)
        return x_norm * ANGLE_SCALE_RAD * self.masks[hand]  # (B, 22) rad, inactive slots zero

    # --- training ---------------------------------------------------------------------------
    def fit(
        self,
        train_states: Mapping[str, ArrayLike],
        masks: Mapping[str, ArrayLike] | None = None,
        paired: Mapping[str, ArrayLike] | None = None,
    ) -> dict:
        """Train teacher, students and fine-tuning on `{hand: (N, 22) rad}`; returns per-phase loss lists.

        `paired[hand]` (N_teacher, 22): the robot state retargeted from each row of the teacher hand's states
        (row for row), UniHM's training pairs.
        """
        cfg = self.config
        if not train_states:
            raise ValueError("UniHMTokenizer.fit needs states of at least one hand: {'human': (N, 22) radians, ...}")
        states = {hand: as_states(s, f"train_states[{hand!r}]") for hand, s in train_states.items()}
        empty = [hand for hand, s in states.items() if s.shape[0] == 0]
        if empty:
            raise ValueError(f"train_states has no frames for {empty}; drop those hands or add data")
        self.masks = (
            {hand: as_mask(m, hand).float() for hand, m in masks.items()} if masks is not None
            else {hand: m.float() for hand, m in infer_masks(states).items()}
        )  # fmt: skip
        missing = sorted(set(states) - set(self.masks))
        if missing:
            raise ValueError(f"masks lack hands {missing}; give one (22,) mask per hand in train_states")
        generator = torch.Generator().manual_seed(cfg.seed)
        torch.manual_seed(cfg.seed)
        self.quantizer = VectorQuantizer(cfg)
        self.teacher = UniHMEncoder(cfg)
        self.decoders = nn.ModuleDict({hand: UniHMDecoder(cfg) for hand in states})
        student_hands = [hand for hand in states if hand != cfg.teacher_hand]
        self.students = nn.ModuleDict({hand: UniHMEncoder(cfg) for hand in student_hands})
        # robot slot ranges for semantic insertion of human states (used where no retargeted pairs are given)
        self._ranges = {hand: (s.min(0).values, s.max(0).values) for hand, s in states.items()}
        norm = {hand: self._normalise(s, hand) for hand, s in states.items()}
        self._paired = {}
        for hand, pair in (paired or {}).items():
            pair = as_states(pair, f"paired[{hand!r}]")
            if (
                hand not in states
                or cfg.teacher_hand not in states
                or pair.shape[0] != states[cfg.teacher_hand].shape[0]
            ):
                raise ValueError(
                    f"paired[{hand!r}] must hold one retargeted state per {cfg.teacher_hand!r} training row "
                    f"({states[cfg.teacher_hand].shape[0] if cfg.teacher_hand in states else 0}) of a hand in train_states; "
                    f"got {tuple(pair.shape)}"
                )
            self._paired[hand] = self._normalise(pair, hand)
        self.train()
        history = {"teacher": self._fit_teacher(norm, generator)}
        history.update(self._fit_students(norm, generator))
        self.eval()
        return history

    def _normalise(self, states_rad: torch.Tensor, hand: str) -> torch.Tensor:
        check_hand(hand, self.masks, self.name)
        return states_rad / ANGLE_SCALE_RAD * self.masks[hand]  # (B, 22)

    def _robot_target(self, human_norm: torch.Tensor, idx: torch.Tensor, hand: str) -> torch.Tensor:
        """The robot state paired with human rows `idx`: retargeted if given, else semantically inserted."""
        if hand in self._paired:
            return self._paired[hand][idx]
        return self._insert(human_norm, hand)

    def _insert(self, human_norm: torch.Tensor, hand: str) -> torch.Tensor:
        """Human state -> hand's active slots, clipped to the range the hand shows in training."""
        lower, upper = self._ranges[hand]
        return torch.clamp(human_norm, lower / ANGLE_SCALE_RAD, upper / ANGLE_SCALE_RAD) * self.masks[hand]

    def _batch(self, norm: dict[str, torch.Tensor], hand: str, generator: torch.Generator) -> torch.Tensor:
        return norm[hand][self._indices(norm, hand, generator)]

    def _indices(self, norm: dict[str, torch.Tensor], hand: str, generator: torch.Generator) -> torch.Tensor:
        return torch.randint(norm[hand].shape[0], (self.config.batch_size,), generator=generator)

    def _l1(self, pred: torch.Tensor, target: torch.Tensor, hand: str) -> torch.Tensor:
        mask = self.masks[hand]
        return ((pred - target).abs() * mask).sum() / (mask.sum() * pred.shape[0])

    def _fit_teacher(self, norm: dict[str, torch.Tensor], generator: torch.Generator) -> list[float]:
        cfg = self.config
        params = list(self.teacher.parameters()) + list(self.decoders.parameters())
        opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
        opt_codebook = torch.optim.SGD(self.quantizer.parameters(), lr=cfg.codebook_lr, momentum=cfg.codebook_momentum)
        human = cfg.teacher_hand if cfg.teacher_hand in norm else None
        recent: list[torch.Tensor] = []
        losses = []
        for step in progress_bar(range(cfg.teacher_steps), desc="UniHM teacher", disable=not cfg.progress):
            idx = {hand: self._indices(norm, hand, generator) for hand in norm}
            batches = {hand: norm[hand][i] for hand, i in idx.items()}
            z = self.teacher(torch.cat(list(batches.values())))  # (H*B, D)
            z_q, _, vq_loss = self.quantizer(z)
            chunks = dict(zip(batches, z_q.split(cfg.batch_size), strict=True))
            loss = vq_loss
            for hand, x in batches.items():
                loss = loss + self._l1(self.decoders[hand](chunks[hand]), x, hand)
            if human is not None:  # UniHM's multi-decoder loss: every robot decodes the human code
                for hand in norm:
                    if hand != human:
                        target = self._robot_target(batches[human], idx[human], hand)
                        loss = loss + self._l1(self.decoders[hand](chunks[human]), target, hand)
            opt.zero_grad()
            opt_codebook.zero_grad()
            loss.backward()
            opt.step()
            opt_codebook.step()
            losses.append(loss.item())
            recent = (recent + [z.detach()])[-8:]
            if step + 1 >= cfg.kmeans_first_step and (step + 1 - cfg.kmeans_first_step) % cfg.kmeans_every == 0:
                cold = cfg.kmeans_cold_ratio if step >= cfg.kmeans_cold_after * cfg.teacher_steps else None
                self.quantizer.kmeans_reset(torch.cat(recent), cfg.kmeans_iters, cold, generator)
        return losses

    def _student_pairs(self, norm: dict[str, torch.Tensor], hand: str, generator: torch.Generator) -> tuple:
        """(student input, teacher input): the hand's own states, plus inserted human states if any."""
        own = self._batch(norm, hand, generator)
        human = self.config.teacher_hand
        if human not in norm:
            return own, own
        idx = self._indices(norm, human, generator)
        human_batch = norm[human][idx]
        return torch.cat([own, self._robot_target(human_batch, idx, hand)]), torch.cat([own, human_batch])

    def _fit_students(self, norm: dict[str, torch.Tensor], generator: torch.Generator) -> dict[str, list[float]]:
        cfg = self.config
        history: dict[str, list[float]] = {"distill": [], "align": [], "finetune": []}
        for p in self.teacher.parameters():
            p.requires_grad_(False)
        self.quantizer.codebook.weight.requires_grad_(False)
        for hand, student in self.students.items():
            for i in range(cfg.rounds):
                scale = cfg.round_lr_decay**i
                opt = torch.optim.AdamW(student.parameters(), lr=cfg.distill_lr * scale, weight_decay=cfg.weight_decay)
                for _ in progress_bar(
                    range(cfg.distill_steps), desc=f"UniHM distil {hand} r{i}", disable=not cfg.progress
                ):
                    x_s, x_t = self._student_pairs(norm, hand, generator)
                    loss = F.l1_loss(student(x_s), self.teacher(x_t))
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
                    history["distill"].append(loss.item())
                opt = torch.optim.AdamW(student.parameters(), lr=cfg.align_lr * scale, weight_decay=cfg.weight_decay)
                for _ in progress_bar(
                    range(cfg.align_steps), desc=f"UniHM align {hand} r{i}", disable=not cfg.progress
                ):
                    x_s, x_t = self._student_pairs(norm, hand, generator)
                    z_q_s, _, vq_loss = self.quantizer(student(x_s))
                    with torch.no_grad():
                        z_q_t = self.quantizer.codebook(self.quantizer.indices(self.teacher(x_t)))
                    loss = F.l1_loss(z_q_s, z_q_t) + vq_loss
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
                    history["align"].append(loss.item())
            decoder = self.decoders[hand]
            decoder.requires_grad_(False)
            opt = torch.optim.AdamW(student.parameters(), lr=cfg.finetune_lr, weight_decay=cfg.weight_decay)
            for _ in progress_bar(range(cfg.finetune_steps), desc=f"UniHM fine-tune {hand}", disable=not cfg.progress):
                x_s, _ = self._student_pairs(norm, hand, generator)
                z_q, _, vq_loss = self.quantizer(student(x_s))
                loss = self._l1(decoder(z_q), x_s, hand) + vq_loss
                opt.zero_grad()
                loss.backward()
                opt.step()
                history["finetune"].append(loss.item())
            decoder.requires_grad_(True)
        self.teacher.requires_grad_(True)
        self.quantizer.codebook.weight.requires_grad_(True)
        return history

    def extra_repr(self) -> str:
        return f"hands={sorted(self.decoders)}, config={asdict(self.config)}"
