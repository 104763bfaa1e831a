"""Process set-up shared by the experiment CLIs: logging, headless matplotlib, one torch thread."""

import logging
import os

from lerobot_unidextok.experiments.config import ExperimentConfig


def setup(cfg: ExperimentConfig) -> ExperimentConfig:
    """One torch thread: these models are small and extra threads are ~10x slower on shared cores."""
    import torch

    os.environ.setdefault("MPLBACKEND", "Agg")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    torch.set_num_threads(1)
    torch.manual_seed(cfg.seed)
    return cfg
