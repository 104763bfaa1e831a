"""What the experiments share: sample data cache, cached tokenizer training, scoring, result files."""

import dataclasses
import json
import logging
import math
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.config import ExperimentConfig, config_dict
from lerobot_unidextok.constants import DATA_GLOB, INFO_PATH
from lerobot_unidextok.training import (
    HandStates,
    TrainConfig,
    load_hand_states,
    train_tokenizer,
)
from lerobot_unidextok.training.splits import split_by_episode
from lerobot_unidextok.utils.files import fingerprint, jsonable

logger = logging.getLogger(__name__)

HUMAN = "human"
UNIDEXTOK = "UniDexTok"


# ---------------------------------------------------------------------------------------------
# provenance and result files
# ---------------------------------------------------------------------------------------------
WHERE_TO = ("output_root", "cache_dir", "figure_to")  # where a run writes, not what it measures: not in its command


def shown_command(command: str) -> str:
    """A recorded command without its `WHERE_TO` flags (paths of the machine that ran it)."""
    return " ".join(w for w in command.split() if not any(w.startswith(f"--{name}=") for name in WHERE_TO))


def git_commit() -> str:
    """HEAD of the checkout these experiments live in (+ '-dirty' with uncommitted changes), or 'unknown'."""
    repo = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(
            ["git", "-C", str(repo), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            [
                "git",
                "-C",
                str(repo),
                "status",
                "--porcelain",
                "--",
                "lerobot_unidextok",
            ],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def provenance(cfg: ExperimentConfig, data: "ExperimentData", seconds: float) -> dict:
    """Data, preset, seed and commit a result came from."""
    return {
        "data": {"source": data.source, "synthetic_sample": data.synthetic, "datasets": [str(d) for d in data.datasets],
                 "train_rows": len(data.train), "test_rows": len(data.test), "hands": data.train.hand_names()},
        "preset": cfg.train.preset,
        "seed": cfg.seed,
        "git_commit": git_commit(),
        "config": config_dict(cfg),
        "wall_seconds": round(seconds, 1),
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }  # fmt: skip


def out_dir(cfg: ExperimentConfig, name: str) -> Path:
    path = Path(cfg.output_root) / name
    path.mkdir(parents=True, exist_ok=True)
    return path


def write_result(folder: Path, name: str, result: dict, markdown: str) -> Path:
    """`<folder>/<name>.json` and `<folder>/<name>.md`; returns the JSON path."""
    (folder / f"{name}.json").write_text(json.dumps(jsonable(result), indent=2))
    (folder / f"{name}.md").write_text(markdown.rstrip() + "\n")
    logger.info("wrote %s/%s.{json,md}", folder, name)
    return folder / f"{name}.json"


def fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def md_table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += [
        "| " + " | ".join(fmt(c) if isinstance(c, float) or c is None else str(c) for c in r) + " |" for r in rows
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# data: converted sample sources (cached) or the user's converted datasets
# ---------------------------------------------------------------------------------------------
@dataclass
class ExperimentData:
    train: HandStates
    test: HandStates
    datasets: list[Path | str]
    synthetic: bool
    raw_dir: Path | None = None  # raw sample sources (labels for the probe), None otherwise
    source: str = "sample"  # "real" (../shared/data/real), "sample" (SYNTHETIC), "datasets" (--datasets)
    clip: object | None = None  # real_data.RealHuman: the real human clip and its retargeted hands (real only)


def sample_raw_dir(cfg: ExperimentConfig) -> Path:
    return Path(cfg.data_dir) / f"raw_e{cfg.sample_episodes}_f{cfg.sample_frames}_s{cfg.seed}"


def _valid_dataset(root: Path) -> bool:
    return (root / INFO_PATH).is_file() and any(root.glob(DATA_GLOB))


def prepare_sample_data(cfg: ExperimentConfig, mapping: str = "semantic") -> list[Path]:
    """Write the synthetic sample sources once and convert them with `mapping`; reused when present."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, SAMPLE_SOURCES, write_samples

    raw = sample_raw_dir(cfg)
    if not (raw / "DONE").is_file():
        shutil.rmtree(raw, ignore_errors=True)
        write_samples(
            raw,
            episodes_per_source=cfg.sample_episodes,
            frames_per_episode=cfg.sample_frames,
            seed=cfg.seed,
        )
        (raw / "DONE").write_text("complete\n")
    conv = Path(cfg.data_dir) / f"{mapping}_{raw.name}"
    roots = []
    for source in SAMPLE_SOURCES:
        root = conv / source
        if not _valid_dataset(root):
            convert(ConvertOptions(source=source, input=raw / source, root=root, repo_id=f"local/sample_{source}_{mapping}",
                                   source_options=SAMPLE_SOURCE_OPTIONS.get(source, {}), mapping=mapping,
                                   overwrite=True, progress=False))  # fmt: skip
        roots.append(root)
    return roots


def use_real_data(cfg: ExperimentConfig) -> bool:
    """Real recordings unless --data=sample or --datasets is given; --data=real fails when they are absent."""
    from experiments.real_data import real_available

    if cfg.datasets or cfg.data == "sample":
        return False
    if real_available(cfg):
        return True
    if cfg.data == "real":
        raise FileNotFoundError(
            f"--data=real but the real recordings are not under {cfg.real_dir} (g1-inspire/, dex-retargeting/); "
            "set --real_data_dir (or UNIDEXTOK_REAL_DATA) or use --data=sample"
        )
    logger.info("real recordings not found under %s: using the SYNTHETIC sample data", cfg.real_dir)
    return False


def load_data(cfg: ExperimentConfig, mapping: str = "semantic", datasets: list[str] | None = None) -> ExperimentData:
    """Train / test rows of `datasets` (default cfg.datasets), else of the real recordings when present,
    else of the converted SYNTHETIC sample data (both converted with `mapping`)."""
    datasets = list(cfg.datasets if datasets is None else datasets)
    if datasets:
        return ExperimentData(
            load_hand_states(datasets, "train"), load_hand_states(datasets, "test"), datasets, False, source="datasets"
        )
    if use_real_data(cfg):
        from experiments.real_data import real_train_test

        train, test, sources, clip = real_train_test(cfg, mapping)
        return ExperimentData(train, test, sources, False, source="real", clip=clip)
    roots = prepare_sample_data(cfg, mapping)
    names = [str(r) for r in roots]
    return ExperimentData(
        load_hand_states(names, "train"), load_hand_states(names, "test"), roots, True, sample_raw_dir(cfg)
    )


def cap_rows(data: HandStates, max_rows: int, seed: int) -> HandStates:
    """At most `max_rows` rows, drawn evenly per hand (deterministic)."""
    if len(data) <= max_rows:
        return data
    rng = np.random.default_rng(seed)
    per_hand = max(1, max_rows // len(data.hand_names()))
    keep = []
    for hand in data.hand_names():
        rows = np.flatnonzero(data.hands == hand)
        keep.append(rng.choice(rows, size=min(per_hand, len(rows)), replace=False))
    return data.select(np.sort(np.concatenate(keep)))


def hand_masks(data: HandStates) -> dict[str, np.ndarray]:
    """(22,) active-DoF mask per hand: union over its rows."""
    return {h: data.masks[data.hands == h].any(0) for h in data.hand_names()}


def per_hand_states(data: HandStates) -> dict[str, np.ndarray]:
    return {h: data.states_rad[data.hands == h] for h in data.hand_names()}


# ---------------------------------------------------------------------------------------------
# UniDexTok: trained once per (configuration, training rows), cached under models_dir
# ---------------------------------------------------------------------------------------------
def train_config(cfg: ExperimentConfig, output_dir: Path, hand_names: list[str]) -> TrainConfig:
    """`cfg.train` with what the experiment sets itself (`experiments.config.SET_BY_THE_EXPERIMENT`)."""
    return dataclasses.replace(
        cfg.train, save_last_every=10**9, seed=cfg.seed, output_dir=str(output_dir), hand_names=hand_names,
        progress=cfg.progress, eval_max_frames=cfg.max_eval_frames,
    )  # fmt: skip


def trained_unidextok(cfg: ExperimentConfig, tag: str, train: HandStates, select: HandStates):
    """A UniDexTok trained on `train` (checkpoint chosen on `select`), from cache when the same
    configuration and rows were trained before. Returns (model, info dict)."""
    from lerobot_unidextok.tokenizer import UniDexTok

    hands = train.hand_names()
    settings = dataclasses.asdict(train_config(cfg, Path("."), hands))  # every training setting, incl. defaults
    for volatile in ("output_dir", "progress"):
        settings.pop(volatile)
    key = fingerprint(
        settings,
        train.states_rad,
        train.hands.astype("U32"),
        train.masks,
        select.states_rad,
    )
    folder = Path(cfg.models_dir) / f"{tag}-{key}"
    done = folder / "train_info.json"
    if done.is_file() and (folder / "best" / "config.json").is_file():
        info = json.loads(done.read_text())
        info["cached"] = True
        logger.info("reusing tokenizer %s (trained %s s)", folder, info.get("seconds"))
        return UniDexTok.from_pretrained(folder / "best"), info
    shutil.rmtree(folder, ignore_errors=True)
    res = train_tokenizer(train_config(cfg, folder, hands), train, select)
    info = {"dir": str(folder / "best"), "best_step": res.best_step, "steps": res.steps, "seconds": round(res.seconds, 1),
            "select_mae_deg": res.best_mae_deg, "train_hands": hands, "train_rows": len(train), "cached": False}  # fmt: skip
    done.write_text(json.dumps(jsonable(info), indent=2))
    return UniDexTok.from_pretrained(folder / "best"), info


def selection_split(train: HandStates, seed: int, fraction: float = 0.1) -> tuple[HandStates, HandStates]:
    """(fit rows, checkpoint-selection rows): whole training episodes held back per hand
    (`training.splits.split_by_episode`), never test rows; every 10th row when no hand has two episodes."""
    fit, select = split_by_episode(train, fraction, seed)
    if len(select):
        return fit, select
    pick = np.zeros(len(train), dtype=bool)
    pick[:: max(2, int(1 / fraction))] = True
    return train.select(np.flatnonzero(~pick)), train.select(np.flatnonzero(pick))


# ---------------------------------------------------------------------------------------------
# scoring: every method through evaluation.metrics
# ---------------------------------------------------------------------------------------------
def reconstruct_unidextok(model, data: HandStates) -> tuple[np.ndarray, np.ndarray]:
    """(decoded (N, 22) rad, codes (N, T, K)); hands unknown to the model go through its unknown-hand embedding."""
    from lerobot_unidextok.evaluation import reconstruct

    rec = reconstruct(model, data.states_rad, data.hands, allow_unknown=True, masks=data.masks)
    return rec.states_rad, rec.codes


def reconstruct_baseline(tokenizer, data: HandStates) -> np.ndarray:
    """decode(encode(x)) per hand through the `StateTokenizer` protocol."""
    from lerobot_unidextok.baselines import reconstruct

    out = np.zeros_like(data.states_rad)
    for hand in data.hand_names():
        rows = data.hands == hand
        out[rows] = reconstruct(tokenizer, data.states_rad[rows], hand).numpy()
    return out


def score(pred_rad: np.ndarray, data: HandStates) -> dict:
    """`evaluation.metrics.reconstruction_metrics` (overall + per hand)."""
    from lerobot_unidextok.evaluation import reconstruction_metrics

    return reconstruction_metrics(pred_rad, data.states_rad, data.hands, data.masks)


SUMMARY_KEYS = ("rows", "mpjae_deg", "mpjpe_mm", "mpjpe_fingers_mm", "fingertip_mm")


def summary_row(entry: dict) -> dict:
    return {k: entry[k] for k in SUMMARY_KEYS}


def abs_errors_deg(pred_rad: np.ndarray, data: HandStates) -> np.ndarray:
    """(N, 22) absolute angle errors (deg), NaN on inactive slots (for per-joint error bars)."""
    err = np.degrees(np.abs(pred_rad.astype(np.float64) - data.states_rad.astype(np.float64)))
    return np.where(data.masks, err, np.nan)


def reduction_pct(before: float | None, after: float | None) -> float | None:
    if before is None or after is None or not before or math.isnan(before) or math.isnan(after):
        return None
    return 100.0 * (before - after) / before
