"""Main table, the paper's two protocols, every method scored by the same code (`evaluation.metrics`):

(a) each method on its own test data: UniDexTok, uniform binning, PCA-8 x 8-bit, FSQ and RVQ trained on the
    experiment's training episodes and scored on its held-out episodes; UniHM trained per robot hand on human
    motion retargeted to it and scored on its retargeted held-out motion (UniHM's own data).
(b) every tokenizer on the retargeted held-out human motion: UniDexTok zero-shot (never trained on retargeted
    data; hands it never saw go through its unknown-hand embedding), UniHM as in (a), and binning / PCA / FSQ /
    RVQ fitted on the retargeted training motion like UniHM.
Default data: the real recordings in ../shared/data/real (G1 Inspire, the real human clip retargeted onto
LinkerHand L10 / L20, XHand1 and Inspire with dex-retargeting); the SYNTHETIC sample otherwise. Also the
rate-distortion plots, 3D renderings, per-joint error bars and codebook usage.
"""

import logging
import time

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import baselines as B
from experiments.common import (
    UNIDEXTOK,
    abs_errors_deg,
    cap_rows,
    fmt,
    load_data,
    md_table,
    out_dir,
    provenance,
    reconstruct_baseline,
    reconstruct_unidextok,
    score,
    selection_split,
    summary_row,
    trained_unidextok,
    write_result,
)
from experiments.config import ExperimentConfig, parse_config
from experiments.retargeted import retargeted_pairs
from experiments.runtime import setup
from lerobot_unidextok.training import HandStates

logger = logging.getLogger(__name__)
NAME = "main_table"
BINNING, FSQ, RVQ = "uniform binning", "FSQ", "RVQ"
UNIHM_RETARGETED, UNIHM_INSERTED = B.UNIHM_RETARGETED, B.UNIHM_INSERTED
METRIC_HEADER = ["MPJAE (deg)", "MPJPE all 21 kp (mm)", "MPJPE 15 finger kp (mm)", "fingertip (mm)"]


def pca_name(cfg: ExperimentConfig) -> str:
    return f"PCA-{cfg.pca_components} x {cfg.pca_bits}-bit"


def _rates(tok, hands: list[str]) -> dict[str, tuple[int, float]]:
    return {h: (tok.rate(h).tokens_per_state, tok.rate(h).bits_per_state) for h in hands}


def _unidextok_rates(model, hands: list[str]) -> dict[str, tuple[int, float]]:
    c = model.config
    return {h: (c.num_tokens, c.num_tokens * c.num_groups * float(np.log2(c.codebook_size))) for h in hands}


def _rows(protocol: str, method: str, pred: np.ndarray, test: HandStates, rates: dict, trained_on: str,
          notes: dict[str, str] | None = None) -> tuple[list[dict], dict]:  # fmt: skip
    rep = score(pred, test)
    rows = []
    for hand in test.hand_names():
        tokens, bits = rates[hand]
        rows.append({"protocol": protocol, "method": method, "hand": hand, "trained_on": trained_on,
                     "note": (notes or {}).get(hand, ""), "tokens_per_state": int(tokens), "bits_per_state": float(bits),
                     **summary_row(rep["per_hand"][hand])})  # fmt: skip
    overall = {
        **summary_row(rep["overall"]),
        "per_joint_deg": rep["overall"]["per_joint_deg"],
        "trained_on": trained_on,
    }
    return rows, overall


