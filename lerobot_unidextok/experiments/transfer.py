"""Transfer to a hand held out of training (Inspire by default): zero-shot through the unknown-hand
embedding, then few-shot adaptation on 6.2 % of its training frames for 2 epochs (the paper's setting).
Per-joint MPJAE and per-finger fingertip error tables with the error reduction few-shot brings."""

import logging
import time
from pathlib import Path

from lerobot_unidextok.constants import FINGERTIP_INDICES, KEYPOINT_NAMES
from lerobot_unidextok.experiments.common import (
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
from lerobot_unidextok.experiments.config import ExperimentConfig, parse_config
from lerobot_unidextok.experiments.runtime import setup
from lerobot_unidextok.training import TrainConfig, subsample_episodes, train_tokenizer

logger = logging.getLogger(__name__)
NAME = "transfer"
ZERO, FEW, FULL = "zero-shot", "few-shot", "in training (reference)"


def holdout_hand(cfg: ExperimentConfig, hands: list[str]) -> str:
    if cfg.holdout_hand:
        if cfg.holdout_hand not in hands:
            raise ValueError(f"--holdout_hand={cfg.holdout_hand!r} is not in the data; hands: {hands}")
        return cfg.holdout_hand
    inspire = [h for h in hands if "inspire" in h]
    if not inspire:
        raise ValueError(f"no Inspire hand in the data ({hands}); pass --holdout_hand=<one of them>")
    return inspire[0]


def run(cfg: ExperimentConfig) -> dict:
    from lerobot_unidextok.tokenizer import UniDexTok

    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    hand = holdout_hand(cfg, data.train.hand_names())
    test = cap_rows(data.test.only(hand), cfg.max_eval_frames, cfg.seed)
    fit, select = selection_split(data.train, cfg.seed)

    base, base_info = trained_unidextok(cfg, f"without_{hand}", fit.without(hand), select.without(hand))
    full, full_info = trained_unidextok(cfg, "all_hands", fit, select)
    reports = {ZERO: score(reconstruct_unidextok(base, test)[0], test)}

    # few-shot: the first fraction of the held-out hand's training frames (whole episodes first);
    # the checkpoint is chosen on those same frames, so no held-out frame is seen before scoring
    shots = subsample_episodes(data.train.only(hand), cfg.fewshot_fraction, seed=cfg.seed)
    few_cfg = TrainConfig(
        preset=cfg.preset, init_from=base_info["dir"], fraction=1.0, epochs=cfg.fewshot_epochs, batch_size=cfg.fewshot_batch_size,
        lr=cfg.fewshot_lr, adapt=cfg.fewshot_adapt, unknown_hand_prob=0.0, warmup_steps=1, eval_every=1, save_last_every=10**9, seed=cfg.seed,
        output_dir=str(Path(cfg.models_dir) / f"fewshot_{hand}_{Path(base_info['dir']).parent.name}"), progress=cfg.progress,
    )  # fmt: skip
    few_res = train_tokenizer(few_cfg, shots, shots)
    few = UniDexTok.from_pretrained(few_res.best_dir)
    reports[FEW] = score(reconstruct_unidextok(few, test)[0], test)
    reports[FULL] = score(reconstruct_unidextok(full, test)[0], test)

    per_joint = {}
    for joint in reports[ZERO]["per_hand"][hand]["per_joint_deg"]:
        z, f = (reports[k]["per_hand"][hand]["per_joint_deg"][joint] for k in (ZERO, FEW))
        per_joint[joint] = {
            ZERO: z,
            FEW: f,
            FULL: reports[FULL]["per_hand"][hand]["per_joint_deg"][joint],
            "reduction_pct": reduction_pct(z, f),
        }
    per_finger = {}
    for tip in (KEYPOINT_NAMES[i] for i in FINGERTIP_INDICES):
        z, f = (reports[k]["per_hand"][hand]["per_keypoint_mm"][tip] for k in (ZERO, FEW))
        per_finger[tip] = {
            ZERO: z,
            FEW: f,
            FULL: reports[FULL]["per_hand"][hand]["per_keypoint_mm"][tip],
            "reduction_pct": reduction_pct(z, f),
        }
    summary = {k: summary_row(r["per_hand"][hand]) for k, r in reports.items()}
    result = {
        "experiment": NAME, "provenance": provenance(cfg, data, time.perf_counter() - t0), "holdout_hand": hand,
        "fewshot": {"fraction": cfg.fewshot_fraction, "epochs": cfg.fewshot_epochs, "frames": len(shots),
                    "of_frames": int((data.train.hands == hand).sum()), "steps": few_res.steps, "seconds": round(few_res.seconds, 1)},
        "summary": summary, "mpjae_reduction_pct": reduction_pct(summary[ZERO]["mpjae_deg"], summary[FEW]["mpjae_deg"]),
        "fingertip_reduction_pct": reduction_pct(summary[ZERO]["fingertip_mm"], summary[FEW]["fingertip_mm"]),
        "per_joint_deg": per_joint, "per_finger_tip_mm": per_finger,
        "training": {"base_without_holdout": base_info, "reference_with_holdout": full_info}, "figures": {},
    }  # fmt: skip
    from lerobot_unidextok import viz

    result["figures"]["per_joint_errors"] = str(viz.plot_per_joint_errors(
        {ZERO: [per_joint.get(j, {}).get(ZERO, float("nan")) for j in _joints()],
         FEW: [per_joint.get(j, {}).get(FEW, float("nan")) for j in _joints()]},
        folder / "per_joint_errors.png", title=f"{hand} held out: zero-shot vs few-shot per-joint error"))  # fmt: skip
    write_result(folder, NAME, result, markdown(result))
    return result


def _joints() -> list[str]:
    from lerobot_unidextok.constants import UDHM_JOINT_NAMES

    return list(UDHM_JOINT_NAMES)


def markdown(result: dict) -> str:
    fs = result["fewshot"]
    lines = [f"# {NAME}", "", (f"Held-out hand: **{result['holdout_hand']}**. Zero-shot = tokenizer trained without it "
             f"(unknown-hand embedding); few-shot = that tokenizer adapted on {fs['frames']} of its {fs['of_frames']} "
             f"training frames ({100 * fs['fraction']:.1f} %) for {fs['epochs']:g} epochs ({fs['steps']} steps, "
             f"{fs['seconds']} s); reference = the tokenizer trained with it. Reduction = (zero - few) / zero."), ""]  # fmt: skip
    lines.append(md_table(["setting", "MPJAE (deg)", "MPJPE (mm)", "fingertip (mm)"],
                          [[k, v["mpjae_deg"], v["mpjpe_mm"], v["fingertip_mm"]] for k, v in result["summary"].items()]))  # fmt: skip
    lines += ["", (f"MPJAE reduction {fmt(result['mpjae_reduction_pct'], 1)} %, fingertip reduction "
              f"{fmt(result['fingertip_reduction_pct'], 1)} %."), "", "Per-joint MPJAE (deg):", ""]  # fmt: skip
    lines.append(md_table(["joint", ZERO, FEW, "reduction %", FULL],
                          [[j, v[ZERO], v[FEW], v["reduction_pct"], v[FULL]] for j, v in result["per_joint_deg"].items()]))  # fmt: skip
    lines += ["", "Per-finger fingertip error (mm):", ""]
    lines.append(md_table(["fingertip", ZERO, FEW, "reduction %", FULL],
                          [[t, v[ZERO], v[FEW], v["reduction_pct"], v[FULL]] for t, v in result["per_finger_tip_mm"].items()]))  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv, __doc__)))))


if __name__ == "__main__":
    main()
