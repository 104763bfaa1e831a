"""`unidextok-eval`: per-hand MPJAE / MPJPE / fingertip error and codebook usage of a tokenizer.

    unidextok-eval --checkpoint=outputs/small --datasets='[data/sample_mixture]'   # a run folder: uses best/
    unidextok-eval --checkpoint=outputs/small/best --datasets='[data/sample_mixture]'
    unidextok-eval --checkpoint=me/unidextok-small --datasets='[me/inspire_udhm]' --split=test
    unidextok-eval --checkpoint=unidextok/universal-small --datasets='[data/g1]' --encoding.rounds=0   # nearest codes

Hands the checkpoint never saw are evaluated zero-shot (unknown-hand embedding) and flagged.
Writes the report as two files and prints it: first what was scored (the checkpoint folder, and per dataset the
episodes of the split and their hand-rows: one row per hand per frame, so a two-hand frame gives two rows), then
the per-hand table, then the two paths written. Where (`report_stem`):

    --output=results/run1        ->  results/run1.json, results/run1.md
    --output=results/run1.json   ->  results/run1.json, results/run1.md   (.json or .md: the same two files)
    --output=results/  (a trailing slash, or an existing folder)  ->  results/eval.json, results/eval.md
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging
import os
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
    # where the report goes: a path stem (<output>.json + <output>.md), or a folder (a trailing "/", or an
    # existing folder) that gets eval.json + eval.md inside
    output: str = "outputs/unidextok_eval/eval"
    device: str = "cpu"

    def __post_init__(self) -> None:
        if not self.checkpoint:
            raise InvalidInputError("--checkpoint is required (a folder with config.json + model.safetensors, a "
                             "unidextok-train run folder, unidextok/universal-small, or a Hub repo id)")  # fmt: skip
        if self.split not in ("train", "test", "all"):
            raise InvalidInputError(f"--split must be train, test or all, got {self.split!r}")


REPORT_NAME = "eval"  # the report's stem inside a folder given as --output


def report_stem(output: str) -> Path:
    """The path stem of the report `--output` names (module docstring): a folder (written with a trailing slash,
    or existing) gets `eval.json`/`eval.md` inside it; a `.json`/`.md` ending is the stem's; anything else is the
    stem itself (`run.v2` -> `run.v2.json`)."""
    path = Path(output).expanduser()
    if output.endswith(("/", os.sep)) or path.is_dir():
        return path / REPORT_NAME
    return path.with_suffix("") if path.suffix.lower() in (".json", ".md") else path


def refuse_a_training_report(stem: Path) -> None:
    """`<stem>.json` may be an earlier `unidextok-eval` report (rewritten), never the report `unidextok-train` wrote
    for its run (`--output=<run folder>` would replace the run's test scores of its best checkpoint)."""
    import json

    from lerobot_unidextok.data.destination import DestinationError
    from lerobot_unidextok.evaluation.report import report_paths

    json_path = report_paths(stem)[0]
    try:
        report = json.loads(json_path.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return
    if isinstance(report, dict) and "training" in report:
        raise DestinationError(
            f"--output would replace {json_path}, the report unidextok-train wrote for its run: choose another --output"
        )


def run(cfg: EvalConfig) -> dict:
    from lerobot_unidextok.evaluation import evaluate_tokenizer, write_report
    from lerobot_unidextok.evaluation.report import claim_report, describe_scored, report_paths
    from lerobot_unidextok.pretrained import resolve
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import load_hand_states

    stem = report_stem(cfg.output)
    refuse_a_training_report(stem)
    claim_report(stem, inputs=[Path(d) for d in cfg.datasets if Path(d).expanduser().exists()])
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
    md = write_report(report, stem)
    print(md)
    json_path, md_path = report_paths(stem)
    print(f"wrote {json_path} and {md_path}")
    return report


@wrap()
def eval_cli(cfg: EvalConfig) -> None:
    run(cfg)


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    run_cli(eval_cli)


if __name__ == "__main__":
    main()
