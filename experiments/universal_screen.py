"""Choose the universal recipe by measurement on data the reported figures never use.

Each variant changes the universal recipe (`configs/train/universal.yaml`) in one or two settings, trains at
a screening length, and is scored on
- the run's selection episodes: whole training episodes held out from training (`select_fraction`), per hand;
- every registered hand's states uniform inside its registered ranges, drawn with another seed than the
  card's in-range figures (`SCREEN_SEED`).
The test episodes and held-out recordings, which the card reports, are not loaded here.

    python experiments/universal_screen.py --variants='[shipped,wide]' --steps=3000
    python experiments/universal_screen.py --runs='[outputs/run_a,outputs/run_b]'   # finished full-length runs
    python experiments/universal_screen.py --runs='[outputs/unidextok_universal]' \
        --rounds='[0,1,2]' --sweeps='[1,2,3,4]'                      # the code search's settings
    python experiments/universal_screen.py --runs='[outputs/unidextok_universal]' --methods='[greedy]' \
        --rounds='[0,1,2]' --changes='[4,8,16,32]' --tolerances_deg='[0,0.1]'   # the greedy search's

Each variant's result is cached in <output_root>/universal_screen/runs.jsonl (keyed by its resolved settings).
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
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig

logger = logging.getLogger(__name__)
NAME = "universal_screen"
SCREEN_SEED = 7  # the card's in-range states use seed 0 (experiments/universal.py)


@dataclass(frozen=True)
class Variant:
    """A change against the recipe: TrainConfig fields and preset (model) fields."""

    note: str
    train: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)


VARIANTS: dict[str, Variant] = {
    "shipped": Variant("configs/train/universal.yaml as it is (small preset)"),
    "anneal": Variant("lr decays to 0 and no dead-code re-seeding in the last 30 % of steps",
                      {"min_lr_ratio": 0.0, "reseed_until": 0.7}),  # fmt: skip
    "wide": Variant("C = 128 (small preset otherwise)", model={"hidden_dim": 128}),
    "fourier": Variant("Fourier input features (6 octaves)", model={"fourier_octaves": 6}),
    "l1": Variant("L1 loss added (weight 1)", model={"l1_weight": 1.0}),
}


@dataclass
class ScreenConfig:
    recipe: str = "train/universal"  # the unidextok-train config screened
    variants: list[str] = field(default_factory=lambda: ["shipped", "anneal"])
    steps: int = 3000  # screening length (the recipe's own steps are not used)
    range_rows: int = 2000  # in-range states scored per registered hand
    # Finished `unidextok-train` run folders of the recipe (e.g. full-length candidates) to score the same way
    # (their best/ checkpoint) instead of training variants.
    runs: list[str] = field(default_factory=list)
    # The grid of encodings (EncodingConfig) the runs are scored with (rounds 0 = the nearest codes, once; then per
    # method in `methods` every rounds x sweeps pair ("sweeps") or rounds x changes pair ("greedy")): how the
    # shipped config's encoding was chosen.
    rounds: list[int] = field(default_factory=lambda: [0])
    methods: list[str] = field(default_factory=lambda: ["sweeps"])
    sweeps: list[int] = field(default_factory=lambda: [3])
    changes: list[int] = field(default_factory=lambda: [16])
    tolerances_deg: list[float] = field(default_factory=lambda: [0.0])  # greedy: its tolerance_deg values
    output_root: str = "outputs/experiments"


def recipe_config(cfg: ScreenConfig, variant: Variant, output_dir: Path):
    import draccus

    from lerobot_unidextok.training import TrainConfig

    base = draccus.parse(TrainConfig, config_path=resolve_config_path(cfg.recipe, "recipe"), args=[])
    return dataclasses.replace(base, steps=cfg.steps, output_dir=str(output_dir), progress=False,
                               save_last_every=10**9, **variant.train)  # fmt: skip


def resolved(cfg: ScreenConfig, name: str) -> dict:
    tcfg = recipe_config(cfg, VARIANTS[name], Path("."))
    from lerobot_unidextok.tokenizer.configuration_unidextok import ENCODING_FIELDS

    skip = ("output_dir", "progress", *ENCODING_FIELDS)
    train = {k: v for k, v in dataclasses.asdict(tcfg).items() if k not in skip}
    return {"train": train, "model": VARIANTS[name].model, "range_rows": cfg.range_rows}


def selection_split(tcfg):
    """The run's (fit, select) rows: its training split minus the held-out selection episodes."""
    from lerobot_unidextok.training import load_hand_states
    from lerobot_unidextok.training.run import fit_and_select

    train = load_hand_states(tcfg.datasets, split="train", holdout=tcfg.holdout)  # the test split stays unread
    return fit_and_select(tcfg, train)


