"""The figures and the package files of the shipped universal tokenizer (`lerobot_unidextok/pretrained/`).

`figures` scores a tokenizer on data it never trained on:
- each converted dataset's test episodes (`--split=test`, the converter's split), per hand, as
  `unidextok-eval --checkpoint=<model> --datasets='[<root>]'` reports them;
- every registered hand on `IN_RANGE_ROWS` states uniform inside its registered joint ranges, each on a random
  side (`training.coverage.range_states`, seed `IN_RANGE_SEED`), which depend only on the hand specs: a test
  recomputes them from the shipped files alone.

`write_package` copies a `unidextok-train` checkpoint into a package folder with `eval.json` (the figures, the
commands that measured them) and the README.md card whose evaluation table is made from that `eval.json`.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

SUMMARY = ("rows", "mpjae_deg", "mpjpe_mm", "fingertip_mm")
IN_RANGE_ROWS = 5000
IN_RANGE_SEED = 0
IN_RANGE_PREFIX = "in-range states: "
CHECKPOINT_FILES = ("config.json", "model.safetensors", "training_state.json")


def _summary(entry: dict) -> dict:
    return {k: entry[k] for k in SUMMARY}


def in_range_figures(model, hand_names: list[str] | None = None, rows: int = IN_RANGE_ROWS,
                     seed: int = IN_RANGE_SEED, stages: int | None = None) -> dict[str, dict]:  # fmt: skip
    """{f"in-range states: {hand}": summary} for every registered hand (or `hand_names`): `rows` states each,
    drawn with `seed` (the card's set by default); `stages` the quantiser stages used (None = all)."""
    from lerobot_unidextok import hands
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer
    from lerobot_unidextok.training.coverage import range_states

    out = {}
    for hand in hand_names or list(hands.names()):
        report = evaluate_tokenizer(model, range_states(hand, rows, seed), stages=stages)
        out[IN_RANGE_PREFIX + hand] = _summary(report["per_hand"][hand])
    return out


def held_out_figures(model, datasets: dict[str, str], stages: int | None = None) -> dict[str, dict]:
    """{f"{label} test episodes: {hand}": summary} for each labelled converted dataset root."""
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer
    from lerobot_unidextok.training import load_hand_states

    out = {}
    for label, root in datasets.items():
        report = evaluate_tokenizer(model, load_hand_states([root], split="test"), stages=stages)
        for hand, entry in report["per_hand"].items():
            out[f"{label} test episodes: {hand}"] = _summary(entry)
    return out


def figures(model, datasets: dict[str, str], hand_names: list[str] | None = None,
            stages: int | None = None) -> dict[str, dict]:  # fmt: skip
    """The held-out figures of `datasets` and the in-range figures of `hand_names` (None = every registered hand),
    through the first `stages` quantiser stages (None = all)."""
    return {**held_out_figures(model, datasets, stages), **in_range_figures(model, hand_names, stages=stages)}


def write_package(
    checkpoint: str | Path,
    target: str | Path,
    repo_id: str,
    results: dict[str, dict],
    about: dict,
    sections: list[str],
    data_lines: list[str],
    config_overrides: dict | None = None,
) -> Path:
    """`target` rebuilt from `checkpoint` (config, weights, training state), `eval.json` ({"results", **about})
    and README.md: the generated tokenizer card with `data_lines` as its "## Training data" (the recordings;
    the card's `datasets:` metadata stays for Hub dataset ids) and `sections` (markdown lines) before "## Use".
    `config_overrides` replace fields of the copied config.json."""
    from lerobot_unidextok.hub.card import tokenizer_card

    checkpoint, target = Path(checkpoint), Path(target)
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    for name in CHECKPOINT_FILES:
        shutil.copy2(checkpoint / name, target / name)
    if config_overrides:  # settings of use, not of training (e.g. the code search): config.json only
        from dataclasses import fields

        from lerobot_unidextok.tokenizer import UniDexTokConfig

        unknown = set(config_overrides) - {f.name for f in fields(UniDexTokConfig)}
        if unknown:
            raise ValueError(f"config_overrides {sorted(unknown)} are not UniDexTokConfig fields")
        config = json.loads((target / "config.json").read_text())
        (target / "config.json").write_text(json.dumps({**config, **config_overrides}, indent=2, sort_keys=True) + "\n")
    (target / "eval.json").write_text(json.dumps({"results": results, **about}, indent=2) + "\n")
    card = tokenizer_card(target, repo_id).replace(
        "## Training data\n\n- not recorded in this checkpoint\n", "## Training data\n\n" + "\n".join(data_lines) + "\n"
    )
    head, sep, tail = card.partition("## Use\n")
    (target / "README.md").write_text(head + "\n".join(sections) + "\n\n" + sep + tail)
    return target
