"""Model card (README.md) for a UniDexTok tokenizer checkpoint folder."""

from __future__ import annotations

import json
import logging
from pathlib import Path

logger = logging.getLogger(__name__)

# Fields that identify a preset (VQ settings are the same in every preset).
_SIZE_FIELDS = (
    "num_tokens",
    "hidden_dim",
    "encoder_depth",
    "decoder_depth",
    "num_heads",
    "mlp_ratio",
)
EVAL_GLOBS = ("eval*.json", "metrics*.json", "evaluation*.json")


def infer_preset(config: dict) -> str:
    """Name of the preset whose sizes match `config`, or "custom"."""
    from lerobot_unidextok.tokenizer.configuration_unidextok import PRESETS

    for name, preset in PRESETS.items():
        if all(config.get(f) == getattr(preset, f) for f in _SIZE_FIELDS):
            return name
    return "custom"


def find_eval_json(folder: Path) -> Path | None:
    """First evaluation JSON in the checkpoint folder, if any."""
    for pattern in EVAL_GLOBS:
        hits = sorted(folder.glob(pattern))
        if hits:
            return hits[0]
    return None


def eval_table(metrics: dict) -> str:
    """Markdown table from `{row: {metric: value}}` or a flat `{metric: value}` dict."""
    rows = metrics.get("results", metrics) if isinstance(metrics, dict) else {}
    if rows and all(not isinstance(v, dict) for v in rows.values()):
        rows = {"all": rows}
    rows = {k: v for k, v in rows.items() if isinstance(v, dict)}
    if not rows:
        return ""
    cols = list(dict.fromkeys(c for v in rows.values() for c in v if not isinstance(v[c], (dict, list))))

    def fmt(x) -> str:
        return f"{x:.4g}" if isinstance(x, float) else str(x)

    lines = ["| | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    lines += [f"| {name} | " + " | ".join(fmt(v.get(c, "")) for c in cols) + " |" for name, v in rows.items()]
    return "\n".join(lines)


def training_section(state: dict) -> list[str]:
    """Card lines from a checkpoint's `training_state.json` (written by `unidextok-train`): the hands trained
    and their coverage mixture, the data, the schedule and how the checkpoint was chosen."""
    mixture = state.get("mixture") or {}
    hands = mixture.get("hands") or {}
    lines = ["## Training", ""]
    if state.get("datasets"):
        lines += ["Data (converted UDHM datasets):", "", *[f"- `{d}`" for d in state["datasets"]], ""]
    if state.get("excluded_hands"):
        lines += [
            f"Hands left out of training (zero-shot): {', '.join(f'`{h}`' for h in state['excluded_hands'])}.",
            "",
        ]
    if hands:
        lines += [
            "Hands trained, their share of a batch and the coverage mixture of their rows (recorded rows vs "
            f"states synthesised inside the hand's joint ranges; noise bound {mixture.get('noise_deg')} deg):",
            "",
            "| hand | kind | recorded rows | batch share | ranges from | sources |",
            "|---|---|---|---|---|---|",
        ]
        for name, h in hands.items():
            sources = ", ".join(f"{k} {v:.2f}" for k, v in h.get("sources", {}).items())
            lines.append(f"| `{name}` | {h.get('kind')} | {h.get('recorded_rows')} | {h.get('share', 0):.2f} | "
                         f"{h.get('ranges_from')} | {sources} |")  # fmt: skip
        lines.append("")
    extra = {k: state[k] for k in ("preset", "steps", "batch_size", "lr", "unknown_hand_prob", "adapt", "init_from",
                                   "step") if state.get(k) is not None}  # fmt: skip
    if extra:
        lines += [", ".join(f"{k}: {v}" for k, v in extra.items()), ""]
    if state.get("selection") is not None:
        lines += [f"Checkpoint selection: {state['selection']}", ""]
    return lines


def tokenizer_card(folder: str | Path, repo_id: str, training_data: list[str] | None = None) -> str:
    """README.md text: hands supported, training data and mixture, preset and the evaluation table."""
    folder = Path(folder)
    config_path = folder / "config.json"
    if not config_path.is_file():
        raise FileNotFoundError(
            f"{folder} has no config.json: not a UniDexTok checkpoint (save one with UniDexTok.save_pretrained)"
        )
    config = json.loads(config_path.read_text())
    hands = config.get("hand_names") or []
    training_data = list(training_data or config.get("training_data") or [])
    preset = infer_preset(config)
    eval_path = find_eval_json(folder)
    table = eval_table(json.loads(eval_path.read_text())) if eval_path else ""
    state_path = folder / "training_state.json"
    state = json.loads(state_path.read_text()) if state_path.is_file() else {}
    trained = list((state.get("mixture") or {}).get("hands") or [])

    front = [
        "---",
        "library_name: lerobot-unidextok",
        "license: apache-2.0",
        "tags:",
        "- lerobot",
        "- unidextok",
        "- dexterous-hands",
        "- tokenizer",
    ]
    front += ["datasets:"] + [f"- {d}" for d in training_data] if training_data else []
    front += ["---", ""]
    body = [
        f"# {repo_id}",
        "",
        f"UniDexTok hand-state tokenizer: 22-DoF UDHM joint angles (radians; input normalisation "
        f"`{config.get('input_norm', 'pi')}`) of any supported",
        (
            f"hand -> {config.get('num_tokens')} tokens x {config.get('num_groups')} groups of "
            f"{config.get('codebook_size')}-entry cosine codebooks, decoded back to angles."
        ),
        "",
        "## Hands supported",
        "",
        *(
            [f"- `{h}`" + ("" if not trained or h in trained else " (in the vocabulary, not trained)") for h in hands]
            or ["- (none listed)"]
        ),  # fmt: skip
        '- any other hand through the shared "unknown hand" embedding (zero-shot)',
        "",
        *(
            training_section(state)
            if state
            else [
                "## Training data",
                "",
                *([f"- `{d}`" for d in training_data] or ["- not recorded in this checkpoint"]),
                "",
            ]
        ),
        "## Model",
        "",
        f"- preset: `{preset}`",
        *[f"- {f}: {config.get(f)}" for f in (*_SIZE_FIELDS, "codebook_dim", "num_groups", "codebook_size")],
        "",
        "## Evaluation",
        "",
        (f"From `{eval_path.name}`:\n\n{table}" if table else "No evaluation file in this checkpoint."),
        "",
        "## Use",
        "",
        "```python",
        "from lerobot_unidextok.tokenizer import UniDexTok",
        f'tok = UniDexTok.from_pretrained("{repo_id}")   # offline after `unidextok-pull {repo_id}`',
        "```",
        "",
    ]
    return "\n".join(front + body)
