"""Fine-tuning a pretrained tokenizer (by default the shipped `unidextok/universal-small`) on one converted
dataset against training from scratch at equal steps, all scored on that dataset's test-split episodes: the
"Fine-tuning from it" table of docs/tokenizer.md.

    python experiments/finetune.py                                      # outputs/universal_data/g1_inspire
    python experiments/finetune.py --steps='[500,1500,5000]' --seeds='[0,1]' --finetune_lrs='[0.006,0.0006]'
    python experiments/finetune.py --dataset=path/to/converted --checkpoint=path/to/checkpoint_or_repo_id

For each step budget and seed:
- scratch: the recipe (`configs/train/small.yaml`: small preset, lr 6e-3) as `unidextok-train` runs it;
- fine-tuned: the same recipe with `init_from=<checkpoint>`, once per fine-tune lr (default: the recipe's);
and once: the checkpoint as it is (0 steps). Every training uses the dataset's train split, minus the
`select_fraction` of its episodes that choose the kept checkpoint; every row is scored on the test split only.
Not k-fold over all episodes: the shipped universal tokenizer trained on the train split of
outputs/universal_data/g1_inspire, so folds would score it on episodes it trained on.

Each finished training is cached in <output_root>/finetune/runs.jsonl, keyed by its resolved training
settings, a fingerprint of the checkpoint's weights and one of the dataset's rows (a retrained checkpoint or a
re-converted dataset trains again), so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_unidextok.configs import resolve_config_path
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig
from lerobot_unidextok.tokenizer.configuration_unidextok import ENCODING_FIELDS
from lerobot_unidextok.utils.files import fingerprint

logger = logging.getLogger(__name__)
NAME = "finetune"
METRICS = ("mpjae_deg", "mpjpe_mm", "fingertip_mm")
SCRATCH, FINETUNED, CHECKPOINT = "scratch", "fine-tuned", "checkpoint as it is"


@dataclass
class FinetuneConfig:
    dataset: str = "outputs/universal_data/g1_inspire"  # a converted UDHM dataset with test-split episodes
    checkpoint: str = UNIVERSAL_SMALL  # what fine-tuning starts from: shipped id, local folder or Hub repo id
    recipe: str = "train/small"  # unidextok-train config (shipped name or file) of every training (scratch: as it is)
    steps: list[int] = field(default_factory=lambda: [500, 1500, 5000])  # step budgets, each for both trainings
    seeds: list[int] = field(default_factory=lambda: [0])  # batches, splits and scratch initialisation
    finetune_lrs: list[float] = field(default_factory=list)  # peak lr of the fine-tuned rows; empty = the recipe's
    # Train only these conditions ("scratch", "fine-tuned"; empty = both), e.g. the scratch rows while the
    # checkpoint is still being trained. A later run without it reuses them from the cache.
    only: list[str] = field(default_factory=list)
    # Every kept model is also scored with this encoding (docs/tokenizer.md "Code search"; default the shipped
    # model's: 2 rounds of the greedy search, rows within 0.1 deg stop); the main columns use the nearest codes, as
    # each model was trained. null = no second score.
    searched: EncodingConfig | None = field(default_factory=lambda: EncodingConfig(rounds=2, tolerance_deg=0.1))
    output_root: str = "outputs/experiments"

    def __post_init__(self) -> None:
        if not self.steps or min(self.steps) < 1:
            raise ValueError(f"steps must be a non-empty list of budgets >= 1, got {self.steps}")
        if not self.seeds:
            raise ValueError("seeds must list at least one seed, e.g. --seeds='[0]'")
        if set(self.only) - {SCRATCH, FINETUNED}:
            raise ValueError(f"only takes {SCRATCH!r} and {FINETUNED!r}, got {self.only}")
        if any(lr <= 0 for lr in self.finetune_lrs):
            raise ValueError(f"finetune_lrs must be > 0, got {self.finetune_lrs}")


@dataclass(frozen=True)
class Condition:
    """One training: from scratch (`init_from` None) or from the checkpoint, at `steps` with `seed` and `lr`."""

    name: str
    steps: int
    seed: int
    lr: float
    init_from: str | None

    @property
    def slug(self) -> str:
        kind = "scratch" if self.init_from is None else f"finetuned_lr{self.lr:g}"
        return f"{kind}_steps{self.steps}_seed{self.seed}"


def recipe(cfg: FinetuneConfig):
    """The recipe's TrainConfig (its own steps, seed, lr, datasets and output folder are replaced per run)."""
    import draccus

    from lerobot_unidextok.training import TrainConfig

    return draccus.parse(TrainConfig, config_path=resolve_config_path(cfg.recipe, "recipe"), args=[])


