"""`unidextok-train`: train or adapt a UniDexTok tokenizer on converted UDHM datasets.

    unidextok-train --config_path=configs/train/small.yaml --datasets='[data/sample_mixture]'
    unidextok-train --preset=tiny --steps=300 --datasets='[me/dexycb_udhm]' --output_dir=outputs/tiny
    # few-shot: 6 % of an unseen hand's frames for 2 epochs, starting from a trained tokenizer
    unidextok-train --init_from=outputs/small/best --datasets='[data/inspire]' --fraction=0.062 --epochs=2
    # multi-GPU: accelerate launch --num_processes=4 -m lerobot_unidextok.scripts.train --device=cuda ...

Writes output_dir/best (lowest held-out joint MAE in degrees), output_dir/last (resume), and the
per-hand evaluation of best as output_dir/eval.{json,md}.
"""

import logging
from pathlib import Path

import draccus

from lerobot_unidextok.training import TrainConfig, load_hand_states, subsample_episodes, train_tokenizer


def run(cfg: TrainConfig) -> dict:
    """Load splits, train, evaluate the selected checkpoint; returns the evaluation report."""
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer, write_report
    from lerobot_unidextok.tokenizer import UniDexTok

    train = load_hand_states(cfg.datasets, split="train", holdout=cfg.holdout)
    test = load_hand_states(cfg.datasets, split="test", holdout=cfg.holdout)
    if cfg.exclude_hands:
        train = train.without(cfg.exclude_hands)
    train = subsample_episodes(train, cfg.fraction, seed=cfg.seed)
    result = train_tokenizer(cfg, train, test)
    model = UniDexTok.from_pretrained(result.best_dir)
    report = evaluate_tokenizer(model, test)
    report["training"] = {
        "best_step": result.best_step, "best_mae_deg": result.best_mae_deg, "steps": result.steps,
        "seconds": result.seconds, "train_rows": len(train), "test_rows": len(test), "preset": cfg.preset,
        "excluded_hands": cfg.exclude_hands, "fraction": cfg.fraction,
    }  # fmt: skip
    md = write_report(report, Path(cfg.output_dir) / "eval")
    print(md)
    return report


@draccus.wrap()
def train_cli(cfg: TrainConfig) -> None:
    run(cfg)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    train_cli()


if __name__ == "__main__":
    main()
