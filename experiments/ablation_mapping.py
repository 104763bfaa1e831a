"""Ablation: semantic insertion vs append-and-pad. The same raw sources are converted both ways and a
UniDexTok is trained on each; both are scored on the same held-out frames.

MPJAE is over each hand's native DoFs in either layout. For MPJPE / fingertip error the append-and-pad
reconstruction is moved back into the semantic slots (a pure slot permutation per hand, derived through
the hand spec's public mapping functions) so forward kinematics sees joints where they belong.
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
    ExperimentData,
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
from lerobot_unidextok.constants import INFO_PATH, MAPPINGS
from lerobot_unidextok.training import HandStates, load_hand_states

logger = logging.getLogger(__name__)
NAME = "ablation_mapping"


def append_to_semantic_perm(hand: str) -> np.ndarray | None:
    """`perm` with semantic[perm[k]] = append_pad[k] for the hand's active DoFs; None = same layout."""
    from lerobot_unidextok import hands as registry

    spec = registry.get(hand)
    if spec.kind == "keypoints":
        return None
    return spec.slot_indices("right")  # append_pad position k holds the k-th active joint, i.e. this slot


def to_semantic(states_rad: np.ndarray, hands: np.ndarray) -> np.ndarray:
    out = np.zeros_like(states_rad)
    for hand in np.unique(hands):
        rows = hands == hand
        perm = append_to_semantic_perm(str(hand))
        if perm is None:
            out[rows] = states_rad[rows]
        else:
            out[np.ix_(rows, perm)] = states_rad[np.ix_(rows, np.arange(len(perm)))]
    return out


def _datasets(cfg: ExperimentConfig, mapping: str) -> ExperimentData:
    if not cfg.raw_sources:
        return load_data(cfg, mapping, datasets=[])
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    roots = []
    for item in cfg.raw_sources:
        source, path = item.split("=", 1)
        root = Path(cfg.data_dir) / f"{mapping}_user" / f"{source}_{abs(hash(path)) % 10**8}"
        if not (root / INFO_PATH).is_file():
            convert(ConvertOptions(source=source, input=path, root=root, repo_id=f"local/{source}_{mapping}", mapping=mapping,
                                   overwrite=True, progress=cfg.progress))  # fmt: skip
        roots.append(str(root))
    return ExperimentData(load_hand_states(roots, "train"), load_hand_states(roots, "test"), roots, False)


def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = {m: _datasets(cfg, m) for m in MAPPINGS}
    sem_test = data["semantic"].test
    if len(sem_test) != len(data["append_pad"].test) or not np.array_equal(
        sem_test.hands, data["append_pad"].test.hands
    ):
        raise ValueError("the two conversions disagree on the held-out frames; convert the same raw sources both ways")
    keep = cap_rows(
        HandStates(
            sem_test.states_rad,
            sem_test.hands,
            sem_test.masks,
            np.arange(len(sem_test)),
        ),
        cfg.max_eval_frames,
        cfg.seed,
    ).episode_index
    check = to_semantic(data["append_pad"].test.states_rad[keep], sem_test.hands[keep])
    layout_error = float(np.abs(check - sem_test.states_rad[keep]).max())  # 0 when the permutation is right
    reports, infos, mpjae_native = {}, {}, {}
    for m in MAPPINGS:
        fit, select = selection_split(data[m].train, cfg.seed)
        model, infos[m] = trained_unidextok(cfg, f"all_hands_{m}" if m != "semantic" else "all_hands", fit, select)
        test = data[m].test.select(keep)
        pred = reconstruct_unidextok(model, test)[0]
        mpjae_native[m] = score(pred, test)  # angles in the layout the model saw (native DoFs)
        sem_pred = pred if m == "semantic" else to_semantic(pred, test.hands)
        reports[m] = score(sem_pred, sem_test.select(keep))
    rows = []
    for hand in [*sem_test.hand_names(), "overall"]:
        pick = (lambda r: r["overall"]) if hand == "overall" else (lambda r, h=hand: r["per_hand"][h])
        entry = {"hand": hand}
        for m in MAPPINGS:
            entry[m] = {
                **summary_row(pick(reports[m])),
                "mpjae_deg": pick(mpjae_native[m])["mpjae_deg"],
            }
        entry["mpjae_reduction_pct"] = reduction_pct(entry["append_pad"]["mpjae_deg"], entry["semantic"]["mpjae_deg"])
        entry["mpjpe_reduction_pct"] = reduction_pct(entry["append_pad"]["mpjpe_mm"], entry["semantic"]["mpjpe_mm"])
        rows.append(entry)
    result = {"experiment": NAME, "provenance": provenance(cfg, data["semantic"], time.perf_counter() - t0),
              "rows": rows, "training": infos, "layout_check_max_abs_rad": layout_error, "figures": {}}  # fmt: skip
    write_result(folder, NAME, result, markdown(result))
    return result


def markdown(result: dict) -> str:
    header = ["hand", "MPJAE semantic (deg)", "MPJAE append-pad (deg)", "MPJAE reduction %", "MPJPE all 21 kp semantic (mm)",
              "MPJPE all 21 kp append-pad (mm)", "MPJPE reduction %", "MPJPE 15 finger kp semantic (mm)",
              "MPJPE 15 finger kp append-pad (mm)"]  # fmt: skip
    body = [[r["hand"], r["semantic"]["mpjae_deg"], r["append_pad"]["mpjae_deg"], r["mpjae_reduction_pct"],
             r["semantic"]["mpjpe_mm"], r["append_pad"]["mpjpe_mm"], r["mpjpe_reduction_pct"],
             r["semantic"].get("mpjpe_fingers_mm"), r["append_pad"].get("mpjpe_fingers_mm")] for r in result["rows"]]  # fmt: skip
    return "\n".join([f"# {NAME}", "", ("Same raw sources converted with semantic insertion and with append-and-pad, one "
                      "UniDexTok each (same steps and seed). Reduction = (append-pad - semantic) / append-pad. "
                      f"Layout check (max |permuted append-pad - semantic| on held-out states): "
                      f"{result['layout_check_max_abs_rad']:.2e} rad."), "", md_table(header, body)])  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    print(markdown(run(setup(parse_config(argv, __doc__)))))


if __name__ == "__main__":
    main()
