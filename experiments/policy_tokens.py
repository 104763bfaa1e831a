"""What hand tokens cost a policy: the same small ACT trained on one robot's episodes with different hand
inputs, scored open loop on episodes it never saw, next to copying the current state.

    python experiments/policy_tokens.py                         # real G1 + Inspire, 3 folds x 3 seeds
    python experiments/policy_tokens.py --inputs='[udhm,tokens_dequantized]' --seeds='[0,1,2,3,4]'
    python experiments/policy_tokens.py --datasets='[path/to/converted_robot]' --act.steps=3000

Inputs (`policy_data.HAND_INPUTS`): the arms are the same in all (`observation.state`, radians); the hand part
(`observation.environment_state`) is the native values, the UDHM blocks, UniDexTok codes dequantized or as
code vectors, or 8-bit binned UDHM blocks. Targets: the converted action chunk (arms + the UDHM slots each
hand has). Folds: whole episodes, dealt round-robin after a shuffle with `split_seed`; in each fold a
tokenizer is trained on the training episodes only (`--tokenizer.*`, unidextok-train's settings), unless
`--tokenizer_pretrained` names one for every fold (e.g. a tokenizer never trained on this robot).
Every (input, fold, seed) run is cached in <output_root>/policy_tokens/runs.jsonl, keyed by its settings.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from experiments.policy_data import HAND_INPUTS, TOKEN_INPUTS, RobotFrames
from experiments.policy_training import SmallACT
from lerobot_unidextok.tokenizer import EncodingConfig
from lerobot_unidextok.training.config import TrainConfig

logger = logging.getLogger(__name__)
NAME = "policy_tokens"
COPY = "copy_state"
METRICS = ("arms_deg_first", "arms_deg_chunk", "hands_udhm_deg_first", "hands_udhm_deg_chunk",
           "hands_native_first", "hands_native_chunk")  # fmt: skip


@dataclass
class TokenizerTraining(TrainConfig):
    """unidextok-train's settings for the per-fold tokenizer, shortened (the small preset, 500 steps)."""

    steps: int = 500
    lr: float = 6e-3
    warmup_steps: int = 50
    eval_every: int = 250
    # written into the fold's checkpoint: the token inputs use the package's default encoding (the greedy code
    # search, one round), as the shipped tokenizer and the processor step do
    encoding: EncodingConfig | None = field(default_factory=lambda: EncodingConfig(rounds=1))


@dataclass
class PolicyTokensACT(SmallACT):
    """act_udt_cpu.yaml's sizes, steps cut to fit 30 CPU-minutes (a class default, so `--act.<field>=...` keeps
    it: draccus builds a nested config from its class, which reset the steps to 5000)."""

    steps: int = 800


@dataclass
class PolicyTokensConfig:
    datasets: list[str] = field(default_factory=list)  # one converted whole-robot dataset; empty = real G1 recordings
    inputs: list[str] = field(default_factory=lambda: list(HAND_INPUTS))  # hand inputs compared (see --help of policy_data)
    folds: int = 3  # k-fold over whole episodes
    only_folds: list[int] = field(default_factory=list)  # run only these folds; empty = all
    split_seed: int = 0  # shuffles the episodes before they are dealt into folds
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])  # ACT initialisation and batch order
    # ACT sizes, batch, lr: configs/lerobot/act_udt_cpu.yaml's; steps cut to fit 30 CPU-minutes (--act.steps=...)
    act: PolicyTokensACT = field(default_factory=PolicyTokensACT)
    tokenizer: TokenizerTraining = field(default_factory=TokenizerTraining)  # per-fold tokenizer training
    # A tokenizer (folder or Hub repo id) used for every fold instead of training one; empty = train per fold.
    tokenizer_pretrained: str = ""
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_data"  # where the real recordings are converted once

    def __post_init__(self) -> None:
        if isinstance(self.act, dict):
            self.act = PolicyTokensACT(**self.act)
        if isinstance(self.tokenizer, dict):
            self.tokenizer = TokenizerTraining(**self.tokenizer)
        unknown = sorted(set(self.inputs) - set(HAND_INPUTS))
        if unknown:
            raise ValueError(f"unknown inputs {unknown}; choose from {sorted(HAND_INPUTS)}")
        if len(self.datasets) > 1:
            raise ValueError(f"give one converted robot dataset (one state layout), got {len(self.datasets)}")
        if not self.seeds:
            raise ValueError("give at least one seed, e.g. --seeds='[0,1,2]'")


