"""Evaluate a tokenizer on held-out rows and write the report as JSON + a Markdown table."""

import json
import math
from pathlib import Path

import numpy as np

from lerobot_unidextok.data.destination import claim_files, is_json_with
from lerobot_unidextok.evaluation.metrics import reconstruction_metrics
from lerobot_unidextok.evaluation.reconstruct import codebook_usage, reconstruct
from lerobot_unidextok.utils.files import jsonable


def evaluate_tokenizer(model, data, batch_size: int = 4096, stages: int | None = None) -> dict:
    """Per-hand and overall metrics of decode(encode(x)); hands unknown to the model are scored
    zero-shot through its unknown-hand embedding and flagged `zero_shot`. `stages`: the quantiser stages used
    (None = all of the model's; 1 = a residual model's first stage alone)."""
    rec = reconstruct(model, data.states_rad, data.hands, batch_size=batch_size, allow_unknown=True,
                      masks=data.masks, stages=stages)
    report = reconstruction_metrics(rec.states_rad, data.states_rad, data.hands, data.masks)
    size = model.config.codebook_size
    report["overall"]["codebook"] = codebook_usage(rec.codes, size)
    for hand, entry in report["per_hand"].items():
        entry["zero_shot"] = not model.knows_hand(hand)
        entry["codebook"] = codebook_usage(rec.codes[data.hands == hand], size)
    report["model"] = {"hand_names": list(model.config.hand_names), "num_tokens": model.config.num_tokens,
                       "num_groups": model.config.num_groups, "codebook_size": size,
                       "encoding": encoding(model.config)}  # fmt: skip
    return report


def encoding(config) -> str:
    """How codes were picked: the nearest codes (the paper's encoding) or the decoder-aware code search."""
    return config.encoding.describe()


HAND_ROWS = "hand-rows: one row per hand per frame (a two-hand frame gives two rows)"


def episode_ranges(episodes) -> str:
    """Sorted episode indices as compact ranges: [0, 1, 2, 5, 7, 8] -> "0-2, 5, 7-8"."""
    eps = sorted(int(e) for e in episodes)
    parts, i = [], 0
    while i < len(eps):
        j = i
        while j + 1 < len(eps) and eps[j + 1] == eps[j] + 1:
            j += 1
        parts.append(str(eps[i]) if i == j else f"{eps[i]}-{eps[j]}")
        i = j + 1
    return ", ".join(parts)


def describe_scored(data, datasets: list[str], split: str, checkpoint: str | None = None) -> dict:
    """What a report scored: the checkpoint, the split, and per dataset (position `i` in `datasets` is
    `data.dataset_index == i`) its episodes and hand-rows (`HAND_ROWS`), overall and per hand."""
    entries = []
    for i, name in enumerate(datasets):
        rows = np.ones(len(data), bool) if data.dataset_index is None else data.dataset_index == i
        episodes = [] if data.episode_index is None else np.unique(data.episode_index[rows]).tolist()
        hands, counts = np.unique(data.hands[rows], return_counts=True)
        entries.append({"dataset": str(name), "episodes": episodes, "hand_rows": int(rows.sum()),
                        "hand_rows_per_hand": dict(zip(hands.tolist(), counts.tolist(), strict=True))})  # fmt: skip
    return {"checkpoint": None if checkpoint is None else str(checkpoint), "split": split, "rows": HAND_ROWS,
            "datasets": entries}  # fmt: skip


def scored_markdown(scored: dict) -> str:
    """The `describe_scored` record as a sentence and a per-dataset table of episodes and hand-rows."""
    where = f"checkpoint `{scored['checkpoint']}`" if scored.get("checkpoint") else "the model"
    lines = [f"Scored: {where} on the {scored['split']} episodes below. Rows are {scored['rows']}.", "",
             "| dataset | episodes | hand-rows |", "|---|---|---|"]  # fmt: skip
    for d in scored["datasets"]:
        lines.append(f"| {d['dataset']} | {episode_ranges(d['episodes']) or '-'} ({len(d['episodes'])}) | "
                     f"{d['hand_rows']} |")  # fmt: skip
    return "\n".join(lines)


def _fmt(x: float, digits: int = 3) -> str:
    return "nan" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def markdown_table(report: dict) -> str:
    """What was scored (when the report says), the per-hand summary table, then the per-joint MAE (deg) table."""
    lines = [scored_markdown(report["scored"]), ""] if report.get("scored") else []
    if report.get("model", {}).get("encoding"):
        lines += [f"Encoding: {report['model']['encoding']}.", ""]
    lines += [
        "| hand | rows | active DoFs | MPJAE (deg) | MPJPE (mm) | fingertip (mm) | code usage | zero-shot |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rows = [*report["per_hand"].items(), ("**overall**", report["overall"])]
    for hand, e in rows:
        usage = e.get("codebook", {}).get("usage", float("nan"))
        zs = "yes" if e.get("zero_shot") else ("" if hand == "**overall**" else "no")
        lines.append(
            f"| {hand} | {e['rows']} | {e['active_dofs']} | {_fmt(e['mpjae_deg'])} | {_fmt(e['mpjpe_mm'])} | "
            f"{_fmt(e['fingertip_mm'])} | {_fmt(usage, 2)} | {zs} |"
        )
    hands = list(report["per_hand"])
    lines += ["", "Per-joint MAE (deg), active rows only:", "", "| joint | " + " | ".join(hands) + " |",
              "|---|" + "---|" * len(hands)]  # fmt: skip
    joints = list(report["overall"]["per_joint_deg"])
    for j in joints:
        cells = [
            _fmt(report["per_hand"][h]["per_joint_deg"][j], 2) if j in report["per_hand"][h]["per_joint_deg"] else "-"
            for h in hands
        ]
        lines.append(f"| {j} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report_paths(stem: str | Path) -> tuple[Path, Path]:
    """`<stem>.json` and `<stem>.md`, the suffixes added to the whole name (a stem `run.v2` gives `run.v2.json`,
    where `with_suffix` gave `run.json`)."""
    stem = Path(stem)
    return stem.with_name(f"{stem.name}.json"), stem.with_name(f"{stem.name}.md")


def claim_report(stem: str | Path, inputs: list[Path] | tuple[Path, ...] = ()) -> Path:
    """Check that `<stem>.json` and `<stem>.md` may be written (`data.destination.claim_files`): not an input,
    not inside a dataset or a checkpoint, and an existing file only when it is an earlier report. Returns the
    stem resolved."""
    stem = Path(stem).expanduser().resolve()
    is_report = is_json_with("per_hand", "overall")
    json_path, md_path = report_paths(stem)
    claim_files([json_path, md_path], inputs=inputs, flag="--output",
                is_ours=lambda p: is_report(json_path))  # fmt: skip
    return stem


def write_report(report: dict, stem: str | Path) -> str:
    """Write `<stem>.json` and `<stem>.md` (where `claim_report` allows); returns the Markdown text."""
    json_path, md_path = report_paths(claim_report(stem))
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(jsonable(report), indent=2))
    md = markdown_table(report)
    md_path.write_text(md + "\n")
    return md
