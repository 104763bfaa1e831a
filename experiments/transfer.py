"""Transfer to a hand held out of training (Inspire by default): zero-shot through the unknown-hand
embedding, then few-shot on 6.2 % of its training frames for 2 epochs (the paper's setting), both as the
paper's fine-tuning of the whole tokenizer and as adaptation of the new hand's embedding row only.
Per-joint MPJAE and per-finger fingertip error tables with the error reduction few-shot brings.

    python experiments/transfer.py            # real recordings when present: held out = the G1 Inspire hands
    python experiments/transfer.py --data=sample

On the real recordings the base tokenizer trains on the real human clip plus the SYNTHETIC sample robot
hands other than the held-out one (`transfer_sample_hands`). The few-shot frames come from the held-out
hand's train-split episodes (whole episodes first); every figure is on its test-split episodes, which no
model trains on; `fewshot_repeats` draws of the few-shot frames give the mean and spread.
"""

import logging
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.common import (
    cap_rows,
    fmt,
    load_data,
    md_table,
    out_dir,
    provenance,
    reconstruct_unidextok,
    reduction_pct,
    score,
    selection_split,
    summary_row,
    trained_unidextok,
    write_result,
)
from experiments.config import ExperimentConfig, parse_config
from experiments.runtime import setup
from lerobot_unidextok.constants import FINGERTIP_INDICES, KEYPOINT_NAMES
from lerobot_unidextok.training import HandStates, TrainConfig, load_hand_states, subsample_episodes, train_tokenizer

logger = logging.getLogger(__name__)
NAME = "transfer"
ZERO, FEW_ROW, FEW_ALL, FULL = (
    "zero-shot",
    "few-shot, embedding row",
    "few-shot, whole tokenizer (paper)",
    "in training (reference)",
)


def holdout_hand(cfg: ExperimentConfig, hands: list[str]) -> str:
    if cfg.holdout_hand:
        if cfg.holdout_hand not in hands:
            raise ValueError(f"--holdout_hand={cfg.holdout_hand!r} is not in the data; hands: {hands}")
        return cfg.holdout_hand
    inspire = [h for h in hands if "inspire" in h]
    if not inspire:
        raise ValueError(f"no Inspire hand in the data ({hands}); pass --holdout_hand=<one of them>")
    return inspire[0]


def other_sample_hands(cfg: ExperimentConfig, data, hand: str) -> HandStates | None:
    """Train rows of the SYNTHETIC sample robot hands other than `hand` (and the human hand when the data
    has real human rows), added to the base training data of a run on real recordings."""
    from experiments.common import prepare_sample_data

    if data.synthetic or not cfg.transfer_sample_hands:
        return None
    drop = [hand, *(["human"] if "human" in data.train.hand_names() else [])]
    rows = load_hand_states([str(r) for r in prepare_sample_data(cfg)], "train").without(drop)
    return rows if len(rows) else None


def adapt(cfg: ExperimentConfig, base_dir: str, shots: HandStates, how: str, tag: str):
    """Few-shot: the base tokenizer adapted on `shots` for `fewshot_epochs` (final model, no selection)."""
    from lerobot_unidextok.tokenizer import UniDexTok

    lr = cfg.fewshot_lr if how == "hand_embedding" else cfg.fewshot_lr_all
    few_cfg = TrainConfig(
        preset=cfg.train.preset, init_from=base_dir, fraction=1.0, epochs=cfg.fewshot_epochs, batch_size=cfg.fewshot_batch_size,
        lr=lr, adapt=how, unknown_hand_prob=0.0, warmup_steps=1, eval_every=10**9, save_last_every=10**9, seed=cfg.seed,
        select_fraction=0.0, output_dir=str(Path(cfg.models_dir) / f"fewshot_{tag}"), progress=cfg.progress,
    )  # fmt: skip
    res = train_tokenizer(few_cfg, shots, None)
    return UniDexTok.from_pretrained(res.best_dir), res