# ---------------------------------------------------------------------------------------------
# folds and tokenizers
# ---------------------------------------------------------------------------------------------
def episode_folds(episodes: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Test episodes of each fold: every episode in exactly one, shuffled then dealt round-robin."""
    unique = np.unique(episodes)
    if not 2 <= folds <= len(unique):
        raise ValueError(f"folds must be in [2, {len(unique)}] (the number of episodes), got {folds}")
    order = np.random.default_rng(seed).permutation(unique)
    return [np.sort(order[k::folds]) for k in range(folds)]


def _digest(obj: object) -> str:
    return hashlib.sha1(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:12]


def fold_tokenizer(cfg: PolicyTokensConfig, frames: RobotFrames, test: np.ndarray, folder: Path) -> tuple[str, dict]:
    """(tokenizer folder or repo id, facts) for a fold: `tokenizer_pretrained`, else one trained on the fold's
    training episodes only (cached by its settings and episodes)."""
    if cfg.tokenizer_pretrained:
        return cfg.tokenizer_pretrained, {"tokenizer": cfg.tokenizer_pretrained, "trained_on_fold": False}
    import torch

    from lerobot_unidextok.training import load_hand_states, train_tokenizer
    from lerobot_unidextok.training.splits import split_by_episode

    train_cfg = dataclasses.asdict(cfg.tokenizer)
    for volatile in ("output_dir", "datasets", "progress"):
        train_cfg.pop(volatile)
    key = _digest({"train": train_cfg, "test": test.tolist(), "data": str(frames.root)})
    out = folder / "tokenizers" / key
    facts_path = out / "fold_tokenizer.json"
    if facts_path.is_file():
        return str(out / "best"), json.loads(facts_path.read_text())
    data = load_hand_states([str(frames.root)], split=None)
    train = data.select(np.flatnonzero(~np.isin(data.episode_index, test)))
    tcfg = dataclasses.replace(cfg.tokenizer, output_dir=str(out), progress=False, save_last_every=10**9)
    fit, select = split_by_episode(train, tcfg.select_fraction, seed=tcfg.seed)
    torch.manual_seed(tcfg.seed)
    cpu0 = time.process_time()
    res = train_tokenizer(tcfg, fit, select)
    facts = {"tokenizer": f"trained on the fold's training episodes ({len(fit)} rows, {res.steps} steps)",
             "trained_on_fold": True, "select_mpjae_deg": res.best_mae_deg,
             "train_cpu_s": round(time.process_time() - cpu0, 1)}  # fmt: skip
    facts_path.write_text(json.dumps(facts))
    return str(res.best_dir), facts


# ---------------------------------------------------------------------------------------------
# runs
# ---------------------------------------------------------------------------------------------
def run_one(cfg: PolicyTokensConfig, frames: RobotFrames, kind: str, hands_x: np.ndarray, test: np.ndarray,
            seed: int) -> dict:  # fmt: skip
    from experiments.policy_data import chunk_index, open_loop_errors
    from experiments.policy_training import train_act

    held = np.isin(frames.episode, test)
    train_rows, test_rows = np.flatnonzero(~held), np.flatnonzero(held)
    chunk, cols = cfg.act.chunk_size, frames.action_columns
    index, pad = chunk_index(frames.episode, chunk)
    arms = frames.state[:, frames.passthrough_columns]
    model = train_act(cfg.act, arms[train_rows], hands_x[train_rows], frames.action[index[train_rows]][..., cols],
                      pad[train_rows], seed=seed)  # fmt: skip
    pred = np.zeros((len(test_rows), chunk, frames.action.shape[1]))
    pred[..., cols] = model.predict(arms[test_rows], hands_x[test_rows])
    return {"errors": open_loop_errors(pred, frames, test_rows, chunk), "train_cpu_s": round(model.cpu_s, 1),
            "steps_per_s": round(model.steps_per_s, 1), "final_loss": model.final_loss,
            "hand_input_width": int(hands_x.shape[1]), "train_rows": len(train_rows), "test_rows": len(test_rows)}  # fmt: skip


def cached_runs(cache: Path) -> dict[str, dict]:
    """Finished runs by settings digest and seed."""
    done = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            r = json.loads(line)
            done[_digest(r["resolved"]) + f"/{r['seed']}"] = r
    return done


def resolved(cfg: PolicyTokensConfig, kind: str, test: np.ndarray, tokenizer: str, data: str) -> dict:
    """Everything a run's result depends on: its cache key (the per-fold tokenizer's folder is named by the digest
    of its training settings, test episodes and data)."""
    out = {"act": dataclasses.asdict(cfg.act), "test_episodes": test.tolist(), "data": data, "input": kind}
    if kind in TOKEN_INPUTS:
        out["tokenizer"] = tokenizer
    return out


def run(cfg: PolicyTokensConfig) -> dict:
    from experiments.policy_data import copy_state_prediction, hand_input, load_frames, open_loop_errors

    t0 = time.time()
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    if cfg.datasets:
        source, root = "datasets", Path(cfg.datasets[0])
    else:
        from experiments.unseen_data import converted_g1

        source, root = "real", converted_g1(cfg.cache_dir)
    frames = load_frames(root)
    fold_tests = episode_folds(frames.episode, cfg.folds, cfg.split_seed)
    fold_ids = cfg.only_folds or list(range(cfg.folds))
    cache = folder / "runs.jsonl"
    runs, tokenizers = [], {}
    for k in fold_ids:
        test = fold_tests[k]
        tok, facts = (fold_tokenizer(cfg, frames, test, folder) if set(cfg.inputs) & set(TOKEN_INPUTS)
                      else ("", {}))  # fmt: skip
        tokenizers[k] = facts
        rows = np.flatnonzero(np.isin(frames.episode, test))
        copy = open_loop_errors(copy_state_prediction(frames, rows, cfg.act.chunk_size), frames, rows,
                                cfg.act.chunk_size)  # fmt: skip
        runs.append({"input": COPY, "fold": k, "seed": None, "errors": copy, "test_episodes": test.tolist()})
        for kind in cfg.inputs:
            settings = resolved(cfg, kind, test, tok, str(root))
            hands_x = None
            for seed in cfg.seeds:
                key = _digest(settings) + f"/{seed}"
                done = cached_runs(cache)  # re-read: processes running other folds or inputs append to it
                if key not in done:
                    if hands_x is None:
                        hands_x = hand_input(kind, frames, tok or None)
                    logger.info("fold %d, %s, seed %d: training ACT (%d steps)", k, kind, seed, cfg.act.steps)
                    r = {"input": kind, "fold": k, "seed": seed, "test_episodes": test.tolist(), "resolved": settings,
                         **run_one(cfg, frames, kind, hands_x, test, seed)}  # fmt: skip
                    with cache.open("a") as f:
                        f.write(json.dumps(r) + "\n")
                    done[key] = r
                runs.append(done[key])
    result = {
        "experiment": NAME, "command": command_line(cfg), "config": dataclasses.asdict(cfg), "fold_tests": [t.tolist() for t in fold_tests],
        "fold_ids": fold_ids, "tokenizers": tokenizers, "summary": summarise(runs, cfg), "runs": runs,
        "provenance": provenance(cfg, source, root, frames, fold_tests, fold_ids, time.time() - t0),
    }  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def command_line(cfg: PolicyTokensConfig) -> str:
    """`python experiments/policy_tokens.py` with the flags of every setting that differs from the defaults."""
    flags = []

    def walk(obj, default, prefix: str) -> None:
        for f in dataclasses.fields(obj):
            value, base = getattr(obj, f.name), getattr(default, f.name)
            if dataclasses.is_dataclass(value):
                walk(value, base, f"{prefix}{f.name}.")
            elif value != base:
                shown = "[" + ",".join(map(str, value)) + "]" if isinstance(value, list) else value
                flags.append(f"--{prefix}{f.name}={shown}" if not isinstance(value, list) else f"--{prefix}{f.name}='{shown}'")

    walk(cfg, PolicyTokensConfig(), "")
    return " ".join(["python experiments/policy_tokens.py", *flags])


def provenance(cfg, source: str, root: Path, frames: RobotFrames, fold_tests, fold_ids, seconds: float) -> dict:
    """What `make_results` prints above the table."""
    test = np.isin(frames.episode, np.concatenate([fold_tests[k] for k in fold_ids]))
    train_rows = [int((~np.isin(frames.episode, fold_tests[k])).sum()) for k in fold_ids]
    name = "g1-inspire (converted)" if source == "real" else str(root)
    return {"data": {"source": source, "synthetic_sample": False, "datasets": [name],
                     "train_rows": " / ".join(map(str, train_rows)) + " per fold",
                     "test_rows": int(test.sum()), "hands": sorted(set(frames.hands))},
            "preset": cfg.tokenizer.preset if not cfg.tokenizer_pretrained else cfg.tokenizer_pretrained,
            "seed": cfg.seeds, "git_commit": git_commit(), "config": {"steps": cfg.act.steps, **dataclasses.asdict(cfg)},
            "wall_seconds": round(seconds, 1), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# summary and table
# ---------------------------------------------------------------------------------------------
def summarise(runs: list[dict], cfg: PolicyTokensConfig) -> dict:
    """Per input and metric: each seed's mean over folds, then mean and std over seeds (copy: one value)."""
    out = {}
    for kind in [COPY, *cfg.inputs]:
        rs = [r for r in runs if r["input"] == kind]
        seeds = sorted({r["seed"] for r in rs}, key=lambda s: -1 if s is None else s)
        per_seed = {m: [float(np.mean([r["errors"][m] for r in rs if r["seed"] == s])) for s in seeds] for m in METRICS}
        out[kind] = {m: {"mean": float(np.mean(v)), "std": float(np.std(v, ddof=1)) if len(v) > 1 else 0.0}
                     for m, v in per_seed.items()}  # fmt: skip
        out[kind]["seeds"] = len(seeds) if kind != COPY else 0
        out[kind]["folds"] = len({r["fold"] for r in rs})
        cpu = [r["train_cpu_s"] for r in rs if "train_cpu_s" in r]
        out[kind]["train_cpu_s"] = float(np.mean(cpu)) if cpu else 0.0
    return out


