"""A tokenizer zero-shot on hands added by a YAML spec only (outside its vocabulary: the unknown-hand embedding).

For each YAML-only spec (default: LinkerHand O6 and L7, `experiments/hands/`, loaded with `hands.load_spec`,
never registered, so never in the shipped tokenizer's training data) it scores
- `rows` states uniform inside the spec's joint ranges, each on a random side (`training.coverage.range_states`
  with the spec, seed `seed`);
- the real LinkerHand vendor presets of that model (hand-tuned poses for the hardware): the SDK's
  `<MODEL>_positions.yaml` on its own side and the GUI's `preset_actions` (no side upstream) on both sides,
  duplicates (same side and values) once, mapped with `spec.to_udhm`;
with the tokenizer through its unknown-hand embedding (`evaluate_tokenizer`, which marks `zero_shot`), next to
8-bit per-joint binning over the spec's ranges on the same states. For reference, each registered relative
(default the LinkerHand L6) on its own in-range states under its own row and under the unknown-hand row.

    python experiments/universal_zeroshot.py [--checkpoint=unidextok/universal-small] [--rows=5000]
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import yaml

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, write_result
from experiments.config import PROJECT_ROOT, default_real_data_dir
from experiments.universal import IN_RANGE_ROWS, IN_RANGE_SEED
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import EncodingConfig

logger = logging.getLogger(__name__)
NAME = "universal_zeroshot"
SDK_DIR = "linkerhand-ros2-sdk"
GUI_PRESETS = "linkerhand_gui_preset_actions.json"
YAML_SIDES = {"RIGHT_HAND": "right", "LEFT_HAND": "left"}
UNKNOWN_PREFIX = "unregistered_copy_of_"  # a registered hand's states under a name outside every vocabulary


@dataclass
class ZeroShotConfig:
    checkpoint: str = UNIVERSAL_SMALL  # shipped id, local folder or Hub id of the tokenizer scored
    # Hands outside the tokenizer's vocabulary: YAMLs kept out of the registry (relative paths: to the working
    # directory, else to the project root), or registered hands added after the tokenizer was trained, by name
    specs: list[str] = field(
        default_factory=lambda: ["experiments/hands/linkerhand_o6.yaml", "experiments/hands/linkerhand_l7.yaml"]
    )
    relatives: list[str] = field(default_factory=lambda: ["linkerhand_l6"])  # registered hands for reference
    real_data_dir: str = ""  # the real data folder (empty = ../shared/data/real or UNIDEXTOK_REAL_DATA)
    rows: int = IN_RANGE_ROWS  # in-range states per hand (the card's count)
    seed: int = IN_RANGE_SEED  # of the in-range states (the card's seed)
    # how codes are picked: None = the checkpoint's own encoding; --encoding.rounds=0 = the nearest codes
    encoding: EncodingConfig | None = None
    output_root: str = "outputs/experiments"


def spec_path(path: str) -> Path:
    p = Path(path)
    if not p.is_file() and not p.is_absolute() and (PROJECT_ROOT / p).is_file():
        p = PROJECT_ROOT / p
    if not p.is_file():
        raise FileNotFoundError(f"hand spec {path!r} not found; give a YAML path (relative: to here or the project root)")
    return p


def vendor_model(spec) -> str | None:
    """The LinkerHand SDK's model name of a spec ("linkerhand_o6" -> "O6"), None for other hands."""
    return spec.name.removeprefix("linkerhand_").upper() if spec.name.startswith("linkerhand_") else None


def vendor_presets(spec, real_dir: Path):
    """(HandStates, counts) of the model's real vendor presets in UDHM, or (None, counts) when none are found."""
    from lerobot_unidextok.training import HandStates

    model, poses = vendor_model(spec), {}
    counts = {"sdk_yaml": 0, "gui": 0}
    if model is None:
        return None, counts
    sdk = real_dir / SDK_DIR / f"{model}_positions.yaml"
    if sdk.is_file():
        for key, presets in (yaml.safe_load(sdk.read_text()) or {}).items():
            for preset in presets or []:
                poses[(YAML_SIDES[key], tuple(preset["POSITION"]))] = None
                counts["sdk_yaml"] += 1
    gui = real_dir / SDK_DIR / GUI_PRESETS
    if gui.is_file():
        for raw in json.loads(gui.read_text()).get(model, {}).get("preset_actions", {}).values():
            for side in spec.sides:
                poses[(side, tuple(raw))] = None
                counts["gui"] += 1
    counts["unique"] = len(poses)
    if not poses:
        return None, counts
    states = np.stack([np.asarray(spec.to_udhm(np.asarray(raw, np.float64), side=side)) for side, raw in poses])
    masks = np.broadcast_to(spec.mask("semantic"), states.shape)
    return HandStates(states, np.full(len(states), spec.name), masks), counts


