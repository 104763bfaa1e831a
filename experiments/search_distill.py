"""Can the encoder learn the code search? Fine-tune a checkpoint's encoder so that its nearest codes are accurate,
with the decoder, codebooks and hand embeddings frozen (same tokens, same decoder), and score its nearest codes.

    python experiments/search_distill.py                      # the shipped unidextok/universal-small
    python experiments/search_distill.py --variants='[imitate]' --steps=4000

Variants (`VARIANTS`):
- `imitate`: cross-entropy of the encoder's cosine similarities (temperature `tau`) towards the codes the
  checkpoint's search picks, on a pool of `pool_rows` training states (the universal recipe's sampler: its
  recorded training rows minus the selection episodes, and coverage samples), searched once;
- `through_decoder`: the decoder's reconstruction loss of the encoder's nearest codes, its gradient passed to the
  similarities through a softmax (temperature `tau`; straight-through: the forward pass uses the nearest codes),
  on fresh batches of the same sampler.
Scored like the recipe (`universal_screen.py`): MPJAE (deg) through the nearest codes on the run's selection
episodes and on `range_rows` in-range states per hand of seed 7, and the share of code positions where the
nearest codes agree with the searched ones on those in-range states. The test episodes are not loaded.
Writes <output_root>/search_distill/search_distill.{json,md}.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES

NAME = "search_distill"
SCREEN_SEED = 7  # as universal_screen.py: not the card's seed 0
VARIANTS = {
    "imitate": "cross-entropy towards the searched codes (a pool searched once)",
    "through_decoder": "the decoder's loss of the nearest codes, softmax straight-through gradient",
}
ENCODER = ("input_proj", "enc_pos", "encoder.", "enc_norm", "quantizer.project_in")  # what is fine-tuned


@dataclass
class SearchDistillConfig:
    checkpoint: str = UNIVERSAL_SMALL  # a tokenizer whose config.json searches (encoding.rounds > 0)
    recipe: str = "train/universal"  # the unidextok-train config whose data and sampler the pool comes from
    variants: list[str] = field(default_factory=lambda: list(VARIANTS))
    steps: int = 2000  # optimiser steps per variant
    batch_size: int = 256
    lr: float = 1e-3  # peak (100 warm-up steps, cosine to 0)
    tau: float = 0.01  # softmax temperature over cosine similarities
    pool_rows: int = 25600  # `imitate`: training states searched once
    range_rows: int = 500  # in-range states per hand scored (seed 7)
    seed: int = 0
    output_root: str = "outputs/experiments"

    def __post_init__(self) -> None:
        unknown = sorted(set(self.variants) - set(VARIANTS))
        if unknown:
            raise ValueError(f"unknown variants {unknown}; choose from {sorted(VARIANTS)}")
        if self.steps < 1 or self.tau <= 0 or self.pool_rows < self.batch_size:
            raise ValueError("need steps >= 1, tau > 0 and pool_rows >= batch_size")


def sampler_and_selection(cfg: SearchDistillConfig, model):
    """The recipe's batch sampler over its training rows minus the selection episodes (the hands `model` knows),
    and those selection rows."""
    import draccus

    from experiments.universal_screen import selection_split
    from lerobot_unidextok.configs import resolve_config_path
    from lerobot_unidextok.training import TrainConfig
    from lerobot_unidextok.training.coverage import MixtureSampler, resolve_range_hands

    tcfg = draccus.parse(TrainConfig, config_path=resolve_config_path(cfg.recipe, "recipe"), args=[])
    fit, select = selection_split(tcfg)
    range_hands = [h for h in resolve_range_hands(tcfg.range_hands, tcfg.exclude_hands) if model.knows_hand(h)]
    sampler = MixtureSampler(fit, tcfg.hand_weights, tcfg.default_hand_weight, tcfg.coverage,
                             seed=cfg.seed * 1000 + 17, range_hands=range_hands)  # fmt: skip
    return sampler, select


def scored_sets(model, select, range_rows: int) -> dict:
    """{label: rows}: the selection episodes per hand, then `range_rows` in-range states (seed 7) per trained hand."""
    from lerobot_unidextok.training.coverage import range_states

    sets = {f"select: {h}": select.only(h) for h in select.hand_names()}
    return sets | {f"in-range: {h}": range_states(h, range_rows, SCREEN_SEED) for h in model.config.trained_hands}


def score(model, sets: dict, searched: dict) -> dict:
    """Nearest-code MPJAE (deg) on each set, and the share of code positions where the nearest codes are
    `searched` (the checkpoint's searched codes of each in-range set)."""
    import torch

    from lerobot_unidextok.evaluation import mpjae_deg

    out, agree = {}, []
    for label, data in sets.items():
        x, hand = torch.tensor(data.states_rad), data.hand_names()[0]
        nearest = model.encode(x, hand, encoding=NEAREST_CODES)
        out[label] = mpjae_deg(model.decode(nearest, hand).numpy(), data.states_rad, data.masks)
        if label in searched:
            agree.append(float((nearest == searched[label]).float().mean()))
    in_range = [v for k, v in out.items() if k.startswith("in-range")]
    return {"mpjae_deg": out, "in_range_mean": float(np.mean(in_range)), "in_range_max": float(max(in_range)),
            "agree_with_search": float(np.mean(agree))}  # fmt: skip


def fine_tune(cfg: SearchDistillConfig, variant: str, sampler) -> tuple[object, float]:
    """A fresh copy of the checkpoint with its encoder fine-tuned by `variant`; (model, CPU s)."""
    import torch
    import torch.nn.functional as F

    from lerobot_unidextok.constants import ANGLE_SCALE_RAD
    from lerobot_unidextok.tokenizer import UniDexTok

    torch.manual_seed(cfg.seed)
    model = UniDexTok.from_pretrained(cfg.checkpoint)
    hand_id = torch.tensor([model.hand_id(h) for h in sampler.hand_names])
    vq = model.quantizer

    def batch():
        b = sampler.sample(cfg.batch_size)
        return torch.from_numpy(b.states_rad).float(), torch.from_numpy(b.masks), hand_id[torch.from_numpy(b.hands)]

    cpu0 = time.process_time()
    pool = None
    if variant == "imitate":  # searched once with the checkpoint's own encoding
        parts = [batch() for _ in range(cfg.pool_rows // cfg.batch_size)]
        pool = [(x, h, model.encode(x, h, mask=m)) for x, m, h in parts]
    params = [p for name, p in model.named_parameters() if name.startswith(ENCODER)]
    for name, p in model.named_parameters():
        p.requires_grad_(name.startswith(ENCODER))
    optimizer = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=0.0)
    model.train()
    for step in range(cfg.steps):
        lr = cfg.lr * min(1.0, (step + 1) / 100) * 0.5 * (1 + math.cos(math.pi * step / cfg.steps))
        for g in optimizer.param_groups:
            g["lr"] = lr
        if pool is not None:
            x, h, target = pool[step % len(pool)]
            m = None
        else:
            x, m, h = batch()
        with torch.no_grad():
            c = model.hand_embed(h)  # (B, C) frozen
        sim = vq.similarities(vq.unit_groups(model._encode_latent(x, c)))  # (B, N, K, S)
        if pool is not None:
            loss = F.cross_entropy((sim / cfg.tau).flatten(0, 2), target.flatten())
        else:
            probs = (sim / cfg.tau).softmax(-1)  # (B, N, K, S)
            hard = F.one_hot(sim.argmax(-1), probs.shape[-1]).to(probs.dtype)
            weights = hard + probs - probs.detach()  # forward: the nearest codes; backward: the softmax
            q = torch.einsum("bnks,ksd->bnkd", weights, vq.normalized_codebooks())  # (B, N, K, d)
            x_hat = model._decode_latent(vq.project_out(q.flatten(-2)), c)  # (B, 22) radians
            loss = model.reconstruction_loss(x_hat / ANGLE_SCALE_RAD, x / ANGLE_SCALE_RAD, m)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(params, 1.0)
        optimizer.step()
    model.eval()
    return model, time.process_time() - cpu0


def run(cfg: SearchDistillConfig) -> dict:
    from lerobot_unidextok.evaluation.report import encoding
    from lerobot_unidextok.tokenizer import UniDexTok

    base = UniDexTok.from_pretrained(cfg.checkpoint)
    if not base.config.encoding.rounds:
        raise ValueError(f"{cfg.checkpoint} encodes with the nearest codes: give a checkpoint whose config searches")
    import torch

    sampler, select = sampler_and_selection(cfg, base)
    sets = scored_sets(base, select, cfg.range_rows)
    codes = {label: base.encode(torch.tensor(d.states_rad), d.hand_names()[0], mask=torch.tensor(d.masks))
             for label, d in sets.items() if label.startswith("in-range")}  # fmt: skip
    rows = [{"variant": "checkpoint as it is", "cpu_s": 0.0, **score(base, sets, codes)}]
    for variant in cfg.variants:
        model, cpu_s = fine_tune(cfg, variant, sampler)
        rows.append({"variant": variant, "cpu_s": round(cpu_s, 1), **score(model, sets, codes)})
    searched = score_searched(base, sets)
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "search": encoding(base.config),
              "rows": rows, "searched": searched, "git_commit": git_commit(),
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def score_searched(model, sets: dict) -> dict:
    """The reference: the same sets through the checkpoint's search (MPJAE, deg; in-range mean and worst)."""
    from lerobot_unidextok.evaluation import mpjae_deg
    from lerobot_unidextok.evaluation.reconstruct import reconstruct

    out = {}
    for label, data in sets.items():
        rec = reconstruct(model, data.states_rad, data.hands, masks=data.masks)
        out[label] = mpjae_deg(rec.states_rad, data.states_rad, data.masks)
    in_range = [v for k, v in out.items() if k.startswith("in-range")]
    return {"mpjae_deg": out, "in_range_mean": float(np.mean(in_range)), "in_range_max": float(max(in_range))}


def markdown(result: dict) -> str:
    select = [k for k in result["rows"][0]["mpjae_deg"] if k.startswith("select")]
    rows = [[r["variant"], *[f"{r['mpjae_deg'][k]:.3f}" for k in select], f"{r['in_range_mean']:.3f}",
             f"{r['in_range_max']:.3f}", f"{r['agree_with_search']:.3f}", f"{r['cpu_s']:.0f}",
             VARIANTS.get(r["variant"], "")] for r in result["rows"]]  # fmt: skip
    s = result["searched"]
    rows.append([f"reference: the checkpoint's search ({result['search']})",
                 *[f"{s['mpjae_deg'][k]:.3f}" for k in select], f"{s['in_range_mean']:.3f}",
                 f"{s['in_range_max']:.3f}", "1.000", "-", "not an encoder: a search per state"])  # fmt: skip
    cfg = result["config"]
    return "\n".join([
        f"# {NAME}", "",
        f"Encoder of `{cfg['checkpoint']}` fine-tuned for {cfg['steps']} steps (batch {cfg['batch_size']}, lr "
        f"{cfg['lr']}, tau {cfg['tau']}), decoder, codebooks and hand embeddings frozen; MPJAE (deg) through its "
        f"nearest codes on the selection episodes of `{cfg['recipe']}` and on {cfg['range_rows']} in-range states "
        f"per trained hand (seed {SCREEN_SEED}); agreement: share of code positions where its nearest codes are "
        "the searched ones (in range). CPU s: the fine-tuning (and the pool's search), one thread.", "",
        md_table(["encoder", *select, "in-range mean", "in-range worst", "agreement with the search", "CPU s",
                  "what"], rows),
    ])  # fmt: skip


def parse(argv: list[str] | None = None) -> SearchDistillConfig:
    return runtime.parse(SearchDistillConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(SearchDistillConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