def _cell(s: dict, metric: str, digits: int) -> str:
    v = s[metric]
    return f"{v['mean']:.{digits}f}" + (f" +- {v['std']:.{digits}f}" if s["seeds"] else "")


def relative_to(summary: dict, kind: str, base: str = "udhm", metric: str = "hands_udhm_deg_chunk") -> float | None:
    """`kind`'s mean MAE over `base`'s, minus one (0.05 = 5 % worse); None without both."""
    if kind not in summary or base not in summary:
        return None
    return summary[kind][metric]["mean"] / summary[base][metric]["mean"] - 1.0


def markdown(result: dict) -> str:
    cfg, s = result["config"], result["summary"]
    act = cfg["act"]
    header = ["hand input", "arms deg, first", "arms deg, chunk", "hands UDHM deg, first", "hands UDHM deg, chunk",
              "hands native, first", "hands native, chunk", "hands chunk vs udhm", "ACT CPU s/run"]  # fmt: skip
    rows = []
    for kind, v in s.items():
        rel = relative_to(s, kind)
        rows.append([kind, _cell(v, "arms_deg_first", 2), _cell(v, "arms_deg_chunk", 2),
                     _cell(v, "hands_udhm_deg_first", 2), _cell(v, "hands_udhm_deg_chunk", 2),
                     _cell(v, "hands_native_first", 4), _cell(v, "hands_native_chunk", 4),
                     "" if rel is None or kind == "udhm" else f"{100 * rel:+.1f} %",
                     f"{v['train_cpu_s']:.0f}" if v["seeds"] else ""])  # fmt: skip
    tok = "; ".join(f["tokenizer"] + (f", {f['select_mpjae_deg']:.2f} deg MPJAE on its selection episodes"
                                       if "select_mpjae_deg" in f else "")
                    for f in result["tokenizers"].values() if f) or "none"  # fmt: skip
    what = [f"- `{k}`: {HAND_INPUTS[k]}" for k in cfg["inputs"]]
    return "\n".join([
        f"# {NAME}", "",
        f"LeRobot's ACT (stock model; dim_model {act['dim_model']}, {act['n_encoder_layers']} encoder / "
        f"{act['n_decoder_layers']} decoder layers, VAE {act['use_vae']}, chunk {act['chunk_size']}, {act['steps']} steps "
        f"at batch {act['batch_size']}, lr {act['lr']:g}, one CPU thread), the same for every input: arms (radians) as "
        "`observation.state`, the hand input as `observation.environment_state`, both z-scored on the training rows; "
        f"targets: the converted action chunk. {len(result['fold_ids'])} of {cfg['folds']} folds over whole episodes "
        f"(test episodes per fold: {result['fold_tests']}), seeds {cfg['seeds']}. Open-loop mean absolute error on the "
        "held-out episodes' frames, at the first predicted action and over the chunk (steps past an episode's end "
        "excluded): arms in degrees, hands in UDHM degrees (the slots each hand has) and in the robot's native units; "
        "mean +- std over seeds of each seed's mean over folds. `copy_state`: every future action = the current "
        f"state. Tokenizer: {tok}. Hand inputs:", "", *what, "",
        md_table(header, rows), "",
        "`hands chunk vs udhm`: hands UDHM MAE over the chunk against the `udhm` input (+5 % = 5 % worse).", "",
        *reading(result),
    ])  # fmt: skip