def score(model, data, spec, states: str, row: str) -> dict:
    """UniDexTok (its own row, or the unknown-hand one for a name outside its vocabulary) and 8-bit binning
    over `spec`'s ranges on the same states."""
    from experiments.unseen_data import binning_reconstruction
    from lerobot_unidextok.evaluation.metrics import reconstruction_metrics
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer

    (name,) = data.hand_names()
    tok = evaluate_tokenizer(model, data)["per_hand"][name]
    binned = binning_reconstruction(data, specs={name: spec})
    binning = reconstruction_metrics(binned, data.states_rad, data.hands, data.masks)["per_hand"][name]
    return {"hand": spec.name, "states": states, "tokenizer_row": row, "zero_shot": tok["zero_shot"],
            "rows": tok["rows"], "active_dofs": tok["active_dofs"], "mpjae_deg": tok["mpjae_deg"],
            "mpjpe_mm": tok["mpjpe_mm"], "fingertip_mm": tok["fingertip_mm"],
            "binning_mpjae_deg": binning["mpjae_deg"], "binning_mpjpe_mm": binning["mpjpe_mm"]}  # fmt: skip


def checkpoint_info(name: str, model) -> dict:
    from lerobot_unidextok import pretrained

    weights = Path(pretrained.resolve(name)) / "model.safetensors"
    sha = hashlib.sha256(weights.read_bytes()).hexdigest()[:16] if weights.is_file() else None
    return {"checkpoint": name, "model_safetensors_sha256_16": sha, "hand_names": list(model.config.hand_names)}


def run(cfg: ZeroShotConfig) -> dict:
    from lerobot_unidextok import hands
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import HandStates
    from lerobot_unidextok.training.coverage import range_states

    t0 = time.time()
    specs = [hands.load_spec(spec_path(p)) if p.endswith(".yaml") else hands.get(p) for p in cfg.specs]
    model = UniDexTok.from_pretrained(cfg.checkpoint)
    known = [s.name for s in specs if s.name in model.config.hand_names]
    if known:
        raise ValueError(f"specs {known} are in the tokenizer's vocabulary; zero-shot needs hands outside it")
    model.with_encoding(cfg.encoding)
    real_dir = Path(cfg.real_data_dir or default_real_data_dir())
    rows, presets = [], {}
    in_range = f"in-range ({cfg.rows}, seed {cfg.seed})"
    for spec in specs:
        rows.append(score(model, range_states(spec, cfg.rows, cfg.seed), spec, in_range, "unknown"))
        data, presets[spec.name] = vendor_presets(spec, real_dir)
        if data is None:
            logger.warning("no vendor presets of %s under %s: its preset row is left out", spec.name, real_dir)
        else:
            rows.append(score(model, data, spec, "vendor presets", "unknown"))
    for name in cfg.relatives:
        spec, own = hands.get(name), range_states(name, cfg.rows, cfg.seed)
        rows.append(score(model, own, spec, in_range, "own"))
        copy = HandStates(own.states_rad, np.full(len(own), UNKNOWN_PREFIX + name), own.masks)
        rows.append(score(model, copy, spec, in_range, "unknown"))
    from lerobot_unidextok.evaluation.report import encoding

    return {"experiment": NAME, "config": asdict(cfg),
            "model": {**checkpoint_info(cfg.checkpoint, model), "encoding": encoding(model.config)},
            "specs": {s.name: p for s, p in zip(specs, cfg.specs, strict=True)}, "presets": presets, "rows": rows,
            "git_commit": git_commit(), "wall_seconds": round(time.time() - t0, 1),
            "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip


def markdown(result: dict) -> str:
    head = ["| hand | states | rows | tokenizer row | MPJAE (deg) | MPJPE (mm) | fingertip (mm) "
            "| 8-bit binning MPJAE (deg) |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    lines = [f"| {r['hand']} | {r['states']} | {r['rows']} | {r['tokenizer_row']}"
             f"{' (zero-shot)' if r['zero_shot'] else ''} | {r['mpjae_deg']:.3f} | {r['mpjpe_mm']:.3f} | "
             f"{r['fingertip_mm']:.3f} | {r['binning_mpjae_deg']:.3f} |" for r in result["rows"]]  # fmt: skip
    return "\n".join(head + lines)


def run_and_write(cfg: ZeroShotConfig) -> dict:
    result = run(cfg)
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    write_result(folder, NAME, result,
                 f"# {NAME}\n\n{cfg.checkpoint} (encoding: {result['model']['encoding']})\n\n{markdown(result)}")
    return result


def main(argv: list[str] | None = None) -> None:
    runtime.cli(ZeroShotConfig, run_and_write, markdown, argv)


if __name__ == "__main__":
    main()