def conditions(cfg: FinetuneConfig) -> list[Condition]:
    """Every training of the experiment: per step budget and seed, scratch then fine-tuned at each lr."""
    base_lr = recipe(cfg).lr
    out = []
    for steps in cfg.steps:
        for seed in cfg.seeds:
            out.append(Condition(SCRATCH, steps, seed, base_lr, None))
            out += [Condition(FINETUNED, steps, seed, lr, cfg.checkpoint) for lr in cfg.finetune_lrs or [base_lr]]
    return [c for c in out if not cfg.only or c.name in cfg.only]


def train_config(cfg: FinetuneConfig, cond: Condition, output_dir: Path):
    return dataclasses.replace(recipe(cfg), datasets=[cfg.dataset], steps=cond.steps, seed=cond.seed, lr=cond.lr,
                               init_from=cond.init_from, output_dir=str(output_dir), progress=False,
                               save_last_every=10**9, resume=False, folds=0)  # fmt: skip


def resolved_settings(cfg: FinetuneConfig, cond: Condition, checkpoint_id: str, data_id: str) -> dict:
    """Every training setting of a condition (defaults included) and what it starts from and trains on: the
    cache key of its run."""
    train = dataclasses.asdict(train_config(cfg, cond, Path(".")))
    for volatile in ("output_dir", "progress", "datasets"):
        train.pop(volatile)
    train = {k: v for k, v in train.items() if k not in ENCODING_FIELDS}
    return {"train": train, "checkpoint": checkpoint_id if cond.init_from else None, "data": data_id}


def _key(resolved: dict) -> str:
    return json.dumps(resolved, sort_keys=True, default=str)


def model_fingerprint(model) -> str:
    """Of a model's config and every tensor of its state dict: changes when a checkpoint is retrained, not with
    the settings of its use (the code search, which training never runs)."""
    tensors = [t.detach().cpu().numpy() for t in model.state_dict().values()]
    config = {k: v for k, v in dataclasses.asdict(model.config).items() if k not in ENCODING_FIELDS}
    return fingerprint(config, *tensors)


def data_fingerprint(train, test) -> str:
    """Of the rows, hands, masks and episodes of both splits."""
    return fingerprint(*[a for d in (train, test) for a in (d.states_rad, d.hands, d.masks, d.episode_index)])


def load_dataset(cfg: FinetuneConfig, holdout: str):
    """(train split, test split) of `cfg.dataset`; a clear error when it has no test episodes."""
    from lerobot_unidextok.training import load_hand_states

    if not Path(cfg.dataset).expanduser().is_dir():
        raise FileNotFoundError(f"dataset {cfg.dataset} not found: convert one first (unidextok-convert, or "
                                "`python experiments/universal_data.py` for the default), or pass "
                                "--dataset=")  # fmt: skip
    train = load_hand_states([cfg.dataset], split="train", holdout=holdout)
    try:
        test = load_hand_states([cfg.dataset], split="test", holdout=holdout)
    except ValueError as e:
        raise ValueError(f"{cfg.dataset} has no test episodes to score on ({e}): convert it with a test split "
                         "(unidextok-convert --test_fraction=0.2)") from e  # fmt: skip
    if len(test) == 0:
        raise ValueError(f"{cfg.dataset} has no test rows: convert it with a test split (--test_fraction=0.2)")
    return train, test


