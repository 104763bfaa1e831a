"""`unidextok-train`: train or adapt a UniDexTok tokenizer on converted UDHM datasets.

    unidextok-train --config_path=train/small --datasets='[data/sample_mixture]'
    unidextok-train --preset=tiny --steps=300 --datasets='[me/dexycb_udhm]' --output_dir=outputs/tiny
    # zero-shot: leave a hand out (it is not in the vocabulary; unidextok-eval scores it zero-shot)
    unidextok-train --config_path=train/small --datasets='[...]' --exclude_hands='[inspire_rh56_unitree]'
    # few-shot: 6 % of an unseen hand's frames for 2 epochs, starting from a trained tokenizer
    unidextok-train --config_path=train/fewshot --init_from=outputs/small/best --datasets='[data/inspire]'
    # small datasets: also k-fold over episodes (mean and spread of the held-out figures)
    unidextok-train --config_path=train/small --datasets='[data/g1]' --folds=5
    # training data larger than memory: a memory-mapped per-hand row store instead of loading every frame
    unidextok-train --config_path=train/small --datasets='[...]' --streaming=true
    # several processes (effective batch = batch_size x processes); on CPU too (--device=cpu, gloo):
    accelerate launch --multi_gpu --num_processes=4 -m lerobot_unidextok.scripts.train --device=cuda ...
    torchrun --nproc_per_node=2 -m lerobot_unidextok.scripts.train --device=cpu ...

Training uses each dataset's train-split episodes; `select_fraction` of them (whole episodes) choose the
checkpoint; the figures come from the test-split episodes, which training never sees. Writes
output_dir/best (use this one), output_dir/last (resume with --resume=true), each with a model card
(README.md), and the per-hand evaluation of best on the test episodes as output_dir/eval.{json,md}.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging
from pathlib import Path

from lerobot_unidextok.training import TrainConfig
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap


def run(cfg: TrainConfig) -> dict:
    """`training.run.train_and_evaluate`, then print its summary and where the checkpoints are."""
    from lerobot_unidextok.training.run import train_and_evaluate  # torch: not needed for --help

    report, md = train_and_evaluate(cfg)
    if not report:  # another process of a multi-process run
        return report
    out = Path(cfg.output_dir)
    print(md)
    print(
        f"\nCheckpoints in {out}:\n  {out / 'best'}  <- use this one (unidextok-eval --checkpoint={out}, "
        f"UniDexTok.from_pretrained('{out / 'best'}'), unidextok-push)\n  {out / 'last'}  <- resume training "
        "with --resume=true"
    )
    return report


@wrap()
def train_cli(cfg: TrainConfig) -> None:
    run(cfg)


def main() -> None:
    # force: importing lerobot already gave the root logger a WARNING handler (a module-level logging.debug
    # call in lerobot.utils.import_utils), which would make this a no-op and hide our INFO lines
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s", force=True)
    run_cli(train_cli)


if __name__ == "__main__":
    main()
