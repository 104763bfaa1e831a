"""UniDexTok variants on real recordings, scored only on episodes they never trained on (k-fold over
episodes), next to 8-bit per-joint binning on the same frames: the tuning table of docs/tokenizer.md.

    python experiments/unseen_episodes.py                                  # real G1 + Inspire, 5 folds
    python experiments/unseen_episodes.py --variants='[shipped,no_coverage]' --folds=5 --steps=5000
    python experiments/unseen_episodes.py --datasets='[path/to/converted_a,path/to/converted_b]'

Each (variant, fold) result is cached in <output_root>/unseen_episodes/runs.jsonl, so an interrupted run
resumes and new variants reuse the old ones. Besides the held-out episodes, every model is scored on
states drawn uniformly inside each hand's registered joint ranges ("range" column): how it does on poses
the recordings never show.
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
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig
from lerobot_unidextok.training import HandStates, TrainConfig, train_tokenizer
from lerobot_unidextok.training.coverage import CoverageConfig, MixtureSampler
from lerobot_unidextok.training.splits import kfold_by_episode, split_by_episode

logger = logging.getLogger(__name__)
NAME = "unseen_episodes"


@dataclass(frozen=True)
class Variant:
    """A change against the shipped `unidextok-train` defaults: TrainConfig fields and preset fields."""

    note: str
    train: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)
    steps_scale: float = 1.0  # steps x this (e.g. half the batch for twice the steps at equal compute)


RECORDED_ONLY = {"robot": {"recorded": 1.0}, "human": {"recorded": 1.0}}
# Each variant changes one thing against `shipped` (the defaults of TrainConfig + the small preset).
VARIANTS: dict[str, Variant] = {
    "shipped": Variant("TrainConfig defaults, small preset (configs/train/small.yaml)"),
    "no_coverage": Variant("recorded rows only (no coverage samples)", {"coverage": RECORDED_ONLY}),
    "uniform_only": Variant("coverage samples only", {"coverage": {"robot": {"uniform": 1.0}}}),
    "uniform_0.8": Variant(
        "robot rows: recorded 0.2, uniform 0.8", {"coverage": {"robot": {"recorded": 0.2, "uniform": 0.8}}}
    ),
    "batch_128": Variant("batch 128 for twice the steps (equal compute)", {"batch_size": 128}, steps_scale=2.0),
    "robot_augment": Variant(
        "robot rows: recorded 0.3, recombine 0.1, noise 0.2, uniform 0.4",
        {"coverage": {"robot": {"recorded": 0.3, "recombine": 0.1, "noise": 0.2, "uniform": 0.4}}},
    ),
    "before_tuning": Variant(
        "the small preset before this tuning: commitment 0.25, fixed pi normalisation",
        model={"commitment_weight": 0.25, "input_norm": "pi"},
    ),
    "commitment_0.25": Variant("VQ-VAE commitment weight 0.25 (paper)", model={"commitment_weight": 0.25}),
    "commitment_1": Variant("commitment weight 1", model={"commitment_weight": 1.0}),
    "commitment_10": Variant("commitment weight 10", model={"commitment_weight": 10.0}),
    "pi_norm": Variant("fixed pi input normalisation (paper)", model={"input_norm": "pi"}),
    "l1": Variant("L1 loss only", model={"mse_weight": 0.0, "smooth_l1_weight": 0.0, "l1_weight": 1.0}),
    "mse": Variant("MSE loss only (paper)", model={"smooth_l1_weight": 0.0}),
    "ema": Variant("EMA codebook", model={"codebook_update": "ema"}),
    "rotation": Variant("rotation-trick gradient", model={"gradient_estimator": "rotation"}),
    "no_dead_code": Variant("no dead-code re-seeding", {"reseed_every": 0}),
    "wide": Variant("C = 128", model={"hidden_dim": 128}),
    "fourier": Variant("Fourier input features (6 octaves)", model={"fourier_octaves": 6}),
}


@dataclass
class UnseenConfig:
    datasets: list[str] = field(default_factory=list)  # converted UDHM datasets; empty = the real G1 recordings
    variants: list[str] = field(default_factory=lambda: ["shipped", "no_coverage"])
    folds: int = 5
    only_folds: list[int] = field(default_factory=list)  # run only these folds (screening); empty = all
    steps: int = 0  # 0 = the TrainConfig default
    seed: int = 0
    range_rows: int = 5000  # uniform in-range states scored per hand
    # Each model is scored through the nearest codes (as it trained) and with this encoding (docs/tokenizer.md "Code
    # search"; default 2 rounds of the greedy search; null = no second score). A cached run scored otherwise retrains.
    searched: EncodingConfig | None = field(default_factory=lambda: EncodingConfig(rounds=2))
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_data"
    tiny: bool = False  # tests: tiny preset, a few steps


def _train_config(cfg: UnseenConfig, variant: Variant, output_dir: Path) -> TrainConfig:
    kw = dict(variant.train)
    if "coverage" in kw:
        kw["coverage"] = CoverageConfig(**kw["coverage"])
    kw["steps"] = round((cfg.steps or TrainConfig().steps) * variant.steps_scale)
    if cfg.tiny:
        kw |= {"preset": "tiny", "steps": 12, "batch_size": 32, "warmup_steps": 2, "eval_every": 6}
    return TrainConfig(output_dir=str(output_dir), progress=False, save_last_every=10**9, seed=cfg.seed, **kw)


def range_rows(data: HandStates, n: int, seed: int) -> HandStates:
    """`n` states per hand drawn uniformly inside its registered joint ranges (its recorded masks)."""
    parts = []
    for hand in data.hand_names():
        batch = MixtureSampler(data.only(hand), coverage=CoverageConfig(robot={"uniform": 1.0},
                               human={"uniform": 1.0}), seed=seed).sample(n)  # fmt: skip
        parts.append(HandStates(batch.states_rad, np.full(n, hand), batch.masks))
    return HandStates.concat(parts)


def _score(pred: np.ndarray, data: HandStates) -> dict:
    from lerobot_unidextok.evaluation import mpjae_deg

    out = {"all": mpjae_deg(pred, data.states_rad, data.masks)}
    for hand in data.hand_names():
        rows = data.hands == hand
        out[hand] = mpjae_deg(pred[rows], data.states_rad[rows], data.masks[rows])
    return out


def run_fold(cfg: UnseenConfig, name: str, k: int, train: HandStates, test: HandStates, folder: Path) -> dict:
    import torch

    from lerobot_unidextok.evaluation import reconstruct
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training.loop import build_model

    variant = VARIANTS[name]
    tcfg = _train_config(cfg, variant, folder / "models" / f"{name}_fold{k}")
    fit, select = split_by_episode(train, tcfg.select_fraction, seed=cfg.seed)
    torch.manual_seed(cfg.seed)
    model = build_model(tcfg, fit, **variant.model)
    cpu0 = time.process_time()
    res = train_tokenizer(tcfg, fit, select, model=model)
    cpu = time.process_time() - cpu0
    best = UniDexTok.from_pretrained(res.best_dir)
    unif = range_rows(fit, cfg.range_rows, seed=1000 + k)

    def scored(data: HandStates, encoding: EncodingConfig) -> dict:
        rec = reconstruct(best, data.states_rad, data.hands, allow_unknown=True, masks=data.masks, encoding=encoding)
        return _score(rec.states_rad, data)

    searched = {}
    if cfg.searched is not None:
        searched = {"searched_encoding": dataclasses.asdict(cfg.searched),
                    "heldout_searched_deg": scored(test, cfg.searched), "range_searched_deg": scored(unif, cfg.searched)}  # fmt: skip
    return {
        "variant": name, "fold": k, "steps": res.steps, "best_step": res.best_step, "train_cpu_s": round(cpu, 1),
        "train_wall_s": round(res.seconds, 1), "fit_rows": len(fit), "select_rows": len(select),
        "test_rows": len(test), "test_episodes": int(len(np.unique(test.episode_keys()))),
        "heldout_deg": scored(test, NEAREST_CODES), "range_deg": scored(unif, NEAREST_CODES), **searched,
        "git_commit": git_commit(), "resolved": resolved_settings(cfg, name),
    }  # fmt: skip


def binning_fold(k: int, test: HandStates, fit: HandStates, range_n: int) -> dict:
    from experiments.unseen_data import binning_reconstruction

    unif = range_rows(fit, range_n, seed=1000 + k)
    return {"variant": "binning_8bit", "fold": k, "test_rows": len(test),
            "heldout_deg": _score(binning_reconstruction(test), test),
            "range_deg": _score(binning_reconstruction(unif), unif)}  # fmt: skip


def resolved_settings(cfg: UnseenConfig, name: str) -> dict:
    """Every training and model setting of a variant (defaults included): the cache key of its runs."""
    from lerobot_unidextok.tokenizer import UniDexTokConfig
    from lerobot_unidextok.tokenizer.configuration_unidextok import ENCODING_FIELDS

    variant = VARIANTS[name]
    train = dataclasses.asdict(_train_config(cfg, variant, Path(".")))
    for volatile in ("output_dir", "progress", "datasets"):
        train.pop(volatile)
    model = dataclasses.asdict(UniDexTokConfig.from_preset(train["preset"], **variant.model))
    for filled_by_training in ("hand_names", "trained_hands", "joint_range_rad"):
        model.pop(filled_by_training)
    drop = lambda d: {k: v for k, v in d.items() if k not in ENCODING_FIELDS}  # noqa: E731
    return {"train": drop(train), "model": drop(model)}


def _searched(encoding: dict | None) -> str:
    return EncodingConfig.from_dict(encoding).describe() if encoding else "nearest codes only (no search)"


def _key(r: dict) -> tuple:
    return (r["variant"], r["fold"], json.dumps(r["resolved"], sort_keys=True, default=str))


def run(cfg: UnseenConfig) -> dict:
    from experiments.unseen_data import all_episodes, converted_g1

    unknown = sorted(set(cfg.variants) - set(VARIANTS))
    if unknown:
        raise ValueError(f"unknown variants {unknown}; choose from {sorted(VARIANTS)}")
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    datasets = cfg.datasets or [str(converted_g1(cfg.cache_dir))]
    data = all_episodes(datasets)
    folds = kfold_by_episode(data, cfg.folds, seed=cfg.seed)
    fold_ids = cfg.only_folds or list(range(cfg.folds))
    cache = folder / ("runs_tiny.jsonl" if cfg.tiny else "runs.jsonl")
    done = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            r = json.loads(line)
            if "resolved" in r:
                done[_key(r)] = r
    results = []
    for k in fold_ids:
        train, test = folds[k]
        for name in ["binning_8bit", *cfg.variants]:
            if name == "binning_8bit":
                r = binning_fold(k, test, train, cfg.range_rows)
            else:
                probe = {"variant": name, "fold": k, "resolved": resolved_settings(cfg, name)}
                r = done.get(_key(probe))
                if r is not None and cfg.searched and r.get("searched_encoding") != dataclasses.asdict(cfg.searched):
                    r = None  # cached before the code search was scored (or with other rounds): train again
                if r is None:
                    logger.info("training %s on fold %d (%d rows)", name, k, len(train))
                    r = run_fold(cfg, name, k, train, test, folder)
                    with cache.open("a") as f:
                        f.write(json.dumps(r) + "\n")
            results.append(r)
    summary = summarise(results)
    result = {"experiment": NAME, "datasets": datasets, "folds": cfg.folds, "fold_ids": fold_ids,
              "config": dataclasses.asdict(cfg), "summary": summary, "runs": results,
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def summarise(results: list[dict]) -> dict:
    out = {}
    for name in dict.fromkeys(r["variant"] for r in results):
        rs = [r for r in results if r["variant"] == name]
        held = np.array([r["heldout_deg"]["all"] for r in rs])
        rng = np.array([r["range_deg"]["all"] for r in rs])
        searched = [r["heldout_searched_deg"]["all"] for r in rs if "heldout_searched_deg" in r]
        extra = {}
        if searched and len(searched) == len(rs):
            extra = {"heldout_searched_mean": float(np.mean(searched)),
                     "heldout_searched_std": float(np.std(searched, ddof=1)) if len(rs) > 1 else 0.0,
                     "range_searched_mean": float(np.mean([r["range_searched_deg"]["all"] for r in rs]))}  # fmt: skip
        out[name] = {**extra, "folds": len(rs), "heldout_mean": float(held.mean()),
                     "heldout_std": float(held.std(ddof=1)) if len(rs) > 1 else 0.0,
                     "heldout_min": float(held.min()), "heldout_max": float(held.max()), "range_mean": float(rng.mean()),
                     "train_cpu_s": float(np.mean([r.get("train_cpu_s", 0.0) for r in rs])),
                     "note": VARIANTS[name].note if name in VARIANTS else "per-joint 256 bins over the registered range, no training"}  # fmt: skip
    return out


def markdown(result: dict) -> str:
    def searched(s: dict) -> list[str]:
        if "heldout_searched_mean" not in s:
            return ["-", "-"]
        return [f"{s['heldout_searched_mean']:.3f} +- {s['heldout_searched_std']:.3f}", f"{s['range_searched_mean']:.3f}"]

    rows = [[name, s["folds"], f"{s['heldout_mean']:.3f} +- {s['heldout_std']:.3f}",
             f"[{s['heldout_min']:.3f}, {s['heldout_max']:.3f}]", f"{s['range_mean']:.3f}", *searched(s),
             f"{s['train_cpu_s']:.0f}", s["note"]] for name, s in result["summary"].items()]  # fmt: skip
    return "\n".join([
        f"# {NAME}", "",
        f"Datasets: {', '.join(result['datasets'])}; k-fold over episodes ({result['folds']} folds, folds run: "
        f"{result['fold_ids']}). MPJAE (deg) on each fold's held-out episodes: mean +- std over folds [min, max]; "
        "range = MPJAE on states uniform inside each hand's registered joint ranges; through the nearest codes, "
        f"and with the {_searched(result['config'].get('searched'))} ('searched'); CPU s = "
        "training CPU time per fold (one thread).", "",
        md_table(["variant", "folds", "held-out MPJAE (deg)", "[min, max]", "range MPJAE (deg)",
                  "held-out, searched (deg)", "range, searched (deg)", "CPU s", "what"], rows),
    ])  # fmt: skip


def parse(argv: list[str] | None = None) -> UnseenConfig:
    return runtime.parse(UnseenConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(UnseenConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