def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    test = cap_rows(data.test, cfg.max_eval_frames, cfg.seed)
    fit, select = selection_split(data.train, cfg.seed)
    own_label = {"real": "real recordings, train episodes", "sample": "SYNTHETIC sample, train episodes",
                 "datasets": "given datasets, train episodes"}[data.source]  # fmt: skip

    model, train_info = trained_unidextok(cfg, "all_hands", fit, select)
    pred_udt, codes = reconstruct_unidextok(model, test)
    rows, overall, fit_seconds = [], {"a": {}, "b": {}}, {UNIDEXTOK: train_info["seconds"]}
    preds_a = {UNIDEXTOK: pred_udt}
    r, o = _rows("a", UNIDEXTOK, pred_udt, test, _unidextok_rates(model, test.hand_names()), own_label)
    rows += r
    overall["a"][UNIDEXTOK] = o

    # --- protocol (a): the rivals trained on the same training episodes ---------------------------------
    builders = {BINNING: lambda tr: B.binning(tr), pca_name(cfg): lambda tr: B.pca(cfg, tr)}
    if cfg.with_qae:
        builders[FSQ] = lambda tr: B.quantized_ae(cfg, tr, "fsq")
        builders[RVQ] = lambda tr: B.quantized_ae(cfg, tr, "rvq")
    for method, build in builders.items():
        t = time.perf_counter()
        tok = build(data.train if method == BINNING else fit)
        if tok is None:
            continue
        fit_seconds[method] = round(time.perf_counter() - t, 1)
        preds_a[method] = reconstruct_baseline(tok, test)
        r, overall["a"][method] = _rows("a", method, preds_a[method], test, _rates(tok, test.hand_names()), own_label)
        rows += r

    # --- UniHM: per robot hand on retargeted human motion (its recipe), else the insertion stand-in --------
    pairs = retargeted_pairs(cfg, data)
    t = time.perf_counter()
    unihm_tok, unihm_name = B.unihm_for(cfg, fit, pairs)
    fit_seconds[unihm_name] = round(time.perf_counter() - t, 1)
    if pairs is not None:
        rt_test = pairs.test_states()
        pred = reconstruct_baseline(unihm_tok, rt_test)
        r, overall["a"][unihm_name] = _rows("a", unihm_name, pred, rt_test, _rates(unihm_tok, rt_test.hand_names()),
                                            "retargeted human motion (train)")  # fmt: skip
    else:
        preds_a[unihm_name] = reconstruct_baseline(unihm_tok, test)
        r, overall["a"][unihm_name] = _rows("a", unihm_name, preds_a[unihm_name], test,
                                            _rates(unihm_tok, test.hand_names()), own_label)  # fmt: skip
    rows += r

    # --- protocol (b): everyone on the retargeted held-out human motion ------------------------------------
    retarget_info = None
    if pairs is not None:
        rt_train, rt_test = pairs.train_states(), pairs.test_states()
        unseen = {h: "zero-shot (hand unseen)" for h in rt_test.hand_names() if not model.knows_hand(h)}
        seen = {h: "zero-shot (hand seen, motion unseen)" for h in rt_test.hand_names() if model.knows_hand(h)}
        r, overall["b"][UNIDEXTOK] = _rows("b", UNIDEXTOK, reconstruct_unidextok(model, rt_test)[0], rt_test,
                                           _unidextok_rates(model, rt_test.hand_names()), own_label + " (no retargeted data)",
                                           {**seen, **unseen})  # fmt: skip
        rows += r
        r, overall["b"][UNIHM_RETARGETED] = _rows("b", UNIHM_RETARGETED, reconstruct_baseline(unihm_tok, rt_test), rt_test,
                                                  _rates(unihm_tok, rt_test.hand_names()), "retargeted human motion (train)")  # fmt: skip
        rows += r
        for method, build in builders.items():
            tok = build(rt_train)
            if tok is None:
                continue
            r, overall["b"][method] = _rows("b", method, reconstruct_baseline(tok, rt_test), rt_test,
                                            _rates(tok, rt_test.hand_names()), "retargeted human motion (train)")  # fmt: skip
            rows += r
        retarget_info = {"source": pairs.source, "hands": pairs.hands, "mean_target_error_mm": pairs.target_error_mm,
                         "train_rows_per_hand": len(pairs.human_train), "test_rows_per_hand": len(pairs.human_test)}  # fmt: skip

    # --- figures --------------------------------------------------------------------------------------
    from lerobot_unidextok import viz
    from lerobot_unidextok.evaluation import codebook_usage

    rows_a = [r for r in rows if r["protocol"] == "a"]
    rows_b = [r for r in rows if r["protocol"] == "b"]
    figures = {
        "rate_distortion_mpjae": str(viz.plot_rate_distortion(rows_a, folder / "rate_distortion_mpjae.png",
                                                              title="rate-distortion, protocol (a): own held-out data")),
        "rate_distortion_mpjpe_fingers": str(viz.plot_rate_distortion(rows_a, folder / "rate_distortion_mpjpe_fingers.png",
                                                                      error="mpjpe_fingers_mm", error_label="MPJPE, 15 finger keypoints (mm)",
                                                                      title="rate-distortion, protocol (a): own held-out data")),
        "per_joint_errors": str(viz.plot_per_joint_errors({m: abs_errors_deg(p, test) for m, p in preds_a.items()},
                                                          folder / "per_joint_errors.png",
                                                          title="per-joint angle error, held-out states, all hands")),
        "codebook_usage": str(viz.plot_codebook_usage(codes, model.config.codebook_size, folder / "codebook_usage.png",
                                                      title="UniDexTok codebook usage (held-out states)")),
    }  # fmt: skip
    if rows_b:
        figures["rate_distortion_mpjae_b"] = str(viz.plot_rate_distortion(
            rows_b, folder / "rate_distortion_mpjae_b.png", title="rate-distortion, protocol (b): retargeted held-out motion"))  # fmt: skip
    rng = np.random.default_rng(cfg.seed)
    rival = UNIHM_INSERTED if UNIHM_INSERTED in preds_a else pca_name(cfg)
    for hand in test.hand_names():
        rows_h = np.flatnonzero(test.hands == hand)
        pick = np.sort(rng.choice(rows_h, size=min(cfg.render_samples, len(rows_h)), replace=False))
        figures[f"render_{hand}"] = str(viz.plot_hand_reconstructions(
            test.states_rad[pick], {UNIDEXTOK: preds_a[UNIDEXTOK][pick], rival: preds_a[rival][pick]},
            hand, folder / f"render_{hand}.png", title=f"{hand}: ground truth (light) vs {UNIDEXTOK} (green) vs {rival} (red)"))  # fmt: skip

    result = {
        "experiment": NAME,
        "provenance": provenance(cfg, data, time.perf_counter() - t0),
        "methods": sorted({r["method"] for r in rows}),
        "pca_method": pca_name(cfg),
        "rows": rows,
        "overall": overall,
        "fit_seconds": fit_seconds,
        "unidextok_training": train_info,
        "retargeting": retarget_info,
        "codebook": codebook_usage(codes, model.config.codebook_size),
        "figures": figures,
    }
    write_result(folder, NAME, result, markdown(result))
    return result


