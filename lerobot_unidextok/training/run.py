"""What `unidextok-train` runs: load the splits, train, score the selected checkpoint on the test episodes,
k-fold over episodes when asked, write the report and the model cards.

    from lerobot_unidextok.training import TrainConfig
    from lerobot_unidextok.training.run import train_and_evaluate
    report, markdown = train_and_evaluate(TrainConfig(datasets=["data/g1_udhm"], output_dir="outputs/g1"))
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import dataclasses
import json
import logging
import shutil
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.data.destination import (
    DestinationError,
    Kind,
    claim,
    enclosing_unit,
    kind_of,
    move_into_place,
    recover,
    release,
)
from lerobot_unidextok.data.rowstore import INDEX as ROW_STORE_INDEX
from lerobot_unidextok.data.rowstore import HandRowStore
from lerobot_unidextok.errors import ConfigError, InvalidInputError
from lerobot_unidextok.training.arrays import HandStates, load_hand_states, subsample_episodes
from lerobot_unidextok.training.checkpoint import signals_deferred
from lerobot_unidextok.training.config import TrainConfig
from lerobot_unidextok.training.loop import train_tokenizer
from lerobot_unidextok.training.splits import kfold_by_episode, split_by_episode, split_store_by_episode
from lerobot_unidextok.utils.files import temp_sibling

logger = logging.getLogger(__name__)
SUMMARY_KEYS = ("rows", "mpjae_deg", "mpjpe_mm", "fingertip_mm")


# ---------------------------------------------------------------------------------------------
# splits
# ---------------------------------------------------------------------------------------------
def _load_split(datasets: list[str], split: str | None, holdout: str) -> HandStates:
    try:
        return load_hand_states(datasets, split=split, holdout=holdout)
    except ValueError as e:  # a dataset without that split
        if split != "test":
            raise
        logger.warning("no test episodes (%s); the held-out figures come from --folds only", e)
        return HandStates(np.zeros((0, 22)), np.zeros(0, str), np.zeros((0, 22), bool), np.zeros(0), np.zeros(0))


def fit_and_select(cfg: TrainConfig, train: HandStates) -> tuple[HandStates, HandStates]:
    """Held-out selection episodes first, then the few-shot fraction of the rest."""
    if cfg.exclude_hands:
        train = train.without(cfg.exclude_hands)
    fit, select = split_by_episode(train, cfg.select_fraction, seed=cfg.seed)
    return subsample_episodes(fit, cfg.fraction, seed=cfg.seed), select


def load_splits(cfg: TrainConfig) -> tuple[HandStates | HandRowStore, HandStates, HandStates]:
    """(training rows, checkpoint-selection rows, test rows) of `cfg.datasets`.

    In memory: every frame. With `cfg.streaming`: training rows from a memory-mapped row store (built by the
    main process first), and up to `eval_max_frames` rows each for selection and test."""
    if not cfg.streaming:
        train = load_hand_states(cfg.datasets, split="train", holdout=cfg.holdout)
        test = _load_split(cfg.datasets, "test", cfg.holdout)
        fit, select = fit_and_select(cfg, train)
        return fit, select, test
    from accelerate import PartialState

    from lerobot_unidextok.data import open_row_store

    folder = Path(cfg.row_store_dir or Path(cfg.output_dir) / "row_store")
    with PartialState(cpu=cfg.device == "cpu").main_process_first():  # one process builds, the others open
        train = open_row_store(cfg.datasets, "train", folder / "train", cfg.holdout)
        test = open_row_store(cfg.datasets, "test", folder / "test", cfg.holdout)
    if cfg.exclude_hands:
        train = train.without(cfg.exclude_hands)
    fit, select = split_store_by_episode(train, cfg.select_fraction, cfg.eval_max_frames, seed=cfg.seed)
    rows = test.sample_rows(cfg.eval_max_frames, seed=cfg.seed)
    return fit, select, HandStates(rows["states_rad"], rows["hands"], rows["masks"], rows["episode_index"],
                                   rows["dataset_index"])  # fmt: skip


# ---------------------------------------------------------------------------------------------
# k-fold over episodes
# ---------------------------------------------------------------------------------------------
def _summary(report: dict) -> dict:
    """{hand: {rows, mpjae_deg, mpjpe_mm, fingertip_mm, zero_shot}} + overall, from `evaluate_tokenizer`."""
    out = {h: {**{k: e[k] for k in SUMMARY_KEYS}, "zero_shot": e.get("zero_shot", False)}
           for h, e in report["per_hand"].items()}  # fmt: skip
    out["overall"] = {k: report["overall"][k] for k in SUMMARY_KEYS}
    return out


def run_kfold(cfg: TrainConfig) -> dict:
    """`cfg.folds` models, each trained without one fold of episodes (all splits pooled) and scored on it."""
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer
    from lerobot_unidextok.tokenizer import UniDexTok

    pooled = load_hand_states(cfg.datasets, split=None, holdout=cfg.holdout)
    folds = []
    for k, (train, test) in enumerate(kfold_by_episode(pooled, cfg.folds, seed=cfg.seed)):
        fit, select = fit_and_select(cfg, train)
        fold_cfg = dataclasses.replace(cfg, output_dir=str(Path(cfg.output_dir) / "folds" / f"fold_{k}"), resume=False)
        result = train_tokenizer(fold_cfg, fit, select)
        report = evaluate_tokenizer(UniDexTok.from_pretrained(result.best_dir), test)
        folds.append({"fold": k, "test_episodes": int(len(np.unique(test.episode_keys()))),
                      "train_rows": len(fit), "test_rows": len(test), "per_hand": _summary(report)})  # fmt: skip
    hands = sorted({h for f in folds for h in f["per_hand"]})
    summary = {}
    for hand in hands:
        per = [f["per_hand"][hand] for f in folds if hand in f["per_hand"]]
        summary[hand] = {"folds": len(per), "rows": int(sum(p["rows"] for p in per))}
        for key in SUMMARY_KEYS[1:]:
            vals = np.array([p[key] for p in per], dtype=np.float64)
            summary[hand] |= {key: float(vals.mean()), f"{key}_std": float(vals.std(ddof=1)) if len(vals) > 1 else 0.0,
                              f"{key}_min": float(vals.min()), f"{key}_max": float(vals.max())}  # fmt: skip
    return {"folds": cfg.folds, "seed": cfg.seed, "per_fold": folds, "summary": summary}


def kfold_markdown(kfold: dict) -> str:
    lines = [f"k-fold over episodes ({kfold['folds']} folds): MPJAE (deg) on each fold's episodes, mean +- std "
             "over folds [min, max]", "", "| hand | folds | rows | MPJAE (deg) | MPJPE (mm) | fingertip (mm) |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for hand, s in kfold["summary"].items():
        lines.append(f"| {hand} | {s['folds']} | {s['rows']} | {s['mpjae_deg']:.3f} +- {s['mpjae_deg_std']:.3f} "
                     f"[{s['mpjae_deg_min']:.3f}, {s['mpjae_deg_max']:.3f}] | {s['mpjpe_mm']:.3f} | "
                     f"{s['fingertip_mm']:.3f} |")  # fmt: skip
    return "\n".join(lines)


def held_out_results(test_summary: dict | None, kfold: dict | None) -> dict[str, dict]:
    """The run's held-out figures as the model card lists them: test episodes per hand, then k-fold."""
    results = {}
    for hand, s in (test_summary or {}).items():
        results[f"test episodes: {hand}"] = s
    for hand, s in ((kfold or {}).get("summary") or {}).items():
        results[f"{kfold['folds']}-fold episodes: {hand}"] = {k: s[k] for k in ("rows", "mpjae_deg", "mpjae_deg_std",
                                                                               "mpjpe_mm", "fingertip_mm")}  # fmt: skip
    return results


