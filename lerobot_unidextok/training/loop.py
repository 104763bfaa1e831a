"""The tokenizer training loop over in-memory per-hand rows (single process or `accelerate launch`)."""

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from lerobot_unidextok.evaluation.metrics import mpjae_deg
from lerobot_unidextok.evaluation.reconstruct import codebook_usage, reconstruct
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.training.arrays import HandMixSampler, HandStates
from lerobot_unidextok.training.checkpoint import (
    load_optimizer_state,
    load_resume_tensors,
    load_training_state,
    save_checkpoint,
)
from lerobot_unidextok.training.config import TrainConfig
from lerobot_unidextok.training.optim import lr_at, make_optimizer

logger = logging.getLogger(__name__)


@dataclass
class TrainResult:
    """Where the selected checkpoint is and how training went."""

    best_dir: Path
    best_mae_deg: float
    best_step: int
    steps: int
    seconds: float
    history: list[dict] = field(default_factory=list)  # one entry per evaluation


def build_model(cfg: TrainConfig, train_data: HandStates) -> UniDexTok:
    """A fresh model from the preset, or `init_from` with any new training hands added."""
    hands = train_data.hand_names()
    if cfg.init_from:
        model = UniDexTok.from_pretrained(cfg.init_from)
        model.add_hands([*cfg.hand_names, *hands])
        return model
    names = list(cfg.hand_names) or list(UniDexTokConfig.from_preset(cfg.preset).hand_names)
    names += [h for h in hands if h not in names]
    return UniDexTok(UniDexTokConfig.from_preset(cfg.preset, hand_names=names))


def evaluate_mae_deg(model: UniDexTok, data: HandStates, max_frames: int, seed: int) -> tuple[float, dict]:
    """Held-out joint MAE (deg, active DoFs) and codebook usage on up to `max_frames` rows."""
    if len(data) > max_frames:
        rows = np.sort(np.random.default_rng(seed).choice(len(data), max_frames, replace=False))
        data = data.select(rows)
    rec = reconstruct(model, data.states_rad, data.hands, allow_unknown=True)
    return mpjae_deg(rec.states_rad, data.states_rad, data.masks), codebook_usage(rec.codes, model.config.codebook_size)


def total_steps(cfg: TrainConfig, num_train_rows: int) -> int:
    if cfg.epochs > 0:
        return max(1, math.ceil(cfg.epochs * num_train_rows / cfg.batch_size))
    return cfg.steps


def train_tokenizer(
    cfg: TrainConfig, train_data: HandStates, eval_data: HandStates, model: UniDexTok | None = None
) -> TrainResult:
    """Train (or adapt) a tokenizer; keeps the checkpoint with the lowest held-out joint MAE (deg)."""

    if len(train_data) == 0 or len(eval_data) == 0:
        raise ValueError(f"need training and held-out rows, got {len(train_data)} and {len(eval_data)}")
    threads_before = torch.get_num_threads()
    if cfg.num_threads > 0:
        torch.set_num_threads(cfg.num_threads)
    try:
        return _train(cfg, train_data, eval_data, model)
    finally:
        torch.set_num_threads(threads_before)


