"""`unidextok-train`: train or adapt a UniDexTok tokenizer on converted UDHM datasets.

    unidextok-train --config_path=configs/train/small.yaml --datasets='[data/sample_mixture]'
    unidextok-train --preset=tiny --steps=300 --datasets='[me/dexycb_udhm]' --output_dir=outputs/tiny
    # few-shot: 6 % of an unseen hand's frames for 2 epochs, starting from a trained tokenizer
    unidextok-train --init_from=outputs/small/best --datasets='[data/inspire]' --fraction=0.062 --epochs=2
    # training data larger than memory: a memory-mapped per-hand row store instead of loading every frame
    unidextok-train --config_path=configs/train/small.yaml --datasets='[...]' --streaming=true
    # several processes (effective batch = batch_size x processes); on CPU too (--device=cpu, gloo):
    accelerate launch --multi_gpu --num_processes=4 -m lerobot_unidextok.scripts.train --device=cuda ...
    torchrun --nproc_per_node=2 -m lerobot_unidextok.scripts.train --device=cpu ...

Writes output_dir/best (lowest held-out joint MAE in degrees), output_dir/last (resume), and the
per-hand evaluation of best as output_dir/eval.{json,md}.
"""

import logging
from pathlib import Path

import draccus

from lerobot_unidextok.training import HandStates, TrainConfig, load_hand_states, subsample_episodes, train_tokenizer


def load_splits(cfg: TrainConfig):
    """(train rows, held-out rows) of `cfg.datasets`: in memory, or with `cfg.streaming` a memory-mapped
    row store for training (built by the main process first) and up to `eval_max_frames` held-out rows."""
    if not cfg.streaming:
        train = load_hand_states(cfg.datasets, split="train", holdout=cfg.holdout)
        test = load_hand_states(cfg.datasets, split="test", holdout=cfg.holdout)
        if cfg.exclude_hands:
            train = train.without(cfg.exclude_hands)
        return subsample_episodes(train, cfg.fraction, seed=cfg.seed), test
    from accelerate import PartialState

    from lerobot_unidextok.data import open_row_store

    folder = Path(cfg.row_store_dir or Path(cfg.output_dir) / "row_store")
    with PartialState(cpu=cfg.device == "cpu").main_process_first():  # one process builds, the others open
        train = open_row_store(cfg.datasets, "train", folder / "train", cfg.holdout)
        test = open_row_store(cfg.datasets, "test", folder / "test", cfg.holdout)
    if cfg.exclude_hands:
        train = train.without(cfg.exclude_hands)
    held_out = test.sample_rows(cfg.eval_max_frames, seed=cfg.seed)
    return train, HandStates(held_out["states_rad"], held_out["hands"], held_out["masks"], held_out["episode_index"])


def run(cfg: TrainConfig) -> dict:
    """Load splits, train, evaluate the selected checkpoint; returns the evaluation report (in the main
    process; {} in the others of a multi-process run, which only train)."""
    from accelerate import PartialState

    from lerobot_unidextok.evaluation.report import evaluate_tokenizer, write_report
    from lerobot_unidextok.tokenizer import UniDexTok

    train, test = load_splits(cfg)
    result = train_tokenizer(cfg, train, test)
    if not PartialState().is_main_process:
        return {}
    model = UniDexTok.from_pretrained(result.best_dir)
    report = evaluate_tokenizer(model, test)
    report["training"] = {
        "best_step": result.best_step, "best_mae_deg": result.best_mae_deg, "steps": result.steps,
        "seconds": result.seconds, "train_rows": len(train), "test_rows": len(test), "preset": cfg.preset,
        "excluded_hands": cfg.exclude_hands, "fraction": cfg.fraction, "streaming": cfg.streaming,
        "processes": PartialState().num_processes,
    }  # fmt: skip
    md = write_report(report, Path(cfg.output_dir) / "eval")
    print(md)
    return report


@draccus.wrap()
def train_cli(cfg: TrainConfig) -> None:
    run(cfg)


def main() -> None:
    # force: importing lerobot already gave the root logger a WARNING handler (a module-level logging.debug
    # call in lerobot.utils.import_utils), which would make this a no-op and hide our INFO lines
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s", force=True)
    train_cli()


if __name__ == "__main__":
    main()