# ---------------------------------------------------------------------------------------------
# the whole run
# ---------------------------------------------------------------------------------------------
RUN_OUTPUTS = ("best", "last", "folds", "row_store", "eval.json", "eval.md", "kfold.json", "kfold.md")
ROW_STORE_SPLITS = ("train", "test")  # the stores `load_splits` keeps in a row-store folder


def check_inputs(cfg: TrainConfig) -> list[Path]:
    """Every input, flag and preset the run needs, checked before anything is written, moved or deleted: the
    datasets are converted UDHM datasets, the preset is known, `init_from` is a tokenizer, --resume and
    --overwrite are not both asked. Returns the datasets' folders."""
    from lerobot_unidextok.data.reader import dataset_folder, udhm_blocks
    from lerobot_unidextok.tokenizer import UniDexTokConfig

    if cfg.resume and cfg.overwrite:
        raise ConfigError("--resume=true continues the run, --overwrite=true replaces it: pass one")
    if not cfg.datasets:
        raise ConfigError("--datasets is empty: pass the converted datasets to train on, e.g. "
                          "--datasets='[data/g1_udhm]'")  # fmt: skip
    roots = []
    for name in cfg.datasets:
        root = dataset_folder(name)  # a missing folder or meta/info.json: named with the fix
        try:
            udhm_blocks(json.loads((root / INFO_PATH).read_text()))
        except (OSError, ValueError) as e:  # ValueError: also a damaged info.json
            raise InvalidInputError(f"--datasets: {root} is not a readable UDHM dataset: {e}") from e
        roots.append(root)
    UniDexTokConfig.from_preset(cfg.preset)  # an unknown preset: named with the choices
    if cfg.init_from:
        UniDexTokConfig.from_pretrained(cfg.init_from)  # not a tokenizer: named with the fix
    return roots


