"""Process set-up shared by the experiment CLIs: logging, headless matplotlib, one torch thread."""

import logging
import os
from collections.abc import Callable

from experiments.config import ExperimentConfig


def _process() -> None:
    """One torch thread: these models are small and extra threads are ~10x slower on shared cores."""
    import torch

    os.environ.setdefault("MPLBACKEND", "Agg")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    torch.set_num_threads(1)


def setup(cfg: ExperimentConfig) -> ExperimentConfig:
    import torch

    _process()
    torch.manual_seed(cfg.seed)
    return cfg


def parse[T](config_cls: type[T], argv: list[str] | None = None) -> T:
    """draccus, like the CLIs and the other experiments: `--<field>=<value>`, lists as `--variants='[a,b]'`."""
    import draccus

    return draccus.parse(config_cls, args=argv)


def cli[T](
    config_cls: type[T], run: Callable[[T], dict], markdown: Callable[[dict], str], argv: list[str] | None
) -> None:
    """An experiment's command line: parse its config, set the process up, run it, print its Markdown."""
    cfg = parse(config_cls, argv)
    _process()
    print(markdown(run(cfg)))