def score(model, select, range_rows: int) -> dict:
    """MPJAE (deg) per hand on the selection episodes, and per registered hand on in-range states (SCREEN_SEED)."""
    from experiments.universal import IN_RANGE_PREFIX, in_range_figures
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer

    select_report = evaluate_tokenizer(model, select)
    in_range = {name.removeprefix(IN_RANGE_PREFIX): entry["mpjae_deg"]
                for name, entry in in_range_figures(model, rows=range_rows, seed=SCREEN_SEED).items()}  # fmt: skip
    return {"select_deg": {h: e["mpjae_deg"] for h, e in select_report["per_hand"].items()},
            "select_rows": len(select), "in_range_deg": in_range,
            "in_range_mean": float(np.mean(list(in_range.values()))),
            "in_range_max": float(max(in_range.values())), "params": sum(p.numel() for p in model.parameters())}  # fmt: skip


def run_variant(cfg: ScreenConfig, name: str, folder: Path) -> dict:
    import torch

    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training.loop import build_model, train_tokenizer

    variant = VARIANTS[name]
    tcfg = recipe_config(cfg, variant, folder / "models" / name)
    fit, select = selection_split(tcfg)
    torch.manual_seed(tcfg.seed)
    model = build_model(tcfg, fit, **variant.model)
    cpu0 = time.process_time()
    res = train_tokenizer(tcfg, fit, select, model=model)
    cpu = time.process_time() - cpu0
    best = UniDexTok.from_pretrained(res.best_dir)
    best.with_encoding(NEAREST_CODES)  # variants are compared through the nearest codes, as they trained
    return {"variant": name, "steps": res.steps, "best_step": res.best_step, "train_cpu_s": round(cpu, 1),
            **score(best, select, cfg.range_rows),
            "git_commit": git_commit(), "resolved": resolved(cfg, name)}  # fmt: skip


def search_settings(cfg: ScreenConfig) -> list[EncodingConfig]:
    """The encodings the runs are scored with: the nearest codes once, then every searched setting of each
    method."""
    out = [NEAREST_CODES] if 0 in cfg.rounds else []
    for method in cfg.methods:
        key, values = ("sweeps", cfg.sweeps) if method == "sweeps" else ("changes", cfg.changes)
        tolerances = sorted(set(cfg.tolerances_deg)) if method == "greedy" else [0.0]
        out += [EncodingConfig(method=method, rounds=r, tolerance_deg=t, **{key: v})
                for r in sorted(set(cfg.rounds) - {0}) for v in sorted(set(values))
                for t in (tolerances if r > 1 else tolerances[:1])]  # fmt: skip
    return out


def search_label(setting: EncodingConfig) -> str:
    if not setting.rounds:
        return "nearest codes"
    per = setting.sweeps if setting.method == "sweeps" else setting.changes
    tolerance = setting.tolerance_deg if setting.method == "greedy" else 0
    return f"{setting.method} {setting.rounds} x {per}" + (f", stop at {tolerance:g} deg" if tolerance else "")