def claim_run_folder(cfg: TrainConfig, roots: list[Path]) -> Path:
    """`cfg.output_dir` may take this run (`data.destination.claim`): not a dataset it reads or anything inside
    one, and an existing run only with --resume or --overwrite. A checkpoint a killed save had set aside is put
    back first. Returns the folder to train into: `output_dir` itself (a new run, or --resume), or, to replace an
    existing run (--overwrite), a temp folder beside it that `train_and_evaluate` moves into place once the new
    run has finished, so a failing run leaves the old one as it was."""
    out = claim(cfg.output_dir, Kind.TOKENIZER_RUN, inputs=roots, overwrite=cfg.overwrite, resume=cfg.resume,
                flag="--output_dir")  # fmt: skip
    for name in ("best", "last"):
        recover(out / name)
    if cfg.streaming and cfg.row_store_dir:
        claim_row_store_dir(Path(cfg.row_store_dir), roots)
    if cfg.overwrite and kind_of(out) is Kind.TOKENIZER_RUN:
        work = temp_sibling(out)
        work.mkdir()
        logger.warning("--overwrite=true: training into %s; it replaces the run at %s when it has finished (until "
                       "then, and if it fails, that run stays as it is)", work.name, out)  # fmt: skip
        return work
    return Path(cfg.output_dir)


def claim_row_store_dir(folder: Path, roots: list[Path]) -> Path:
    """`--row_store_dir` may hold this run's row stores (rebuilt there when out of date): not an input, not
    inside a dataset or a checkpoint, and, when it exists, holding only row stores (`ROW_STORE_SPLITS`)."""
    folder = recover(folder)
    for name in ROW_STORE_SPLITS:
        recover(folder / name)
    for source in roots:
        source = source.resolve()
        if folder == source or source.is_relative_to(folder) or folder.is_relative_to(source):
            raise DestinationError(f"--row_store_dir {folder} is, holds or sits inside the input {source}: "
                                   "choose another --row_store_dir")  # fmt: skip
    unit = enclosing_unit(folder)
    if unit is not None:
        raise DestinationError(f"--row_store_dir {folder} sits inside {unit[1].value} ({unit[0]}), whose files other "
                               "tools read as one unit: choose a --row_store_dir outside it")  # fmt: skip
    if folder.exists() and not folder.is_dir():
        raise DestinationError(f"--row_store_dir {folder} is a file, not a folder: choose another --row_store_dir")
    if folder.is_dir():
        other = sorted(p.name for p in folder.iterdir()
                       if not (p.name in ROW_STORE_SPLITS and (p / ROW_STORE_INDEX).is_file()))  # fmt: skip
        if other:
            raise DestinationError(
                f"--row_store_dir {folder} holds {', '.join(other[:5])}{' ...' if len(other) > 5 else ''}, not only "
                "row stores of unidextok-train (its train/ and test/ are replaced when out of date): choose another "
                "--row_store_dir, or leave it unset (<output_dir>/row_store)"
            )
    return folder


def train_and_evaluate(cfg: TrainConfig) -> tuple[dict, str]:
    """Check the inputs, load splits, train, evaluate the selected checkpoint on the test episodes (and k-fold),
    write output_dir/eval.{json,md} (kfold.{json,md}) and the cards of best/ and last/. A run replacing another
    (--overwrite) trains beside it and takes its place at the end (`claim_run_folder`).

    Returns (report, markdown summary) in the main process; ({}, "") in the others of a multi-process run,
    which only train."""
    from accelerate import PartialState

    if cfg.folds and PartialState().num_processes > 1:
        raise InvalidInputError("--folds trains its fold models one after another in one process: launch without "
                         "accelerate/torchrun, or drop --folds")  # fmt: skip
    roots = check_inputs(cfg)  # in every process: all stop together
    work = _shared(lambda: claim_run_folder(cfg, roots))
    try:
        report, md = _train_and_report(cfg, dataclasses.replace(cfg, output_dir=str(work)))
    except BaseException:  # also Ctrl-C / SIGTERM: an unfinished replacement is removed, the old run kept
        if work != Path(cfg.output_dir) and PartialState().is_main_process:
            with signals_deferred():
                shutil.rmtree(work, ignore_errors=True)
        raise
    finally:
        release(cfg.output_dir)  # the run folder's lock (data/destination.py), however the run ended
    return report, md