# ---------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------
def _table(rows: list[dict]) -> str:
    header = ["hand", "method", "trained on", "note", "tokens/state", "bits/state", *METRIC_HEADER]
    body = [[r["hand"], r["method"], r["trained_on"], r["note"] or "-", r["tokens_per_state"], f"{r['bits_per_state']:g}",
             r["mpjae_deg"], r["mpjpe_mm"], r["mpjpe_fingers_mm"], r["fingertip_mm"]] for r in rows]  # fmt: skip
    return md_table(header, body)


def _overall_table(overall: dict) -> str:
    return md_table(["method", "trained on", *METRIC_HEADER],
                    [[m, o["trained_on"], o["mpjae_deg"], o["mpjpe_mm"], o["mpjpe_fingers_mm"], o["fingertip_mm"]]
                     for m, o in overall.items()])  # fmt: skip


def pca_verdict(result: dict) -> list[str]:
    """Does the PCA rival beat UniDexTok on held-out episodes? Per protocol: per hand and over all rows
    (the overall mean weights hands by their held-out rows)."""
    pca, out = result["pca_method"], []
    for protocol, label in (("a", "own held-out episodes"), ("b", "retargeted held-out motion")):
        rows = [r for r in result["rows"] if r.get("protocol", "a") == protocol]
        by = {(r["method"], r["hand"]): r for r in rows}
        hands = sorted(h for m, h in by if m == UNIDEXTOK and (pca, h) in by)
        if not hands:
            continue
        wins = [h for h in hands if by[(pca, h)]["mpjae_deg"] < by[(UNIDEXTOK, h)]["mpjae_deg"]]
        detail = "; ".join(f"{h} {by[(pca, h)]['mpjae_deg']:.2f} vs {by[(UNIDEXTOK, h)]['mpjae_deg']:.2f} deg "
                           f"({by[(pca, h)]['tokens_per_state']} tokens, {by[(pca, h)]['bits_per_state']:g} bits)" for h in hands)  # fmt: skip
        o = result["overall"].get(protocol, {})
        overall = ""
        if pca in o and UNIDEXTOK in o:
            overall = f"; over all rows {o[pca]['mpjae_deg']:.2f} vs {o[UNIDEXTOK]['mpjae_deg']:.2f} deg"
        out.append(f"- Protocol ({protocol}), {label}: {pca} beats UniDexTok on {len(wins)} of {len(hands)} hands "
                   f"({', '.join(wins) or 'none'}). MPJAE, PCA vs UniDexTok: {detail}{overall}.")  # fmt: skip
    return out


