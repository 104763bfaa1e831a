"""Pool, then fine-tune: the bound checkpoint's state statistics kept through the fine-tune, against the same
fine-tune reading the robot dataset's (what LeRobot's override did before `unidextok-deploy` kept them).

`closed_loop.py`'s `mix_ft_default` runs pool (the recipe's mix, `steps // 2` updates), bind with today's
`unidextok-deploy` (the state's statistics in `unidextok.kept_normalizer`) and fine-tune with the stock
`lerobot-train --policy.path=`. For each of those runs this script takes the same pooled checkpoint, binds it the
same way, folds the kept statistics back into LeRobot's `normalizer_processor` (the bound checkpoint as deploy
wrote it before 2026-12-07, the same numbers: checked on the robot's first frame), fine-tunes it with the same
command, seed and updates, and scores it on the same evaluation episodes. The only difference between the two is
which statistics the fine-tune's state normaliser holds.

    python experiments/kept_state_stats.py --tasks='[PinchLift-v0]' \
        --hands='[inspire_rh56_unitree,shadow,leap,xhand1,linkerhand_l10]' --pools='[2,3,5]' \
        --output_root=outputs/pinchlift --cache_dir=outputs/pinchlift/_sim [--seeds='[0]']

Run `closed_loop.py` with `--arms='[alone,mix_ft_default]'` and the same flags first; its runs are read, not made.
"""

from __future__ import annotations

import json
import logging
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from experiments import closed_loop as cl
from experiments import runtime

logger = logging.getLogger(__name__)
NAME = "kept_state_stats"
ARM = "mix_ft_default"


@dataclass
class KeptStatsConfig:
    tasks: list[str] = field(default_factory=lambda: ["PinchLift-v0"])
    hands: list[str] = field(default_factory=lambda: list(cl.HANDS))
    targets: list[str] = field(default_factory=list)  # default: every hand
    pools: list[int] = field(default_factory=lambda: [2])
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    demos: int = 10
    output_root: str = "outputs"  # closed_loop.py's --output_root: its runs are read here, this one's written
    cache_dir: str = "outputs/closed_loop_sim"  # closed_loop.py's --cache_dir


def closed_loop_config(cfg: KeptStatsConfig) -> cl.ClosedLoopConfig:
    return cl.ClosedLoopConfig(tasks=cfg.tasks, hands=cfg.hands, targets=cfg.targets, pools=cfg.pools, seeds=cfg.seeds, demos=[cfg.demos],
                               mix_demos=[cfg.demos], arms=["alone", ARM], output_root=cfg.output_root,
                               cache_dir=cfg.cache_dir)  # fmt: skip


def swapped(bound: Path, out: Path, robot: Path) -> Path:
    """`bound` with the state's statistics back in LeRobot's normaliser (deploy before 2026-12-07), at `out`."""
    import torch
    from lerobot.datasets import LeRobotDataset
    from lerobot.processor import NormalizerProcessorStep, PolicyProcessorPipeline

    import lerobot_policy_unidextok  # noqa: F401  (the unidextok steps)
    from lerobot_unidextok.policies.checkpoint import PREPROCESSOR
    from lerobot_unidextok.processor import KeptNormalizerStep

    if (out / "model.safetensors").is_file():
        return out
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(bound, out)
    pre = PolicyProcessorPipeline.from_pretrained(out, config_filename=PREPROCESSOR)
    steps = list(pre.steps)
    at = next(i for i, s in enumerate(steps) if type(s) is NormalizerProcessorStep)
    kept = next(s for s in steps if isinstance(s, KeptNormalizerStep))
    rest = steps[at]
    steps[at] = NormalizerProcessorStep(features=rest.features, norm_map=rest.norm_map, eps=rest.eps,
                                        stats={**rest.stats, **kept.stats})  # fmt: skip
    steps.remove(kept)
    old = PolicyProcessorPipeline(steps=steps, name=pre.name)
    item = LeRobotDataset("x", root=robot)[0]
    obs = {k: v.unsqueeze(0) for k, v in item.items() if k.startswith("observation") and torch.is_tensor(v)}
    a, b = pre(dict(obs)), old(dict(obs))
    if not all(torch.equal(a[k], b[k]) for k in obs):
        raise RuntimeError(f"folding the kept statistics back changed what {bound} computes")
    old.save_pretrained(out, config_filename=PREPROCESSOR)
    return out