def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    hand = holdout_hand(cfg, data.train.hand_names())
    pool, scored = data.train.only(hand), cap_rows(data.test.only(hand), cfg.max_eval_frames, cfg.seed)
    if len(scored) == 0:
        raise ValueError(f"{hand}: no test-split rows to score")
    base_rows = data.train.without(hand)
    extra = other_sample_hands(cfg, data, hand)
    if extra is not None:
        base_rows = HandStates.concat([base_rows, extra])
    fit, select = selection_split(base_rows, cfg.seed)
    base, base_info = trained_unidextok(cfg, f"without_{hand}", fit, select)
    # reference: the same base data plus the held-out hand's whole train split
    ref_fit, ref_select = selection_split(HandStates.concat([base_rows, pool]), cfg.seed)
    full, full_info = trained_unidextok(cfg, "with_holdout", ref_fit, ref_select)

    reports = {ZERO: score(reconstruct_unidextok(base, scored)[0], scored),
               FULL: score(reconstruct_unidextok(full, scored)[0], scored)}  # fmt: skip
    repeats = []
    for r in range(cfg.fewshot_repeats):
        shots = subsample_episodes(pool, cfg.fewshot_fraction, seed=cfg.seed + r)
        entry = {"repeat": r, "frames": len(shots), "episodes": int(len(np.unique(shots.episode_keys())))}
        for label, how in ((FEW_ROW, "hand_embedding"), (FEW_ALL, "all")):
            model, res = adapt(
                cfg, base_info["dir"], shots, how, f"{hand}_{how}_r{r}_{Path(base_info['dir']).parent.name}"
            )
            entry[label] = score(reconstruct_unidextok(model, scored)[0], scored)
            entry[f"{label} steps"], entry[f"{label} seconds"] = res.steps, round(res.seconds, 1)
        repeats.append(entry)
    for label in (FEW_ROW, FEW_ALL):
        reports[label] = repeats[0][label]

    def per_hand(report: dict) -> dict:
        return report["per_hand"][hand]

    spread = {label: [per_hand(e[label])["mpjae_deg"] for e in repeats] for label in (FEW_ROW, FEW_ALL)}
    summary = {k: summary_row(per_hand(reports[k])) for k in (ZERO, FEW_ROW, FEW_ALL, FULL)}
    for label, vals in spread.items():
        summary[label] |= {"mpjae_deg": float(np.mean(vals)), "mpjae_deg_std": float(np.std(vals, ddof=1)) if len(vals) > 1
                           else 0.0, "mpjae_deg_repeats": vals}  # fmt: skip
    per_joint = {}
    for joint in per_hand(reports[ZERO])["per_joint_deg"]:
        row = {k: float(np.mean([per_hand(e[k])["per_joint_deg"][joint] for e in repeats])) for k in (FEW_ROW, FEW_ALL)}
        row[ZERO], row[FULL] = (per_hand(reports[k])["per_joint_deg"][joint] for k in (ZERO, FULL))
        row["reduction_pct"] = reduction_pct(row[ZERO], min(row[FEW_ROW], row[FEW_ALL]))
        per_joint[joint] = row
    per_finger = {}
    for tip in (KEYPOINT_NAMES[i] for i in FINGERTIP_INDICES):
        row = {k: float(np.mean([per_hand(e[k])["per_keypoint_mm"][tip] for e in repeats])) for k in (FEW_ROW, FEW_ALL)}
        row[ZERO], row[FULL] = (per_hand(reports[k])["per_keypoint_mm"][tip] for k in (ZERO, FULL))
        row["reduction_pct"] = reduction_pct(row[ZERO], min(row[FEW_ROW], row[FEW_ALL]))
        per_finger[tip] = row
    fs = repeats[0]
    result = {
        "experiment": NAME, "provenance": provenance(cfg, data, time.perf_counter() - t0), "holdout_hand": hand,
        "target": {"pool_rows": len(pool), "scored_rows": len(scored), "base_hands": base_rows.hand_names(),
                   "sample_hands_added": [] if extra is None else extra.hand_names()},
        "fewshot": {"fraction": cfg.fewshot_fraction, "epochs": cfg.fewshot_epochs, "frames": fs["frames"],
                    "of_frames": len(pool), "repeats": cfg.fewshot_repeats, "lr_embedding_row": cfg.fewshot_lr,
                    "lr_whole_tokenizer": cfg.fewshot_lr_all, "steps": fs[f"{FEW_ROW} steps"],
                    "seconds": fs[f"{FEW_ROW} seconds"]},
        "summary": summary,
        "mpjae_reduction_pct": {k: reduction_pct(summary[ZERO]["mpjae_deg"], summary[k]["mpjae_deg"]) for k in (FEW_ROW, FEW_ALL)},
        "per_joint_deg": per_joint, "per_finger_tip_mm": per_finger,
        "training": {"base_without_holdout": base_info, "reference_with_holdout": full_info}, "figures": {},
    }  # fmt: skip
    from lerobot_unidextok import viz
    from lerobot_unidextok.constants import UDHM_JOINT_NAMES

    result["figures"]["per_joint_errors"] = str(viz.plot_per_joint_errors(
        {label: [per_joint.get(j, {}).get(label, float("nan")) for j in UDHM_JOINT_NAMES] for label in (ZERO, FEW_ROW, FEW_ALL)},
        folder / "per_joint_errors.png", title=f"{hand} held out: zero-shot vs few-shot per-joint error"))  # fmt: skip
    write_result(folder, NAME, result, markdown(result))
    return result