def scores(model, test, encoding: EncodingConfig = NEAREST_CODES) -> dict:
    """Overall and per-hand MPJAE (deg), MPJPE (mm), fingertip error (mm) on the test rows, encoded with `encoding`
    (default the nearest codes, whatever the model's config says)."""
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer

    model.with_encoding(encoding)
    report = evaluate_tokenizer(model, test)
    per_hand = {h: {**{k: float(e[k]) for k in METRICS}, "rows": int(e["rows"])} for h, e in report["per_hand"].items()}
    return {"overall": {k: float(report["overall"][k]) for k in METRICS}, "per_hand": per_hand}


def _episodes(data) -> list[int]:
    return sorted(int(e) for e in np.unique(data.episode_index))


def run_condition(cfg: FinetuneConfig, cond: Condition, train, test, folder: Path, resolved: dict) -> dict:
    """Train one condition with `train_tokenizer` (the loop `unidextok-train` runs) and score its kept
    checkpoint on the test rows."""
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import train_tokenizer
    from lerobot_unidextok.training.run import fit_and_select

    tcfg = train_config(cfg, cond, folder / "models" / cond.slug)
    fit, select = fit_and_select(tcfg, train)
    cpu0 = time.process_time()
    res = train_tokenizer(tcfg, fit, select)
    cpu = time.process_time() - cpu0
    best = UniDexTok.from_pretrained(res.best_dir)
    return {
        "condition": cond.name, "steps": res.steps, "seed": cond.seed, "lr": cond.lr, "init_from": cond.init_from,
        "best_step": res.best_step, "train_cpu_s": round(cpu, 1), "train_wall_s": round(res.seconds, 1),
        "fit_rows": len(fit), "select_rows": len(select), "test_rows": len(test),
        "fit_episodes": _episodes(fit), "select_episodes": _episodes(select), "test_episodes": _episodes(test),
        "model_dir": str(res.best_dir), **scores(best, test), "git_commit": git_commit(), "resolved": resolved,
    }  # fmt: skip


def checkpoint_row(cfg: FinetuneConfig, model, test, checkpoint_id: str) -> dict:
    """The checkpoint scored as it is (no training on this dataset's run)."""
    return {"condition": CHECKPOINT, "steps": 0, "seed": None, "lr": None, "init_from": cfg.checkpoint,
            "best_step": None, "train_cpu_s": 0.0, "test_rows": len(test), "test_episodes": _episodes(test),
            **scores(model, test), "checkpoint_fingerprint": checkpoint_id}  # fmt: skip


def _read_cache(cache: Path) -> dict[str, dict]:
    done = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[_key(r["resolved"])] = r
    return done


