"""The tokenizer training loop over per-hand rows, in memory or memory-mapped (one process, or several
through `accelerate launch` / `torchrun`: see `training/distributed.py`)."""

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.data.rowstore import HandRowStore
from lerobot_unidextok.errors import ConfigError, MissingInputError
from lerobot_unidextok.evaluation.metrics import mpjae_deg
from lerobot_unidextok.evaluation.reconstruct import codebook_usage, reconstruct
from lerobot_unidextok.tokenizer import NEAREST_CODES, UniDexTok, UniDexTokConfig
from lerobot_unidextok.training.arrays import HandStates
from lerobot_unidextok.training.checkpoint import (
    check_checkpoint,
    load_optimizer_state,
    load_resume_tensors,
    save_checkpoint,
)
from lerobot_unidextok.training.config import TrainConfig
from lerobot_unidextok.training.coverage import (
    MixtureSampler,
    hand_ranges_rad,
    range_only_table,
    recorded_tables,
    resolve_range_hands,
)
from lerobot_unidextok.training.distributed import broadcast_from_main, check_replicas, leave_at_exit
from lerobot_unidextok.training.optim import lr_at, make_optimizer
from lerobot_unidextok.utils.cli import progress_bar
from lerobot_unidextok.utils.files import recover_folder

logger = logging.getLogger(__name__)


@dataclass
class TrainResult:
    """Where the selected checkpoint is and how training went."""

    best_dir: Path
    best_mae_deg: float  # on the selection rows; nan without them
    best_step: int
    steps: int
    seconds: float
    history: list[dict] = field(default_factory=list)  # one entry per evaluation


def training_vocabulary(cfg: TrainConfig, train_data: HandStates) -> list[str]:
    """Hand vocabulary of a new model: the hands explicitly requested (`hand_names`) then the training hands.

    The preset's default list is not used, so a hand left out of training (`exclude_hands`, zero-shot) is
    not in the vocabulary and goes through the unknown-hand embedding.
    """
    clash = sorted(set(cfg.hand_names) & set(cfg.exclude_hands))
    if clash:
        raise ValueError(
            f"hands {clash} are both requested in hand_names and excluded by exclude_hands; a hand excluded for "
            "zero-shot must not get its own (untrained) embedding row: drop it from one of the two"
        )
    return list(dict.fromkeys([*cfg.hand_names, *train_data.hand_names(), *resolve_range_hands(cfg.range_hands,
                                                                                              cfg.exclude_hands)]))


def joint_ranges_rad(
    train_data: HandStates | HandRowStore, chunk_rows: int = 1 << 20, range_hands: list[str] | tuple[str, ...] = ()
) -> list[list[float]]:
    """(22, 2) per-joint [lo, hi] covering every training hand's joint range (registry) and recorded rows
    (read in chunks of `chunk_rows`, so a memory-mapped store is never loaded whole), and the registered
    ranges of `range_hands`."""
    lo, hi = np.full(UDHM_DIM, np.inf), np.full(UDHM_DIM, -np.inf)
    for hand in range_hands:
        _, hlo, hhi = range_only_table(hand)
        lo, hi = np.minimum(lo, hlo.min(0)), np.maximum(hi, hhi.max(0))
    for hand, rows, masks, take in recorded_tables(train_data):
        index = np.arange(len(rows)) if take is None else take
        mask = np.zeros(UDHM_DIM, dtype=bool)
        for start in range(0, len(index), chunk_rows):
            part = index[start : start + chunk_rows]
            x = np.asarray(rows[part], dtype=np.float64)  # (n, 22)
            lo, hi = np.minimum(lo, x.min(0)), np.maximum(hi, x.max(0))
            mask |= np.asarray(masks[part]).any(0)
        hlo, hhi, _ = hand_ranges_rad(hand, mask, x)  # `x` only matters for unregistered hands, inside lo..hi
        lo, hi = np.minimum(lo, hlo.min(0)), np.maximum(hi, hhi.max(0))
    return [[float(a), float(b)] for a, b in zip(lo, hi, strict=True)]