def reading(result: dict) -> list[str]:
    """What the table says, computed from it: each quantised input against the UDHM state (the 5 % goal), the
    reference, the universal-tokenizer variant and the CPU spent."""
    s, cfg = result["summary"], result["config"]
    lines = []
    base = s.get("udhm")
    for kind in ("tokens_dequantized", "tokens_embedding", "binned_8bit", "native"):
        if kind not in s or base is None:
            continue
        parts = []
        for metric, label in (("hands_udhm_deg_first", "hands, first action"), ("hands_udhm_deg_chunk", "hands, chunk"),
                              ("arms_deg_chunk", "arms, chunk")):  # fmt: skip
            rel = relative_to(s, kind, metric=metric)
            noise = base[metric]["std"] / base[metric]["mean"]
            parts.append(f"{label} {100 * rel:+.1f} % (udhm seed std {100 * noise:.1f} %)")
        worst = max(relative_to(s, kind, metric=m) for m in ("hands_udhm_deg_first", "hands_udhm_deg_chunk"))
        verdict = "within the 5 % goal" if worst <= 0.05 else "NOT within the 5 % goal"
        lines.append(f"- `{kind}` against `udhm`: {'; '.join(parts)}: {verdict} on the hands.")
    if COPY in s:
        compared = ("arms_deg_first", "arms_deg_chunk", "hands_udhm_deg_first", "hands_udhm_deg_chunk")
        beaten = [k for k in cfg["inputs"] if any(s[k][m]["mean"] < s[COPY][m]["mean"] for m in compared)]
        lines.append("- Copying the current state beats every input on arms and hands, first action and chunk: at "
                     "this size, steps and data this ACT does not beat holding still open loop, so the table compares "
                     "inputs, not a useful controller." if not beaten else
                     f"- Inputs beating copying the current state on arms or hands (first action or chunk): {beaten}.")  # fmt: skip
    if not cfg["tokenizer_pretrained"]:
        lines.append("- Tokenizer trained on this robot's training episodes in each fold. A tokenizer not trained on "
                     "this robot (e.g. `unidextok/universal-small`) runs with `--tokenizer_pretrained=<repo id or folder>`.")
    runs = [r for r in result["runs"] if "train_cpu_s" in r]
    tok_cpu = sum(f.get("train_cpu_s", 0.0) for f in result["tokenizers"].values() if f)
    lines.append(f"- CPU: {len(runs)} ACT runs, {sum(r['train_cpu_s'] for r in runs):.0f} CPU-s training "
                 f"({np.mean([r['train_cpu_s'] for r in runs]):.0f} s each, one thread) + {tok_cpu:.0f} CPU-s for the "
                 f"fold tokenizers; sized for a 30 CPU-minute budget: {cfg['act']['steps']} ACT steps, "
                 f"{cfg['tokenizer']['steps']} tokenizer steps, {len(cfg['seeds'])} seeds, folds {result['fold_ids']} of "
                 f"{cfg['folds']}." if runs else "- CPU: no ACT runs.")  # fmt: skip
    return lines


def parse(argv: list[str] | None = None) -> PolicyTokensConfig:
    return runtime.parse(PolicyTokensConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(PolicyTokensConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
