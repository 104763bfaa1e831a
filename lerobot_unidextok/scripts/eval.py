"""`unidextok-eval`: per-hand MPJAE / MPJPE / fingertip error and codebook usage of a tokenizer.

    unidextok-eval --checkpoint=outputs/small --datasets='[data/sample_mixture]'   # a run folder: uses best/
    unidextok-eval --checkpoint=outputs/small/best --datasets='[data/sample_mixture]'
    unidextok-eval --checkpoint=me/unidextok-small --datasets='[me/inspire_udhm]' --split=test
    unidextok-eval --checkpoint=unidextok/universal-small --datasets='[data/g1]' --encoding.rounds=0   # nearest codes

Hands the checkpoint never saw are evaluated zero-shot (unknown-hand embedding) and flagged.
Writes <output>.json and <output>.md and prints them: first what was scored (the checkpoint folder, and per
dataset the episodes of the split and their hand-rows: one row per hand per frame, so a two-hand frame gives
two rows), then the per-hand table.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.tokenizer.configuration_unidextok import EncodingConfig
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap

logger = logging.getLogger(__name__)


@dataclass
class EvalConfig:
    # tokenizer folder (config.json + model.safetensors), a `unidextok-train` run folder (its best/), or a repo id
    checkpoint: str = ""
    datasets: list[str] = field(default_factory=list)  # converted UDHM datasets: local roots or repo ids
    split: str = "test"  # train | test | all
    holdout: str = "auto"  # datasets without a recorded test split (lerobot-edit-dataset): auto | recorded | hash
    hands: list[str] = field(default_factory=list)  # evaluate only these hands (empty = all)
    # How to pick codes instead of the checkpoint's own encoding (docs/tokenizer.md "Code search"): unset = the
    # checkpoint's; --encoding.rounds=0 = each group's nearest code (the paper's encoding); an override replaces
    # the whole encoding (--encoding.rounds=2 --encoding.tolerance_deg=0.1 ...).
    encoding: EncodingConfig | None = None
    output: str = "outputs/unidextok_eval/eval"  # path stem of the .json / .md report
    device: str = "cpu"

    def __post_init__(self) -> None:
        if not self.checkpoint:
            raise InvalidInputError("--checkpoint is required (a folder with config.json + model.safetensors, a "
                             "unidextok-train run folder, unidextok/universal-small, or a Hub repo id)")  # fmt: skip
        if self.split not in ("train", "test", "all"):
            raise InvalidInputError(f"--split must be train, test or all, got {self.split!r}")


def run(cfg: EvalConfig) -> dict:
    from lerobot_unidextok.evaluation import evaluate_tokenizer, write_report
    from lerobot_unidextok.evaluation.report import claim_report, describe_scored
    from lerobot_unidextok.pretrained import resolve
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import load_hand_states

    claim_report(cfg.output, inputs=[Path(d) for d in cfg.datasets if Path(d).expanduser().exists()])
    data = load_hand_states(cfg.datasets, split=None if cfg.split == "all" else cfg.split, holdout=cfg.holdout)
    if cfg.hands:
        data = data.only(cfg.hands)
        if len(data) == 0:
            raise InvalidInputError(f"no rows for hands {cfg.hands} in {cfg.datasets}")
    # the folder scored (a run folder's best/), or the id as given (shipped or Hub)
    checkpoint = resolve(cfg.checkpoint) if Path(cfg.checkpoint).expanduser().is_dir() else cfg.checkpoint
    model = UniDexTok.from_pretrained(cfg.checkpoint, encoding=cfg.encoding).to(cfg.device)
    report = evaluate_tokenizer(model, data)
    report["checkpoint"], report["datasets"], report["split"] = checkpoint, cfg.datasets, cfg.split
    report["scored"] = describe_scored(data, cfg.datasets, cfg.split, checkpoint)
    md = write_report(report, cfg.output)
    print(md)
    return report


@wrap()
def eval_cli(cfg: EvalConfig) -> None:
    run(cfg)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    run_cli(eval_cli)


if __name__ == "__main__":
    main()
