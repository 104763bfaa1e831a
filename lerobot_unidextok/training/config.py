"""Typed training configuration (draccus reads it from YAML / CLI).

A field's `--help` text is the comment on its line, else the docstring below it, else the comments above it;
the first field of each section has one of the first two, so the section divider stays out of its help.
"""

from dataclasses import dataclass, field

from lerobot_unidextok.tokenizer.configuration_unidextok import EncodingConfig, UniDexTokConfig
from lerobot_unidextok.training.coverage import CoverageConfig


@dataclass
class TrainConfig:
    """How to train (or adapt) a UniDexTok tokenizer."""

    # --- data -------------------------------------------------------------------------------------
    datasets: list[str] = field(default_factory=list)
    """Converted UDHM LeRobotDatasets: local roots, or repo ids resolved in HF_LEROBOT_HOME."""
    holdout: str = "auto"  # datasets without a recorded test split: auto (hash fallback, warned) | recorded | hash
    # Share of each hand in a batch (relative weights). Hands not listed get `default_hand_weight`.
    hand_weights: dict[str, float] = field(default_factory=dict)
    # 1.0 for every hand = balanced mixing; set 0 to train only on the hands listed in hand_weights.
    default_hand_weight: float = 1.0
    # Hands dropped from training (kept in evaluation): the zero-shot protocol.
    exclude_hands: list[str] = field(default_factory=list)
    # Coverage training: per hand kind, the weights of recorded rows vs states synthesised inside the hand's
    # joint ranges (training/coverage.py). `--coverage.robot='{"recorded": 1.0}'` trains on recordings only.
    coverage: CoverageConfig = field(default_factory=CoverageConfig)
    # Registered hands also trained without recordings, on states uniform inside their registered joint ranges
    # (both sides); `[all]` = every registered hand (minus exclude_hands). They join the vocabulary and the
    # hand mixing (`hand_weights`); hands with recordings keep their own coverage mixture.
    range_hands: list[str] = field(default_factory=list)
    # Training data larger than memory: read the rows from a memory-mapped per-hand store on disk
    # (`data.open_row_store`, built once from the datasets and reused while they are unchanged) instead
    # of loading every frame; same mixing and coverage. Checkpoint selection: up to `eval_max_frames` rows of
    # the held-out (select_fraction) training episodes; the test figures: up to `eval_max_frames` test rows.
    streaming: bool = False
    # where the stores go (a folder of row stores only: their train/ and test/ are rebuilt when out of date);
    # default <output_dir>/row_store
    row_store_dir: str = ""

    # --- model ------------------------------------------------------------------------------------
    preset: str = "small"  # UniDexTokConfig preset: paper | small | small_residual | tiny
    # Hands to give an embedding row besides the training hands, which always get one (listed first, then the
    # training hands). Other hands, e.g. those left out with exclude_hands, go through the unknown-hand row.
    hand_names: list[str] = field(default_factory=list)
    init_from: str | None = None  # start from a pretrained checkpoint (folder or repo id)
    # The encoding written into the saved checkpoints' config (`EncodingConfig`: how `encode` picks codes at use,
    # e.g. in unidextok-eval; docs/tokenizer.md "Code search"), e.g. --encoding.rounds=1. Training and checkpoint
    # selection always use the nearest codes. None = the preset's (nearest codes) or the init_from checkpoint's.
    encoding: EncodingConfig | None = None

    # --- optimisation -------------------------------------------------------------------------------
    steps: int = 5000  # optimiser steps (derived from `epochs` when that is > 0)
    batch_size: int = 256  # rows per step and process
    lr: float = 6e-3  # peak learning rate (the paper preset uses 5e-4: configs/train/paper.yaml)
    min_lr_ratio: float = 0.05  # cosine decays to lr * min_lr_ratio
    warmup_steps: int = 200  # linear warmup from 0 to lr
    weight_decay: float = 0.01  # not applied to codebooks, norms, embeddings, biases
    betas: tuple[float, float] = (0.9, 0.99)  # AdamW betas
    grad_clip_norm: float = 1.0  # gradient norm clip (0 disables)
    reseed_every: int = 50  # dead-code re-seeding period in steps (0 disables)
    # Share of the steps after which dead codes are no longer re-seeded: a re-seeded code takes states from its
    # neighbours, which the decoder must then relearn; near the end of training there are no steps left for it.
    reseed_until: float = 1.0
    # Share of training rows conditioned on the "unknown hand" embedding instead of their own hand
    # (hand-embedding dropout, as classifier-free guidance drops its condition). Without it that
    # embedding is never trained and zero-shot tokenisation of unseen hands is meaningless.
    # Not in the paper, which does not say how its unknown-hand path is trained.
    unknown_hand_prob: float = 0.05
    seed: int = 0  # seeds the model, the batches and the splits

    # --- evaluation and checkpoints ----------------------------------------------------------------
    select_fraction: float = 0.1
    """Share of each hand's training-split episodes held out (whole episodes) to choose `best`; the reported
    figures come from the datasets' test episodes. 0 = no selection, `best` is the final model."""
    # k-fold over episodes (small datasets): when >= 2, also train `folds` models, each scored on the episodes
    # of one fold (train + test splits pooled), and report mean and spread (output_dir/kfold.{json,md}).
    folds: int = 0
    eval_every: int = 250  # steps between checkpoint-selection evaluations
    eval_max_frames: int = 20000  # held-out rows used for checkpoint selection (all if fewer)
    output_dir: str = "outputs/unidextok"  # run folder: best/, last/, eval.{json,md}
    resume: bool = False  # continue from output_dir/last (model, optimiser, step)
    # replace the run already at output_dir: the new run trains in a hidden folder beside it and takes its place
    # only when it has finished (a failing run leaves the old one as it was; files the user added are kept);
    # without it (or --resume), an existing run is refused, never replaced
    overwrite: bool = False
    save_last_every: int = 500  # steps between saves of output_dir/last

    # --- few-shot adaptation ------------------------------------------------------------------------
    fraction: float = 1.0  # share of the training episodes trained on (few-shot: a small share, whole episodes)
    epochs: float = 0.0  # when > 0: train this many passes over those rows (steps is then derived)
    # What adaptation trains: "all" parameters, or only the "hand_embedding" (the shared encoder, codebook
    # and decoder stay as they are, so a few hundred frames cannot overfit them).
    adapt: str = "all"

    # --- runtime ------------------------------------------------------------------------------------
    device: str = "cpu"
    """cpu | cuda | cuda:N. Several processes: `accelerate launch --multi_gpu --num_processes=N -m
    lerobot_unidextok.scripts.train ...` (also on CPU with --device=cpu: gloo) or `torchrun`; each process
    draws its own `batch_size` rows, so the effective batch is batch_size x N (docs/tokenizer.md)"""
    # torch CPU threads while training (0 = torch default). 1 by default: these models are small, and extra
    # intra-op threads slow them down on shared CPUs.
    num_threads: int = 1
    progress: bool = True  # tqdm bar

    def __post_init__(self) -> None:
        if self.encoding is not None and self.init_from is None:  # checked with the preset, before any data loads
            UniDexTokConfig.from_preset(self.preset, encoding=self.encoding)  # e.g. residual stages take rounds=0
        if not 0.0 < self.fraction <= 1.0:
            raise ValueError(f"fraction must be in (0, 1], got {self.fraction}")
        if self.steps < 1 and self.epochs <= 0:
            raise ValueError(f"steps must be >= 1 (or set epochs > 0), got {self.steps}")
        if not 0.0 <= self.unknown_hand_prob < 1.0:
            raise ValueError(f"unknown_hand_prob must be in [0, 1), got {self.unknown_hand_prob}")
        if self.adapt not in ("all", "hand_embedding"):
            raise ValueError(f"adapt must be 'all' or 'hand_embedding', got {self.adapt!r}")
        if not 0.0 <= self.select_fraction < 1.0:
            raise ValueError(f"select_fraction must be in [0, 1), got {self.select_fraction}")
        if self.folds == 1 or self.folds < 0:
            raise ValueError(f"folds must be 0 (off) or >= 2, got {self.folds}")
        if self.streaming and self.fraction < 1.0:
            raise ValueError(
                "--streaming is for large training sets; few-shot (--fraction < 1) trains on a few episodes "
                "in memory: drop --streaming"
            )
        if self.streaming and self.folds:
            raise ValueError("--folds is for small datasets, held in memory: drop --streaming or --folds")
        if not 0.0 <= self.reseed_until <= 1.0:
            raise ValueError(f"reseed_until must be in [0, 1], got {self.reseed_until}")
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {self.batch_size}")
        if self.warmup_steps < 0:
            raise ValueError(f"warmup_steps must be >= 0, got {self.warmup_steps}")
        bad = {h: w for h, w in self.hand_weights.items() if w < 0}
        if bad or self.default_hand_weight < 0:
            raise ValueError(f"hand weights must be >= 0, got {bad or self.default_hand_weight}")
        self.betas = tuple(self.betas)