def build_model(cfg: TrainConfig, train_data: HandStates | HandRowStore, **overrides) -> UniDexTok:
    """A fresh model from the preset (with `overrides` of its fields), or `init_from` with new training hands.

    Vocabulary: `training_vocabulary`. With `input_norm="range"` the joint ranges come from the training
    hands (`joint_ranges_rad`) unless given.
    """
    if cfg.init_from:
        model = UniDexTok.from_pretrained(cfg.init_from, encoding=cfg.encoding)
        model.add_hands([*cfg.hand_names, *train_data.hand_names(), *resolve_range_hands(cfg.range_hands,
                                                                                         cfg.exclude_hands)])
        return model
    preset = UniDexTokConfig.from_preset(cfg.preset)
    if overrides.get("input_norm", preset.input_norm) == "range" and "joint_range_rad" not in overrides:
        overrides["joint_range_rad"] = joint_ranges_rad(
            train_data, range_hands=resolve_range_hands(cfg.range_hands, cfg.exclude_hands)
        )
    if cfg.encoding is not None:
        overrides.setdefault("encoding", cfg.encoding)
    return UniDexTok(
        UniDexTokConfig.from_preset(cfg.preset, hand_names=training_vocabulary(cfg, train_data), **overrides)
    )


def evaluate_mae_deg(model: UniDexTok, data: HandStates, max_frames: int, seed: int) -> tuple[float, dict]:
    """Held-out joint MAE (deg, active DoFs) and codebook usage on up to `max_frames` rows."""
    if len(data) > max_frames:
        rows = np.sort(np.random.default_rng(seed).choice(len(data), max_frames, replace=False))
        data = data.select(rows)
    # the nearest codes (what training optimises), whatever code search the model's config asks for at use
    rec = reconstruct(model, data.states_rad, data.hands, allow_unknown=True, masks=data.masks, encoding=NEAREST_CODES)
    return mpjae_deg(rec.states_rad, data.states_rad, data.masks), codebook_usage(rec.codes, model.config.codebook_size)


def total_steps(cfg: TrainConfig, num_train_rows: int, num_processes: int = 1) -> int:
    if cfg.epochs > 0:  # an epoch = the training rows once at the effective batch size
        return max(1, math.ceil(cfg.epochs * num_train_rows / (cfg.batch_size * num_processes)))
    return cfg.steps


def train_tokenizer(
    cfg: TrainConfig,
    train_data: HandStates | HandRowStore,
    eval_data: HandStates | None,
    model: UniDexTok | None = None,
) -> TrainResult:
    """Train (or adapt) a tokenizer.

    `eval_data`: held-out rows (whole episodes the model never trains on) that choose `output_dir/best`, the
    checkpoint with the lowest joint MAE (deg). None or empty: no selection, `best` is the final model.
    """

    if len(train_data) == 0:
        raise ValueError("need training rows, got none")
    threads_before = torch.get_num_threads()
    if cfg.num_threads > 0:
        torch.set_num_threads(cfg.num_threads)
    try:
        return _train(cfg, train_data, eval_data if eval_data is not None and len(eval_data) else None, model)
    finally:
        torch.set_num_threads(threads_before)