def run(cfg: FinetuneConfig) -> dict:
    from lerobot_unidextok.tokenizer import UniDexTok

    folder = Path(cfg.output_root) / NAME
    todo = conditions(cfg)  # reads the recipe first: a wrong path fails before any loading
    train, test = load_dataset(cfg, recipe(cfg).holdout)
    pretrained = UniDexTok.from_pretrained(cfg.checkpoint)
    checkpoint_id, data_id = model_fingerprint(pretrained), data_fingerprint(train, test)
    folder.mkdir(parents=True, exist_ok=True)
    cache = folder / "runs.jsonl"
    done = _read_cache(cache)
    runs = [checkpoint_row(cfg, pretrained, test, checkpoint_id)]
    for cond in todo:
        resolved = resolved_settings(cfg, cond, checkpoint_id, data_id)
        r = done.get(_key(resolved))
        if r is None:
            logger.info("training %s (%d steps, seed %d, lr %g)", cond.name, cond.steps, cond.seed, cond.lr)
            r = json.loads(json.dumps(run_condition(cfg, cond, train, test, folder, resolved)))  # as cached
            with cache.open("a") as f:
                f.write(json.dumps(r) + "\n")
        runs.append(r)
    if cfg.searched is not None:  # not cached: seconds per model, and no training
        for r in runs:
            model = pretrained if r["condition"] == CHECKPOINT else UniDexTok.from_pretrained(r["model_dir"])
            r["searched"] = scores(model, test, cfg.searched)["overall"]
    result = {"experiment": NAME, "dataset": cfg.dataset, "checkpoint": cfg.checkpoint,
              "checkpoint_fingerprint": checkpoint_id, "data_fingerprint": data_id,
              "test_episodes": _episodes(test), "train_episodes": _episodes(train), "test_rows": len(test),
              "config": dataclasses.asdict(cfg), "summary": summarise(runs), "runs": runs,
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def summarise(runs: list[dict]) -> list[dict]:
    """One entry per (condition, steps, lr): mean and std over seeds of each metric, best steps, CPU s."""
    groups: dict[tuple, list[dict]] = {}
    for r in runs:
        groups.setdefault((r["condition"], r["steps"], r["lr"]), []).append(r)
    out = []
    for (name, steps, lr), rs in groups.items():
        entry = {"condition": name, "steps": steps, "lr": lr, "seeds": [r["seed"] for r in rs],
                 "best_steps": [r["best_step"] for r in rs],
                 "train_cpu_s": float(np.mean([r["train_cpu_s"] for r in rs]))}  # fmt: skip
        for k in METRICS:
            vals = np.array([r["overall"][k] for r in rs])
            entry[k] = float(vals.mean())
            entry[f"{k}_std"] = float(vals.std(ddof=1)) if len(vals) > 1 else 0.0
        if all("searched" in r for r in rs):
            vals = np.array([r["searched"]["mpjae_deg"] for r in rs])
            entry["searched_mpjae_deg"] = float(vals.mean())
            entry["searched_mpjae_deg_std"] = float(vals.std(ddof=1)) if len(vals) > 1 else 0.0
        out.append(entry)
    return out


def _cell(s: dict, k: str) -> str:
    return f"{s[k]:.3f} +- {s[f'{k}_std']:.3f}" if len(s["seeds"]) > 1 else f"{s[k]:.3f}"


def markdown(result: dict) -> str:
    rows = [[s["condition"], s["steps"], "-" if s["lr"] is None else f"{s['lr']:g}",
             "-" if s["seeds"] == [None] else len(s["seeds"]), *[_cell(s, k) for k in METRICS],
             _cell(s, "searched_mpjae_deg") if "searched_mpjae_deg" in s else "-",
             ", ".join("-" if b is None else str(b) for b in s["best_steps"]), f"{s['train_cpu_s']:.0f}"]
            for s in result["summary"]]  # fmt: skip
    searched = result["config"].get("searched")
    return "\n".join([
        f"# {NAME}", "",
        f"Dataset {result['dataset']}: trained on its train-split episodes {result['train_episodes']} (the recipe's "
        f"select_fraction of them held out to choose the kept checkpoint), scored on its test-split episodes "
        f"{result['test_episodes']} ({result['test_rows']} hand-rows). Fine-tuned = `init_from={result['checkpoint']}` "
        f"(weights {result['checkpoint_fingerprint']}); recipe {result['config']['recipe']} with the steps, lr and "
        "seed of each row. Mean (+- std over seeds); CPU s = training CPU time (time.process_time, one torch "
        "thread). MPJAE, MPJPE and fingertip through the nearest codes; "
        + (f"'code search' = MPJAE with codes picked by the {EncodingConfig.from_dict(searched).describe()}."
           if searched else "no code search score."), "",
        md_table(["model", "steps", "lr", "seeds", "MPJAE (deg)", "MPJPE (mm)", "fingertip (mm)",
                  "MPJAE, code search (deg)", "best step", "CPU s"], rows),
    ])  # fmt: skip


def parse(argv: list[str] | None = None) -> FinetuneConfig:
    return runtime.parse(FinetuneConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(FinetuneConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