def run_one(cfg: KeptStatsConfig, ccfg: cl.ClosedLoopConfig, job: dict) -> dict:
    done = Path(cfg.output_root) / NAME / "runs" / f"seed{job['seed']}" / f"{job['task']}__{job['hand']}__{job['arm']}.json"
    if done.is_file():
        return json.loads(done.read_text())
    kept = cl.cached_run(ccfg, job)
    if kept is None:
        raise FileNotFoundError(f"no closed_loop run of {job['arm']} for {job['hand']} seed {job['seed']}: run "
                                "closed_loop.py with --arms='[alone,mix_ft_default]' and these flags first")  # fmt: skip
    robot, out = cl.plan(ccfg, job)["robot"], cl.policy_dir(ccfg, job)
    cpu0 = time.process_time()
    bound = swapped(out / "bound", out / "swapped_bound", robot)
    tuned = cl.fine_tune_policy(cl.fine_tune_args(ccfg, bound, robot, out / "swapped_fine_tuned", job["seed"],
                                                  kept["fine_tune_steps"]), out / "swapped_fine_tuned")  # fmt: skip
    shutil.rmtree(out / "swapped_fine_tuned" / "checkpoints" / "last" / "training_state", ignore_errors=True)
    scores = cl.evaluate(ccfg, tuned, job["task"], job["hand"], job["seed"])
    result = {**{k: job[k] for k in ("task", "hand", "seed", "arm", "pool")}, "kept": kept["successes"],
              "swapped": scores["successes"], "episodes": scores["episodes"],
              "cpu_s": round(time.process_time() - cpu0, 1)}  # fmt: skip
    done.parent.mkdir(parents=True, exist_ok=True)
    done.write_text(json.dumps(result))
    logger.info("%s/%s/%s/seed%d: kept %d, swapped %d of %d", job["task"], job["hand"], job["arm"], job["seed"],
                result["kept"], result["swapped"], result["episodes"])  # fmt: skip
    return result


def run(cfg: KeptStatsConfig) -> dict:
    ccfg = closed_loop_config(cfg)
    jobs = [j for j in cl.jobs(ccfg) if j["kind"] == ARM]
    alone = {(j["task"], j["hand"], j["seed"]): cl.cached_run(ccfg, j) for j in cl.jobs(ccfg) if j["kind"] == "alone"}
    runs = [run_one(cfg, ccfg, j) for j in jobs]
    for r in runs:
        a = alone.get((r["task"], r["hand"], r["seed"]))
        r["alone"] = a["successes"] if a else None
    return {"config": vars(cfg), "runs": runs}


def markdown(result: dict) -> str:
    """Per task and pool: the mean gain over the hand alone of each fine-tune, and how many targets stay within
    3 points of the hand alone, over the seeds."""
    lines = ["| task | pool | kept: mean gain (within 3 of alone) | swapped: mean gain (within 3) | kept - swapped, "
             "per target | CPU-min |", "|---|---|---|---|---|---|"]  # fmt: skip
    runs = result["runs"]
    for task in dict.fromkeys(r["task"] for r in runs):
        for k in sorted({r["pool"] for r in runs if r["task"] == task}):
            cell = [r for r in runs if r["task"] == task and r["pool"] == k and r["alone"] is not None]
            by_hand: dict[str, dict[str, list[float]]] = {}
            for r in cell:
                for arm in ("kept", "swapped", "alone"):
                    by_hand.setdefault(r["hand"], {}).setdefault(arm, []).append(100 * r[arm] / r["episodes"])
            gains = {arm: {h: np.mean(v[arm]) - np.mean(v["alone"]) for h, v in by_hand.items()}
                     for arm in ("kept", "swapped")}  # fmt: skip
            diff = ", ".join(f"{h} {gains['kept'][h] - gains['swapped'][h]:+.0f}" for h in by_hand)
            within = {arm: sum(g >= -cl.NEVER_WORSE_POINTS for g in gains[arm].values()) for arm in gains}
            lines.append(f"| {task} | {k} | {np.mean(list(gains['kept'].values())):+.1f} ({within['kept']} of "
                         f"{len(by_hand)}) | {np.mean(list(gains['swapped'].values())):+.1f} ({within['swapped']} of "
                         f"{len(by_hand)}) | {diff} | {sum(r['cpu_s'] for r in cell) / 60:.1f} |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(KeptStatsConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