def _train(cfg: TrainConfig, train_data: HandStates, eval_data: HandStates, model: UniDexTok | None) -> TrainResult:
    from accelerate import Accelerator

    accelerator = Accelerator(cpu=cfg.device == "cpu")
    torch.manual_seed(cfg.seed + accelerator.process_index)
    out = Path(cfg.output_dir)
    best_dir, last_dir = out / "best", out / "last"

    if model is None:
        model = build_model(cfg, train_data)
    elif cfg.hand_names:
        model.add_hands(cfg.hand_names)
    if cfg.resume:
        if not (last_dir / "config.json").is_file():
            raise FileNotFoundError(f"--resume: no checkpoint at {last_dir}; run once without --resume first")
        model = UniDexTok.from_pretrained(last_dir)
    unknown = [h for h in train_data.hand_names() if not model.knows_hand(h)]
    if unknown:
        model.add_hands(unknown)
    model.train()
    for name, param in model.named_parameters():
        param.requires_grad_(cfg.adapt == "all" or name.startswith("hand_embed"))
    optimizer = make_optimizer(model, cfg.lr, cfg.weight_decay, cfg.betas)

    n_steps = total_steps(cfg, len(train_data))
    start, best_mae, best_step, history = 0, float("inf"), -1, []
    if cfg.resume:
        load_optimizer_state(optimizer, last_dir)
        state = load_training_state(last_dir)
        start, best_mae, best_step, history = state["step"], state["best_mae_deg"], state["best_step"], state["history"]
    model, optimizer = accelerator.prepare(model, optimizer)
    raw_model: UniDexTok = accelerator.unwrap_model(model)

    # seeded as at step 0 also when resuming: the saved generator states (below) continue the same streams
    sampler = HandMixSampler(
        train_data.hands,
        cfg.hand_weights,
        cfg.default_hand_weight,
        seed=cfg.seed * 1000 + accelerator.process_index,
    )
    logger.info("training %d steps on %d rows; hand shares %s", n_steps, len(train_data), sampler.hand_share)
    states = torch.as_tensor(train_data.states_rad)
    masks = torch.as_tensor(train_data.masks)
    hand_ids = torch.tensor([raw_model._hand_index[h] for h in train_data.hands.tolist()])
    device = accelerator.device

    def _evaluate(step: int) -> None:
        nonlocal best_mae, best_step
        if not accelerator.is_main_process:
            return
        mae, usage = evaluate_mae_deg(raw_model, eval_data, cfg.eval_max_frames, cfg.seed)
        history.append({"step": step, "eval_mae_deg": mae, **{f"eval_{k}": v for k, v in usage.items()}})
        if mae < best_mae:
            best_mae, best_step = mae, step
            save_checkpoint(raw_model, best_dir, state={"step": step, "eval_mae_deg": mae})
        logger.info(
            "step %d: held-out MAE %.3f deg (best %.3f @ %d), usage %.2f",
            step,
            mae,
            best_mae,
            best_step,
            usage["usage"],
        )

    dropout_rng = torch.Generator().manual_seed(cfg.seed * 1000 + 1)
    if cfg.resume:  # continue the random streams where the checkpoint left them: resume == uninterrupted run
        saved = load_resume_tensors(last_dir)
        if "sampler_rng" in state and saved:
            sampler.rng.bit_generator.state = state["sampler_rng"]
            torch.set_rng_state(saved["torch_rng"])
            dropout_rng.set_state(saved["dropout_rng"])
            raw_model.quantizer.usage_ema.copy_(saved["usage_ema"])
        else:
            logger.warning("%s has no random-generator state (older checkpoint): the resumed run draws other "
                           "batches than an uninterrupted one would", last_dir)  # fmt: skip

    def _resume_tensors() -> dict[str, torch.Tensor]:
        return {"torch_rng": torch.get_rng_state(), "dropout_rng": dropout_rng.get_state(),
                "usage_ema": raw_model.quantizer.usage_ema}  # fmt: skip

    t0 = time.perf_counter()
    bar = tqdm(
        range(start, n_steps),
        disable=not (cfg.progress and accelerator.is_main_process),
        desc="unidextok",
        initial=start,
        total=n_steps,
    )
    for step in bar:
        lr = lr_at(step, n_steps, cfg.lr, cfg.warmup_steps, cfg.min_lr_ratio)
        for g in optimizer.param_groups:
            g["lr"] = lr
        rows = torch.from_numpy(sampler.sample(cfg.batch_size))
        x, m, h = states[rows].to(device), masks[rows].to(device), hand_ids[rows].to(device)  # (B, 22), (B, 22), (B,)
        if cfg.unknown_hand_prob > 0:  # hand-embedding dropout trains the zero-shot "unknown hand" path
            drop = torch.rand(h.shape, generator=dropout_rng).to(device) < cfg.unknown_hand_prob  # (B,)
            h = torch.where(drop, torch.full_like(h, raw_model.unknown_hand_id), h)

        out = model(x, h, mask=m)
        optimizer.zero_grad(set_to_none=True)
        accelerator.backward(out.loss)
        if cfg.grad_clip_norm > 0:
            accelerator.clip_grad_norm_(model.parameters(), cfg.grad_clip_norm)
        optimizer.step()
        if cfg.adapt == "all" and cfg.reseed_every > 0 and (step + 1) % cfg.reseed_every == 0:
            raw_model.quantizer.reseed_dead_codes()

        if step % 10 == 0:
            with torch.no_grad():
                err = (out.states_rad - x).abs()[m].mean().item()
            bar.set_postfix(
                loss=f"{out.loss.item():.4f}",
                mae_deg=f"{math.degrees(err):.2f}",
                usage=f"{raw_model.quantizer.last_usage:.2f}",
                lr=f"{lr:.1e}",
            )
        if (step + 1) % cfg.eval_every == 0 or step + 1 == n_steps:
            _evaluate(step + 1)
        if accelerator.is_main_process and ((step + 1) % cfg.save_last_every == 0 or step + 1 == n_steps):
            save_checkpoint(
                raw_model, last_dir, optimizer,
                {"step": step + 1, "best_mae_deg": best_mae, "best_step": best_step, "history": history,
                 "sampler_rng": sampler.rng.bit_generator.state},
                _resume_tensors(),
            )  # fmt: skip
    bar.close()
    if start >= n_steps and not history:
        _evaluate(n_steps)
    accelerator.wait_for_everyone()
    return TrainResult(best_dir, best_mae, best_step, n_steps, time.perf_counter() - t0, history)