def _shared(claim_in_main) -> Path:
    """`claim_in_main()` run by the main process; its folder given to every process (a refusal: raised in the
    main process, and named as such in the others instead of leaving them waiting)."""
    from accelerate import PartialState

    state = PartialState()
    if state.num_processes == 1:
        return claim_in_main()
    from accelerate.utils import broadcast_object_list

    folder, error = None, None
    if state.is_main_process:
        try:
            folder = str(claim_in_main())
        except BaseException as e:
            error = e
    shared = broadcast_object_list([folder])[0]
    if error is not None:
        raise error
    if shared is None:
        raise DestinationError("the main process refused --output_dir (its error line says why)")
    return Path(shared)


def _train_and_report(cfg: TrainConfig, run_cfg: TrainConfig) -> tuple[dict, str]:
    """`train_and_evaluate` once the run folder is claimed: `run_cfg` trains into the folder chosen (a temp folder
    replacing `cfg.output_dir` at the end, or `cfg.output_dir` itself)."""
    from accelerate import PartialState

    from lerobot_unidextok.evaluation.report import describe_scored, evaluate_tokenizer, write_report
    from lerobot_unidextok.hub.card import write_run_cards
    from lerobot_unidextok.tokenizer import UniDexTok

    fit, select, test = load_splits(run_cfg)
    result = train_tokenizer(run_cfg, fit, select)
    if not PartialState().is_main_process:
        return {}, ""
    out, work = Path(cfg.output_dir), Path(run_cfg.output_dir)
    model = UniDexTok.from_pretrained(result.best_dir)
    report = evaluate_tokenizer(model, test) if len(test) else {"per_hand": {}, "overall": {}}
    report["scored"] = describe_scored(test, cfg.datasets, "test", out / "best")  # where it is once the run is done
    if cfg.streaming:  # the test rows are a sample
        report["scored"]["rows"] += f"; at most {cfg.eval_max_frames} rows sampled from these episodes"
    report["training"] = {
        "best_step": result.best_step, "select_mae_deg": result.best_mae_deg, "steps": result.steps,
        "seconds": result.seconds, "train_rows": len(fit), "select_rows": len(select), "test_rows": len(test),
        "preset": cfg.preset, "excluded_hands": cfg.exclude_hands, "fraction": cfg.fraction,
        "hands_trained": fit.hand_names(), "vocabulary": list(model.config.hand_names), "streaming": cfg.streaming,
        "processes": PartialState().num_processes,
    }  # fmt: skip
    kfold = run_kfold(run_cfg) if cfg.folds else None
    if kfold:
        report["kfold"] = kfold
    training = {"datasets": list(cfg.datasets), "excluded_hands": list(cfg.exclude_hands), "fraction": cfg.fraction}
    with signals_deferred():  # the reports, the replacement and the cards: a few small files, never cut half-way
        md = write_report(report, work / "eval") if len(test) else "no test episodes in these datasets"
        if kfold:
            md += "\n\n" + kfold_markdown(kfold)
            (work / "kfold.json").write_text(json.dumps(kfold, indent=2))
            (work / "kfold.md").write_text(kfold_markdown(kfold) + "\n")
        if work != out:
            _replace_run(work, out)
        write_run_cards(out, held_out_results(_summary(report) if len(test) else None, kfold), training,
                        report["scored"] if len(test) else None)  # fmt: skip
    return report, md


def _replace_run(work: Path, out: Path) -> None:
    """Move the finished run `work` into place of the run at `out`, keeping the files the user added to that run
    (anything but `RUN_OUTPUTS`: copied, so the old run stays whole until the new one has replaced it). Called
    with Ctrl-C and SIGTERM held back (`signals_deferred`), so never cut between the two renames."""
    kept = []
    for path in sorted(out.iterdir()):
        if path.name in RUN_OUTPUTS or path.name.startswith(".") or (work / path.name).exists():
            continue
        if path.is_dir():
            shutil.copytree(path, work / path.name, symlinks=True)
        else:
            shutil.copy2(path, work / path.name, follow_symlinks=False)
        kept.append(path.name)
    move_into_place(work, out.resolve(), Kind.TOKENIZER_RUN, overwrite=True)
    logger.info("--overwrite=true: the new run replaced the one at %s%s", out,
                f" (kept from it: {', '.join(kept)})" if kept else "")  # fmt: skip