def _train(
    cfg: TrainConfig, train_data: HandStates | HandRowStore, eval_data: HandStates | None, model: UniDexTok | None
) -> TrainResult:
    from accelerate import Accelerator

    accelerator = Accelerator(cpu=cfg.device == "cpu")
    if accelerator.num_processes > 1:  # close the group before the interpreter ends (training/distributed.py)
        leave_at_exit()
    torch.manual_seed(cfg.seed + accelerator.process_index)
    out = Path(cfg.output_dir)
    best_dir, last_dir = out / "best", out / "last"

    state = _resume_state(cfg, last_dir, train_data) if cfg.resume else {}
    model = _prepare_model(cfg, train_data, model, last_dir)
    optimizer = make_optimizer(model, cfg.lr, cfg.weight_decay, cfg.betas)
    n_steps = total_steps(cfg, len(train_data), accelerator.num_processes)
    selection = _Selection(best_dir)
    start = 0
    if cfg.resume:
        load_optimizer_state(optimizer, last_dir)
        start = state["step"]
        selection = _Selection(best_dir, state["best_mae_deg"], state["best_step"], state["history"])
    model, optimizer = accelerator.prepare(model, optimizer)
    raw_model: UniDexTok = accelerator.unwrap_model(model)

    # seeded as at step 0 also when resuming: the saved generator states (below) continue the same streams
    sampler = MixtureSampler(
        train_data,
        cfg.hand_weights,
        cfg.default_hand_weight,
        cfg.coverage,
        seed=cfg.seed * 1000 + accelerator.process_index,  # each process draws its own batches
        range_hands=resolve_range_hands(cfg.range_hands, cfg.exclude_hands),
    )
    mixture = sampler.describe()
    logger.info(
        "training %d steps on %d recorded rows; batch %d x %d processes = %d; mixture %s",
        n_steps, len(train_data), cfg.batch_size, accelerator.num_processes,
        cfg.batch_size * accelerator.num_processes, mixture,
    )  # fmt: skip
    hand_id_of = torch.tensor([raw_model.hand_id(h) for h in sampler.hand_names])  # sampler hand -> model id
    about = _about(cfg, n_steps, sampler.hand_names, mixture, eval_data, len(train_data), train_data.hand_names())

    def _evaluate(step: int) -> None:
        if accelerator.is_main_process and eval_data is not None:
            selection.evaluate(raw_model, eval_data, step, cfg, about)

    dropout_rng = torch.Generator().manual_seed(cfg.seed * 1000 + 1 + 7919 * accelerator.process_index)
    if cfg.resume:
        _restore_random_streams(cfg, last_dir, state, sampler, dropout_rng, raw_model, accelerator.num_processes,
                                accelerator.process_index, start)  # fmt: skip

    t0 = time.perf_counter()
    bar = progress_bar(
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
        batch = sampler.sample(cfg.batch_size)
        x = torch.from_numpy(batch.states_rad).to(accelerator.device)  # (B, 22)
        m = torch.from_numpy(batch.masks).to(accelerator.device)  # (B, 22)
        h = hand_id_of[torch.from_numpy(batch.hands)].to(accelerator.device)  # (B,)
        out = _optimisation_step(cfg, model, optimizer, accelerator, x, h, m, dropout_rng)
        _sync_codebooks(cfg, raw_model, step, n_steps, accelerator.num_processes)

        if step % 10 == 0:
            _show_progress(bar, out, x, m, raw_model, lr)
        if (step + 1) % cfg.eval_every == 0 or step + 1 == n_steps:
            check_replicas(raw_model, step + 1)  # every process; raises if the copies drifted apart
            _evaluate(step + 1)
        if accelerator.is_main_process and ((step + 1) % cfg.save_last_every == 0 or step + 1 == n_steps):
            save_checkpoint(
                raw_model, last_dir, optimizer,
                {"step": step + 1, **selection.state(), **about, "sampler_rng": sampler.rng.bit_generator.state},
                {"torch_rng": torch.get_rng_state(), "dropout_rng": dropout_rng.get_state(),
                 "usage_ema": raw_model.quantizer.usage_ema},
            )  # fmt: skip
    bar.close()
    if start >= n_steps and not selection.history:
        _evaluate(n_steps)
    if eval_data is None and accelerator.is_main_process:  # no held-out rows: the final model is kept
        selection.best_step = n_steps
        save_checkpoint(raw_model, best_dir, state={"step": n_steps, "eval_mae_deg": None, **about})
    accelerator.wait_for_everyone()
    best_mae = selection.best_mae if math.isfinite(selection.best_mae) else float("nan")
    return TrainResult(best_dir, best_mae, selection.best_step, n_steps, time.perf_counter() - t0, selection.history)


# ---------------------------------------------------------------------------------------------
# the parts of a run
# ---------------------------------------------------------------------------------------------
def _prepare_model(
    cfg: TrainConfig, train_data: HandStates | HandRowStore, model: UniDexTok | None, last_dir: Path
) -> UniDexTok:
    """The model to train: given, built, or resumed from `last_dir`; with every training hand in its
    vocabulary, in training mode, and only the parameters `cfg.adapt` names trainable."""
    if model is None:
        model = build_model(cfg, train_data)
    elif cfg.hand_names:
        model.add_hands(cfg.hand_names)
    if cfg.resume:
        model = UniDexTok.from_pretrained(last_dir)
    trained = list(dict.fromkeys([*train_data.hand_names(), *resolve_range_hands(cfg.range_hands, cfg.exclude_hands)]))
    unknown = [h for h in trained if not model.knows_hand(h)]
    if unknown:
        model.add_hands(unknown)
    # the hands this checkpoint has been trained on (vocabulary rows of other hands were never trained)
    model.config.trained_hands = list(dict.fromkeys([*model.config.trained_hands, *trained]))
    model.train()
    if cfg.adapt != "all":
        model.quantizer.eval()  # no EMA codebook or usage updates: the shared parts stay as they are
    for name, param in model.named_parameters():
        trainable = cfg.adapt == "all" or name.startswith("hand_embed")
        if name == "quantizer.codebooks" and model.config.codebook_update == "ema":
            trainable = False  # moved by the EMA update, not by the optimiser
        param.requires_grad_(trainable)
    return model


def _resume_state(cfg: TrainConfig, last_dir: Path, train_data: HandStates | HandRowStore) -> dict:
    """The training state `--resume` continues from, once the checkpoint is whole (`check_checkpoint`) and was
    trained with this run's preset on the same training rows; a clear error otherwise."""
    for note in recover_folder(last_dir):
        logger.warning(note)
    if not (last_dir / "config.json").is_file():
        raise MissingInputError(f"--resume: no checkpoint at {last_dir}; run once without --resume first")
    state = check_checkpoint(last_dir)
    if state.get("preset") not in (None, cfg.preset):
        raise ConfigError(
            f"--resume: {last_dir} was trained with --preset={state['preset']}, this run asks for "
            f"--preset={cfg.preset}; resume with --preset={state['preset']}, or train into another --output_dir"
        )
    rows, hands = len(train_data), train_data.hand_names()
    saved = state.get("train_rows"), state.get("train_hands")
    if saved[0] is not None and saved != (rows, hands):
        raise ConfigError(
            f"--resume: {last_dir} was trained on {saved[0]} rows of hands {saved[1]}, this run reads {rows} rows "
            f"of hands {hands} (other --datasets, --fraction or split); resume with the run's own data, or train "
            "into another --output_dir"
        )
    return state


def _about(cfg: TrainConfig, n_steps: int, hands: list[str], mixture: dict, eval_data: HandStates | None,
           n_rows: int, train_hands: list[str]) -> dict:
    """What this run trains on; saved with every checkpoint (training_state.json) for the model card."""
    return {
        "preset": cfg.preset, "init_from": cfg.init_from, "adapt": cfg.adapt, "steps": n_steps,
        "train_rows": n_rows, "train_hands": train_hands,
        "batch_size": cfg.batch_size, "lr": cfg.lr, "unknown_hand_prob": cfg.unknown_hand_prob,
        "hands_trained": hands, "mixture": mixture,
        "selection": {"rows": len(eval_data), "hands": eval_data.hand_names()} if eval_data is not None
        else "none: best = the final model",
    }  # fmt: skip


def _optimisation_step(cfg: TrainConfig, model, optimizer, accelerator, x: torch.Tensor, h: torch.Tensor,
                       m: torch.Tensor, dropout_rng: torch.Generator):  # fmt: skip
    """Forward, backward, clip, step on one batch (x, m (B, 22), h (B,) hand ids); returns the model output.
    Hand dropout (a share of rows conditioned on the "unknown hand" row) trains the zero-shot path."""
    out = model(x, h, mask=m, hand_drop_prob=cfg.unknown_hand_prob, generator=dropout_rng)
    optimizer.zero_grad(set_to_none=True)
    accelerator.backward(out.loss)
    if cfg.grad_clip_norm > 0:
        accelerator.clip_grad_norm_(model.parameters(), cfg.grad_clip_norm)
    optimizer.step()
    return out


@dataclass
class _Selection:
    """Checkpoint selection: evaluations so far and the best one, saved to `best_dir`."""

    best_dir: Path
    best_mae: float = float("inf")
    best_step: int = -1
    history: list[dict] = field(default_factory=list)

    def evaluate(self, model: UniDexTok, eval_data: HandStates, step: int, cfg: TrainConfig, about: dict) -> None:
        mae, usage = evaluate_mae_deg(model, eval_data, cfg.eval_max_frames, cfg.seed)
        self.history.append({"step": step, "eval_mae_deg": mae, **{f"eval_{k}": v for k, v in usage.items()}})
        if mae < self.best_mae:
            self.best_mae, self.best_step = mae, step
            save_checkpoint(model, self.best_dir, state={"step": step, "eval_mae_deg": mae, **about})
        logger.info(
            "step %d: held-out MAE %.3f deg (best %.3f @ %d), usage %.2f",
            step,
            mae,
            self.best_mae,
            self.best_step,
            usage["usage"],
        )

    def state(self) -> dict:
        """What `last/training_state.json` keeps of it for a resume."""
        return {"best_mae_deg": self.best_mae, "best_step": self.best_step, "history": self.history}


def _restore_random_streams(
    cfg: TrainConfig,
    last_dir: Path,
    state: dict,
    sampler: MixtureSampler,
    dropout_rng: torch.Generator,
    model: UniDexTok,
    num_processes: int,
    process_index: int,
    start: int,
) -> None:
    """Continue the random streams where the checkpoint left them, so resume == an uninterrupted run."""
    saved = load_resume_tensors(last_dir)
    if "sampler_rng" in state and saved and num_processes == 1:
        sampler.rng.bit_generator.state = state["sampler_rng"]
        torch.set_rng_state(saved["torch_rng"])
        dropout_rng.set_state(saved["dropout_rng"])
        model.quantizer.usage_ema.copy_(saved["usage_ema"])
    else:  # only process 0's streams are saved: each process restarts its own from (seed, step, process)
        offset = cfg.seed * 1000 + 7919 * process_index + 104729 * start
        sampler.rng = np.random.default_rng(offset)
        dropout_rng.manual_seed(offset + 1)
        logger.warning("%s: resuming with fresh random streams (%s): the resumed run draws other batches than "
                       "an uninterrupted one would", last_dir,
                       "several processes" if saved else "older checkpoint")  # fmt: skip


def _sync_codebooks(cfg: TrainConfig, model: UniDexTok, step: int, n_steps: int, num_processes: int) -> None:
    """After an optimiser step: re-seed dead codes on schedule (until `reseed_until` of the steps); keep every
    process on process 0's codes."""
    reseeding = cfg.adapt == "all" and cfg.reseed_every > 0 and step < cfg.reseed_until * n_steps
    if reseeding and (step + 1) % cfg.reseed_every == 0:
        model.reseed_dead_codes()  # every quantiser stage
        for vq in model.quantizers:
            broadcast_from_main(vq)  # re-seeded from each process's own batch: keep process 0's
    elif model.config.codebook_update == "ema" and num_processes > 1:
        for vq in model.quantizers:
            broadcast_from_main(vq)  # EMA codes move with each process's batch: keep process 0's


def _show_progress(bar, out, x: torch.Tensor, m: torch.Tensor, model: UniDexTok, lr: float) -> None:
    with torch.no_grad():
        err = (out.states_rad - x).abs()[m].mean().item()
    bar.set_postfix(
        loss=f"{out.loss.item():.4f}",
        mae_deg=f"{math.degrees(err):.2f}",
        usage=f"{model.quantizer.last_usage:.2f}",
        lr=f"{lr:.1e}",
    )