def markdown(result: dict) -> str:
    rows = result["rows"]
    rows_a = [r for r in rows if r.get("protocol", "a") == "a"]
    rows_b = [r for r in rows if r.get("protocol") == "b"]
    rt = result.get("retargeting")
    lines = [
        f"# {NAME}",
        "",
        ("Metrics (`evaluation.metrics`, one code for every method): MPJAE over each hand's active DoFs; MPJPE "
         "through UDHM forward kinematics over all 21 keypoints and over the 15 finger keypoints (the wrist and "
         "the 5 finger bases are fixed on the palm and always have 0 error, so the 21-keypoint mean is ~15/21 of "
         "the finger mean; the paper does not say which it averages); fingertip error over the 5 tips."),
        "",
        "### Protocol (a): each method on its own held-out data",
        "",
        _table(rows_a),
        "",
        "Overall (all held-out rows of each method's own test data):",
        "",
        _overall_table(result["overall"].get("a", result["overall"])),
    ]  # fmt: skip
    if rows_b:
        lines += [
            "",
            "### Protocol (b): every tokenizer on the retargeted held-out human motion",
            "",
            (f"Human motion: {rt['source']}; retargeted with dex-retargeting (vector optimizer) onto "
             f"{', '.join(rt['hands'])}; mean wrist-to-target vector error after retargeting: "
             + ", ".join(f"{h} {e:.1f} mm" for h, e in rt["mean_target_error_mm"].items())
             + f". {rt['train_rows_per_hand']} train / {rt['test_rows_per_hand']} held-out frames per hand. "
             "UniDexTok is zero-shot: it never trained on retargeted data."),
            "",
            _table(rows_b),
            "",
            "Overall:",
            "",
            _overall_table(result["overall"]["b"]),
        ]  # fmt: skip
    else:
        lines += ["", "Protocol (b) skipped: no human motion could be retargeted (no URDFs or no human rows)."]
    lines += ["", "PCA rival at UniDexTok's token count (a hand with fewer than 8 DoFs keeps all of them):", "",
              *pca_verdict(result)] if "pca_method" in result else []  # fmt: skip
    lines += ["", "Where each method wins (computed from the rows above, on the hands UniDexTok is scored on):"]
    for protocol, rs in (("a", rows_a), ("b", rows_b)):
        if rs:
            lines += ["", f"Protocol ({protocol}):", "", *wins(rs)]
    cb = result["codebook"]
    lines += [
        "",
        f"UniDexTok codebook: usage {fmt(cb['usage'])}, mean perplexity {fmt(cb['perplexity'], 1)} of {cb['codebook_size']}.",
    ]
    return "\n".join(lines)


def wins(rows: list[dict]) -> list[str]:
    """Per hand: lowest MPJAE overall, and lowest among the methods at UniDexTok's bit budget or below."""
    out = []
    for hand in sorted({r["hand"] for r in rows if r["method"] == UNIDEXTOK}):
        hr = [r for r in rows if r["hand"] == hand]
        best = min(hr, key=lambda r: r["mpjae_deg"])
        ours = next((r for r in hr if r["method"] == UNIDEXTOK), None)
        line = (
            f"- {hand}: lowest MPJAE {best['method']} ({best['mpjae_deg']:.2f} deg at {best['bits_per_state']:g} bits)"
        )
        if ours is not None:
            budget = [
                r
                for r in hr
                if r["bits_per_state"] <= ours["bits_per_state"] and r["method"] not in (best["method"], UNIDEXTOK)
            ]
            if budget:
                b2 = min(budget, key=lambda r: r["mpjae_deg"])
                line += f"; best other method at <= {ours['bits_per_state']:g} bits: {b2['method']} ({b2['mpjae_deg']:.2f} deg)"
            line += f"; UniDexTok {ours['mpjae_deg']:.2f} deg at {ours['bits_per_state']:g} bits, {ours['tokens_per_state']} tokens"
        out.append(line + ".")
    return out


def main(argv: list[str] | None = None) -> None:
    cfg = setup(parse_config(argv))
    print(markdown(run(cfg)))


if __name__ == "__main__":
    main()