def markdown(result: dict) -> str:
    fs, tgt = result["fewshot"], result["target"]
    lines = [f"# {NAME}", "", (
        f"Held-out hand: **{result['holdout_hand']}**, scored on {tgt['scored_rows']} rows of test-split episodes. "
        f"Zero-shot = tokenizer trained without it on {', '.join(tgt['base_hands'])} (unknown-hand embedding; "
        f"SYNTHETIC sample hands added: {', '.join(tgt['sample_hands_added']) or 'none'}); few-shot = that tokenizer adapted on {fs['frames']} of "
        f"{fs['of_frames']} train-split rows ({100 * fs['fraction']:.1f} %) for {fs['epochs']:g} epochs ({fs['steps']} "
        f"steps), mean +- std over {fs['repeats']} draws of those rows: only the new embedding row (lr "
        f"{fs['lr_embedding_row']:g}) or the whole tokenizer (paper, lr {fs['lr_whole_tokenizer']:g}); reference = "
        "trained with its whole train split. Reduction = (zero - few) / zero."), ""]  # fmt: skip

    def _mpjae(v: dict) -> str:
        return fmt(v["mpjae_deg"], 3) + (f" +- {fmt(v['mpjae_deg_std'], 3)}" if "mpjae_deg_std" in v else "")

    lines.append(md_table(["setting", "MPJAE (deg)", "MPJPE (mm)", "fingertip (mm)"],
                          [[k, _mpjae(v), v["mpjpe_mm"], v["fingertip_mm"]] for k, v in result["summary"].items()]))  # fmt: skip
    red = result["mpjae_reduction_pct"]
    lines += ["", "MPJAE reduction: " + ", ".join(f"{k} {fmt(v, 1)} %" for k, v in red.items()) + ".", "",
              "Per-joint MPJAE (deg), few-shot = mean over draws:", ""]  # fmt: skip
    cols = [ZERO, FEW_ROW, FEW_ALL, "reduction_pct", FULL]
    lines.append(md_table(["joint", *cols], [[j, *[v[c] for c in cols]] for j, v in result["per_joint_deg"].items()]))
    lines += ["", "Per-finger fingertip error (mm):", ""]
    lines.append(
        md_table(["fingertip", *cols], [[t, *[v[c] for c in cols]] for t, v in result["per_finger_tip_mm"].items()])
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv, __doc__)))))


if __name__ == "__main__":
    main()
