"""Main table: per hand, UniDexTok vs UniHM-style vs uniform binning (+ FSQ / RVQ at UniDexTok's budget),
with the rate-distortion table and plot, 3D renderings, per-joint error bars and codebook usage."""

import logging
import time

import numpy as np

from lerobot_unidextok.experiments import baselines as B
from lerobot_unidextok.experiments.common import (
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
from lerobot_unidextok.experiments.config import ExperimentConfig, parse_config
from lerobot_unidextok.experiments.runtime import setup

logger = logging.getLogger(__name__)
NAME = "main_table"
BINNING, UNIHM, FSQ, RVQ = "uniform binning", "UniHM-style", "FSQ", "RVQ"


def run(cfg: ExperimentConfig) -> dict:
    t0 = time.perf_counter()
    folder = out_dir(cfg, NAME)
    data = load_data(cfg)
    test = cap_rows(data.test, cfg.max_eval_frames, cfg.seed)
    fit, select = selection_split(data.train, cfg.seed)

    model, train_info = trained_unidextok(cfg, "all_hands", fit, select)
    pred_udt, codes = reconstruct_unidextok(model, test)
    preds = {UNIDEXTOK: pred_udt}
    rates = {
        UNIDEXTOK: {
            h: (
                model.config.num_tokens,
                model.config.num_tokens * model.config.num_groups * np.log2(model.config.codebook_size),
            )
            for h in test.hand_names()
        }
    }
    fit_seconds = {UNIDEXTOK: train_info["seconds"]}

    tokenizers = {
        BINNING: lambda: B.binning(data.train),
        UNIHM: lambda: B.unihm(cfg, fit),
    }
    if cfg.with_qae:
        tokenizers[FSQ] = lambda: B.quantized_ae(cfg, fit, "fsq")
        tokenizers[RVQ] = lambda: B.quantized_ae(cfg, fit, "rvq")
    for method, build in tokenizers.items():
        t = time.perf_counter()
        tok = build()
        if tok is None:
            continue
        fit_seconds[method] = round(time.perf_counter() - t, 1)
        preds[method] = reconstruct_baseline(tok, test)
        rates[method] = {h: (tok.rate(h).tokens_per_state, tok.rate(h).bits_per_state) for h in test.hand_names()}
        logger.info("%s fitted in %.1f s", method, fit_seconds[method])

    # --- scores: one evaluation code for all --------------------------------------------------------
    reports = {m: score(p, test) for m, p in preds.items()}
    rows = []
    for hand in test.hand_names():
        for m, rep in reports.items():
            tokens, bits = rates[m][hand]
            rows.append({"method": m, "hand": hand, "tokens_per_state": int(tokens), "bits_per_state": float(bits),
                         **summary_row(rep["per_hand"][hand])})  # fmt: skip
    overall = {
        m: {
            **summary_row(rep["overall"]),
            "per_joint_deg": rep["overall"]["per_joint_deg"],
        }
        for m, rep in reports.items()
    }

    # --- figures --------------------------------------------------------------------------------------
    from lerobot_unidextok import viz
    from lerobot_unidextok.evaluation import codebook_usage

    figures = {"rate_distortion_mpjae": str(viz.plot_rate_distortion(rows, folder / "rate_distortion_mpjae.png")),
               "rate_distortion_mpjpe": str(viz.plot_rate_distortion(rows, folder / "rate_distortion_mpjpe.png", error="mpjpe_mm", error_label="MPJPE (mm)")),
               "per_joint_errors": str(viz.plot_per_joint_errors({m: abs_errors_deg(p, test) for m, p in preds.items()}, folder / "per_joint_errors.png",
                                                                  title="per-joint angle error, held-out states, all hands")),
               "codebook_usage": str(viz.plot_codebook_usage(codes, model.config.codebook_size, folder / "codebook_usage.png",
                                                             title="UniDexTok codebook usage (held-out states)"))}  # fmt: skip
    rng = np.random.default_rng(cfg.seed)
    baseline_for_render = UNIHM if UNIHM in preds else BINNING
    for hand in test.hand_names():
        rows_h = np.flatnonzero(test.hands == hand)
        pick = np.sort(rng.choice(rows_h, size=min(cfg.render_samples, len(rows_h)), replace=False))
        figures[f"render_{hand}"] = str(viz.plot_hand_reconstructions(
            test.states_rad[pick], {UNIDEXTOK: preds[UNIDEXTOK][pick], baseline_for_render: preds[baseline_for_render][pick]},
            hand, folder / f"render_{hand}.png", title=f"{hand}: ground truth (light) vs {UNIDEXTOK} (green) vs {baseline_for_render} (red)"))  # fmt: skip

    result = {
        "experiment": NAME,
        "provenance": provenance(cfg, data, time.perf_counter() - t0),
        "methods": list(preds),
        "rows": rows,
        "overall": overall,
        "fit_seconds": fit_seconds,
        "unidextok_training": train_info,
        "codebook": codebook_usage(codes, model.config.codebook_size),
        "figures": figures,
    }
    write_result(folder, NAME, result, markdown(result))
    return result


def markdown(result: dict) -> str:
    rows = result["rows"]
    lines = [
        f"# {NAME}",
        "",
        "Held-out split, per hand; same metric code (`evaluation.metrics`) for every method.",
        "",
    ]
    lines.append(md_table(["hand", "method", "tokens/state", "bits/state", "MPJAE (deg)", "MPJPE (mm)", "fingertip (mm)"],
                          [[r["hand"], r["method"], r["tokens_per_state"], f"{r['bits_per_state']:g}", r["mpjae_deg"], r["mpjpe_mm"], r["fingertip_mm"]] for r in rows]))  # fmt: skip
    lines += ["", "Overall (all held-out rows):", ""]
    lines.append(md_table(["method", "MPJAE (deg)", "MPJPE (mm)", "fingertip (mm)", "fit seconds"],
                          [[m, o["mpjae_deg"], o["mpjpe_mm"], o["fingertip_mm"], fmt(result["fit_seconds"].get(m), 1)] for m, o in result["overall"].items()]))  # fmt: skip
    lines += [
        "",
        "Where each method wins (computed from the rows above):",
        "",
        *wins(rows),
    ]
    lines += [
        "",
        f"UniDexTok codebook: usage {fmt(result['codebook']['usage'])}, mean perplexity {fmt(result['codebook']['perplexity'], 1)} of {result['codebook']['codebook_size']}.",
    ]
    return "\n".join(lines)


def wins(rows: list[dict]) -> list[str]:
    """Per hand: lowest MPJAE overall, and lowest among the methods at UniDexTok's bit budget or below."""
    out = []
    for hand in sorted({r["hand"] for r in rows}):
        hr = [r for r in rows if r["hand"] == hand]
        best = min(hr, key=lambda r: r["mpjae_deg"])
        ours = next((r for r in hr if r["method"] == UNIDEXTOK), None)
        line = (
            f"- {hand}: lowest MPJAE {best['method']} ({best['mpjae_deg']:.2f} deg at {best['bits_per_state']:g} bits)"
        )
        if ours is not None:
            budget = [r for r in hr if r["bits_per_state"] <= ours["bits_per_state"] and r["method"] != best["method"]]
            learned = [r for r in budget if r["method"] != BINNING]
            if learned:
                b2 = min(learned, key=lambda r: r["mpjae_deg"])
                line += f"; best learned tokenizer at <= {ours['bits_per_state']:g} bits: {b2['method']} ({b2['mpjae_deg']:.2f} deg)"
            line += f"; UniDexTok {ours['mpjae_deg']:.2f} deg at {ours['bits_per_state']:g} bits, {ours['tokens_per_state']} tokens"
        out.append(line + ".")
    return out


def main(argv: list[str] | None = None) -> None:
    cfg = setup(parse_config(argv, __doc__))
    result = run(cfg)
    print(markdown(result))


if __name__ == "__main__":
    main()
