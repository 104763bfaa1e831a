"""A residual stage at equal training (#48): a preset with and without one residual stage, trained by the same
recipe (`unidextok-train`'s loop, `configs/train/small.yaml` settings) for the same steps on the same in-range
states of a few hands, scored through their nearest codes (and the residual model's first stage alone) on the
card's in-range states (seed 0), next to the shipped tokenizer's nearest codes and its own encoding (the code
search) on the same rows. The shipped model trained ~20x longer on more data: its rows are a reference, the
A/B is the first two.

    python experiments/residual_ab.py                                   # inspire_rh56_unitree + human, 1500 steps
    python experiments/residual_ab.py --steps=4000 --hands='[inspire_rh56_unitree]'

Writes <output_root>/residual_ab/residual_ab.{json,md}. CPU s = training time.process_time (one torch thread).
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

if __package__ in (None, ""):  # `python experiments/residual_ab.py`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL

NAME = "residual_ab"
CARD_SEED = 0  # the card's in-range states (experiments/universal.py IN_RANGE_SEED)


@dataclass
class ResidualABConfig:
    hands: list[str] = field(default_factory=lambda: ["inspire_rh56_unitree", "human"])
    preset: str = "small"  # the plain arm; the residual arm is the same with residual_stages=1
    steps: int = 1500
    train_rows: int = 20000  # in-range states per hand trained on (seed train_seed), coverage sampling as the recipe
    train_seed: int = 11
    rows: int = 1000  # in-range states per hand scored (the card's seed 0; the card scores 5000)
    seed: int = 0
    checkpoint: str = UNIVERSAL_SMALL  # the reference rows
    tiny: bool = False  # tests: tiny preset, a few steps
    output_root: str = "outputs/experiments"


def in_range(hands: list[str], rows: int, seed: int):
    from lerobot_unidextok.training import HandStates
    from lerobot_unidextok.training.coverage import range_states

    return HandStates.concat([range_states(hand, rows, seed) for hand in hands])


def mpjae_per_hand(model, data, encoding=None, stages: int | None = None) -> dict[str, float]:
    """MPJAE (deg, active DoFs) per hand of decode(encode(x)) with `encoding` (None: the model's own)."""
    import torch

    from lerobot_unidextok.evaluation import mpjae_deg

    out = {}
    for hand in data.hand_names():
        part = data.only(hand)
        x, mask = torch.tensor(part.states_rad), torch.tensor(part.masks)
        codes = model.encode(x, hand, mask=mask, encoding=encoding, stages=stages)
        out[hand] = mpjae_deg(model.decode(codes, hand).numpy(), part.states_rad, part.masks)
    return out


def train_arm(cfg: ResidualABConfig, residual_stages: int, folder: Path) -> tuple[object, float]:
    import torch

    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import TrainConfig, train_tokenizer
    from lerobot_unidextok.training.loop import build_model

    kw = {"preset": "tiny", "steps": 12, "batch_size": 32, "warmup_steps": 2, "eval_every": 6} if cfg.tiny else {
        "preset": cfg.preset, "steps": cfg.steps, "eval_every": max(1, cfg.steps // 4)}  # fmt: skip
    tcfg = TrainConfig(output_dir=str(folder / f"residual_{residual_stages}"), progress=False, save_last_every=10**9,
                       seed=cfg.seed, overwrite=True, **kw)  # fmt: skip
    fit = in_range(cfg.hands, cfg.train_rows, cfg.train_seed)
    select = in_range(cfg.hands, max(1, cfg.rows // 4), cfg.train_seed + 1)
    torch.manual_seed(cfg.seed)
    model = build_model(tcfg, fit, residual_stages=residual_stages)
    cpu0 = time.process_time()
    res = train_tokenizer(tcfg, fit, select, model=model)
    return UniDexTok.from_pretrained(res.best_dir), time.process_time() - cpu0


def run(cfg: ResidualABConfig) -> dict:
    import torch

    from lerobot_unidextok.tokenizer import NEAREST_CODES, UniDexTok

    torch.set_num_threads(1)
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    scored = in_range(cfg.hands, cfg.rows, CARD_SEED)
    plain, plain_cpu = train_arm(cfg, 0, folder / "models")
    residual, residual_cpu = train_arm(cfg, 1, folder / "models")
    shipped = UniDexTok.from_pretrained(cfg.checkpoint)
    rows = [
        {"model": f"{plain.config.num_tokens}-token preset, no residual stage", "encoding": "nearest codes",
         "symbols": plain.config.symbols_per_hand(), "cpu_s": plain_cpu,
         "mpjae_deg": mpjae_per_hand(plain, scored, NEAREST_CODES)},
        {"model": "same + one residual stage", "encoding": "nearest codes, both stages",
         "symbols": residual.config.symbols_per_hand(), "cpu_s": residual_cpu,
         "mpjae_deg": mpjae_per_hand(residual, scored, NEAREST_CODES)},
        {"model": "same + one residual stage", "encoding": "nearest codes, first stage alone",
         "symbols": residual.config.symbols_per_hand(1), "cpu_s": residual_cpu,
         "mpjae_deg": mpjae_per_hand(residual, scored, NEAREST_CODES, stages=1)},
        {"model": f"shipped {cfg.checkpoint} (reference)", "encoding": "nearest codes",
         "symbols": shipped.config.symbols_per_hand(), "cpu_s": None,
         "mpjae_deg": mpjae_per_hand(shipped, scored, NEAREST_CODES)},
        {"model": f"shipped {cfg.checkpoint} (reference)", "encoding": shipped.config.encoding.describe(),
         "symbols": shipped.config.symbols_per_hand(), "cpu_s": None,
         "mpjae_deg": mpjae_per_hand(shipped, scored)},
    ]  # fmt: skip
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "rows": rows, "git_commit": git_commit(),
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def markdown(result: dict) -> str:
    cfg = result["config"]
    hands = cfg["hands"]
    rows = [[r["model"], r["encoding"], r["symbols"], *[f"{r['mpjae_deg'][h]:.3f}" for h in hands],
             "-" if r["cpu_s"] is None else f"{r['cpu_s']:.0f}"] for r in result["rows"]]  # fmt: skip
    return "\n".join([
        f"# {NAME}", "",
        f"Preset `{cfg['preset']}`, {cfg['steps']} steps, trained on {cfg['train_rows']} in-range states per hand "
        f"(seed {cfg['train_seed']}); MPJAE (deg) on {cfg['rows']} in-range states per hand of the card's seed "
        f"{CARD_SEED}; symbols = codes per hand state (32-entry vocabularies); CPU s = training, one thread.", "",
        md_table(["model", "encoding", "symbols", *[f"MPJAE {h} (deg)" for h in hands], "CPU s"], rows),
    ])  # fmt: skip


def parse(argv: list[str] | None = None) -> ResidualABConfig:
    return runtime.parse(ResidualABConfig, argv)


if __name__ == "__main__":
    runtime.cli(ResidualABConfig, run, markdown, None)
