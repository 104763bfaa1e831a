"""Ablation: UniDexTok trained with vs without human-hand data, evaluated on the robot hands' held-out states."""

import logging
import time

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.common import (
    HUMAN,
    cap_rows,
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

logger = logging.getLogger(__name__)
NAME = "ablation_human"
WITH, WITHOUT = "with human data", "without human data"


def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    if HUMAN not in data.train.hand_names():
        raise ValueError(f"ablation_human needs human-hand rows in training; the data has {data.train.hand_names()}. "
                         "Add a converted human dataset (DexYCB, EgoDex, OakInk-v2) to --datasets")  # fmt: skip
    robots = [h for h in data.test.hand_names() if h != HUMAN]
    if not robots:
        raise ValueError("ablation_human evaluates robot hands; the held-out split has none. Add a robot dataset")
    test = cap_rows(data.test.only(robots), cfg.max_eval_frames, cfg.seed)
    fit, select = selection_split(data.train, cfg.seed)
    runs = {WITH: (fit, select), WITHOUT: (fit.without(HUMAN), select.without(HUMAN))}
    reports, infos = {}, {}
    for label, (tr, sel) in runs.items():
        model, infos[label] = trained_unidextok(cfg, "all_hands" if label == WITH else "no_human", tr, sel)
        reports[label] = score(reconstruct_unidextok(model, test)[0], test)

    rows = []
    for hand in [*robots, "overall"]:
        w = reports[WITH]["overall" if hand == "overall" else "per_hand"]
        wo = reports[WITHOUT]["overall" if hand == "overall" else "per_hand"]
        w, wo = (w, wo) if hand == "overall" else (w[hand], wo[hand])
        rows.append({"hand": hand, WITH: summary_row(w), WITHOUT: summary_row(wo),
                     "mpjae_reduction_pct": reduction_pct(wo["mpjae_deg"], w["mpjae_deg"]),
                     "mpjpe_reduction_pct": reduction_pct(wo["mpjpe_mm"], w["mpjpe_mm"])})  # fmt: skip
    result = {"experiment": NAME, "provenance": provenance(cfg, data, time.perf_counter() - t0), "rows": rows,
              "training": infos, "figures": {}}  # fmt: skip
    write_result(folder, NAME, result, markdown(result))
    return result


def markdown(result: dict) -> str:
    header = ["robot hand", "MPJAE with (deg)", "MPJAE without (deg)", "MPJAE reduction %", "MPJPE all 21 kp with (mm)",
              "MPJPE all 21 kp without (mm)", "MPJPE reduction %", "MPJPE 15 finger kp with (mm)",
              "MPJPE 15 finger kp without (mm)"]  # fmt: skip
    body = [[r["hand"], r[WITH]["mpjae_deg"], r[WITHOUT]["mpjae_deg"], r["mpjae_reduction_pct"], r[WITH]["mpjpe_mm"],
             r[WITHOUT]["mpjpe_mm"], r["mpjpe_reduction_pct"], r[WITH].get("mpjpe_fingers_mm"),
             r[WITHOUT].get("mpjpe_fingers_mm")] for r in result["rows"]]  # fmt: skip
    return "\n".join([f"# {NAME}", "", ("UniDexTok trained with vs without human-hand rows (same steps, seed and robot "
                      "rows), scored on robot hands' held-out states. Reduction = (without - with) / without."), "",
                      md_table(header, body)])  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv, __doc__)))))


if __name__ == "__main__":
    main()