def score_runs(cfg: ScreenConfig) -> list[dict]:
    """Finished run folders of the recipe, scored like the variants (selection split from the recipe's seed),
    once per code search setting."""
    import draccus

    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import TrainConfig

    _, select = selection_split(draccus.parse(TrainConfig, config_path=resolve_config_path(cfg.recipe, "recipe"), args=[]))
    out = []
    for folder in map(Path, cfg.runs):
        if not (folder / "best" / "config.json").is_file():
            raise FileNotFoundError(f"{folder}/best not found: pass finished unidextok-train run folders")
        state = json.loads((folder / "best" / "training_state.json").read_text())
        model = UniDexTok.from_pretrained(folder / "best")
        for setting in search_settings(cfg):
            model.with_encoding(setting)
            cpu0 = time.process_time()
            scored = score(model, select, cfg.range_rows)
            out.append({"variant": str(folder), "search": search_label(setting),
                        "steps": state.get("steps"), "best_step": state.get("step"), "train_cpu_s": None,
                        "score_cpu_s": round(time.process_time() - cpu0, 1), **scored})  # fmt: skip
    return out


def run(cfg: ScreenConfig) -> dict:
    from lerobot_unidextok.tokenizer.configuration_unidextok import SEARCH_METHODS

    if sorted(set(cfg.methods) - set(SEARCH_METHODS)):
        raise ValueError(f"methods must be among {SEARCH_METHODS}, got {cfg.methods}")
    unknown = sorted(set(cfg.variants) - set(VARIANTS))
    if unknown:
        raise ValueError(f"unknown variants {unknown}; choose from {sorted(VARIANTS)}")
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    if cfg.runs:
        result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "runs": score_runs(cfg),
                  "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
        (folder / "runs_scored.json").write_text(json.dumps(result, indent=2, default=str))
        (folder / "runs_scored.md").write_text(markdown(result) + "\n")
        return result
    cache = folder / "runs.jsonl"
    done = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            r = json.loads(line)
            done[json.dumps(r["resolved"], sort_keys=True, default=str)] = r
    results = []
    for name in cfg.variants:
        key = json.dumps(resolved(cfg, name), sort_keys=True, default=str)
        r = done.get(key)
        if r is None:
            logger.info("screening %s (%d steps)", name, cfg.steps)
            r = run_variant(cfg, name, folder)
            with cache.open("a") as f:
                f.write(json.dumps(r, default=str) + "\n")
        results.append(r)
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "runs": results,
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2, default=str))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def markdown(result: dict) -> str:
    hands_sel = sorted({h for r in result["runs"] for h in r["select_deg"]})

    def deg(x: float | None) -> str:
        return "-" if x is None else f"{x:.3f}"

    rows = [[r["variant"] + (f" ({r['search']})" if "search" in r else ""), r["steps"], r["best_step"],
             *[deg(r["select_deg"].get(h)) for h in hands_sel],
             deg(r["in_range_mean"]), deg(r["in_range_max"]), r["params"],
             f"{r['train_cpu_s']:.0f}" if r["train_cpu_s"] else "-",
             VARIANTS[r["variant"]].note if r["variant"] in VARIANTS
             else "finished run folder" + (f", scored in {r['score_cpu_s']:.0f} CPU-s" if "score_cpu_s" in r else "")]
            for r in result["runs"]]  # fmt: skip
    return "\n".join([
        f"# {NAME}", "",
        f"Recipe {result['config']['recipe']}"
        + (" (finished run folders). " if result["config"]["runs"] else f" at {result['config']['steps']} steps per variant. ")
        + "MPJAE (deg) on the "
        "selection episodes (training episodes held out from training) per hand, and on states uniform inside "
        f"each registered hand's ranges (seed {SCREEN_SEED}, {result['config']['range_rows']} per hand: mean and "
        "worst hand). CPU s: training, one thread.", "",
        md_table(["variant", "steps", "best step", *[f"select: {h}" for h in hands_sel], "in-range mean",
                  "in-range worst", "params", "CPU s", "what"], rows),
    ])  # fmt: skip


def parse(argv: list[str] | None = None) -> ScreenConfig:
    return runtime.parse(ScreenConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(ScreenConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
