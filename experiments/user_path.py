"""The user's path against the table: one cell of `experiments/closed_loop.py`, run as the stock command lines its
`user_commands` renders (`unidextok-sim-record`, `unidextok-convert`, `unidextok-mix`, `lerobot-train` on
act_udt_cpu.yaml with the user's flags only, `unidextok-deploy`, `lerobot-eval`), each a subprocess in a fresh
output root, its success set beside the table's kept run of the same cell (same seeds, hands and episodes).

    python experiments/user_path.py                          # the Shadow beside the Allegro, 10 demos, seed 0
    python experiments/user_path.py --hand=linkerhand_l10 --pool=3 --seed=1

The table's run is read from `table_root` (`closed_loop.py`'s `--output_root`); run the table's command first.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import closed_loop as cl
from experiments import runtime
from lerobot_env_unidextok.success import wilson_interval

logger = logging.getLogger(__name__)
NAME = "user_path"


@dataclass
class UserPathConfig:
    task: str = "GraspLift-v0"
    hand: str = "shadow"  # the target
    pool: int = 2  # the target and the pool - 1 hands after it (closed_loop.pool_hands)
    demos: int = 10
    arm: str = "mix"  # a closed_loop arm with one training (not a fine-tuned arm)
    seed: int = 0
    table_root: str = "outputs/experiments"  # closed_loop.py's --output_root, whose kept run is compared
    output_root: str = "outputs/user_path"  # wiped and written by the command lines

    def __post_init__(self) -> None:
        if self.arm not in cl.ARMS or self.arm in cl.FINE_TUNED:
            raise ValueError(f"arm must be one of closed_loop's one-training arms, got {self.arm!r}")


def closed_loop_config(cfg: UserPathConfig, output_root: str) -> cl.ClosedLoopConfig:
    """The closed_loop config of the cell, its datasets and policies under `output_root`."""
    return cl.ClosedLoopConfig(tasks=[cfg.task], targets=[cfg.hand], pools=[cfg.pool], demos=[cfg.demos],
                               mix_demos=[cfg.demos], arms=[cfg.arm], seeds=[cfg.seed], output_root=output_root,
                               cache_dir=str(Path(output_root) / "_sim"))  # fmt: skip


def cell_job(ccfg: cl.ClosedLoopConfig) -> dict:
    """The one job of the cell's config (the arm at the asked pool, or the hand alone)."""
    jobs = [j for j in cl.jobs(ccfg) if j["kind"] in ccfg.arms]
    if len(jobs) != 1:
        raise ValueError(f"expected one cell, the config gives {[j['arm'] for j in jobs]}")
    return jobs[0]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(cfg: UserPathConfig) -> dict:
    t0 = time.time()
    out = Path(cfg.output_root)
    shutil.rmtree(out, ignore_errors=True)
    user = closed_loop_config(cfg, str(out))
    job = cell_job(user)
    lines = cl.user_commands(user, job)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "HF_HUB_OFFLINE": "1"}  # fmt: skip
    out.mkdir(parents=True)
    log = out / "commands.log"
    cpu0 = os.times()
    for line in lines:
        logger.info("$ %s", line)
        with log.open("a") as f:
            f.write(f"$ {line}\n")
            f.flush()
            done = subprocess.run(["bash", "-c", line], env=env, stdout=f, stderr=subprocess.STDOUT)
        if done.returncode:
            raise RuntimeError(f"{line.split()[0]} failed ({done.returncode}); see {log}")
    cpu = os.times()
    info = json.loads((cl.policy_dir(user, job) / "eval" / "eval_info.json").read_text())
    overall = info["overall"]
    n = int(overall["n_episodes"])
    k = round(float(overall["pc_success"]) * n / 100)
    table = closed_loop_config(cfg, cfg.table_root)
    kept = json.loads(cl.run_path(table, job).read_text()) if cl.run_path(table, job).is_file() else None
    ours = cl.policy_dir(user, job) / "checkpoints" / "last" / "pretrained_model" / "model.safetensors"
    theirs = cl.policy_dir(table, job) / "checkpoints" / "last" / "pretrained_model" / "model.safetensors"
    return {"experiment": NAME, "config": cfg.__dict__, "job": job, "commands": lines,
            "user": {"successes": k, "episodes": n, "interval": wilson_interval(k, n)},
            "table": None if kept is None else {"successes": kept["successes"], "episodes": kept["episodes"],
                                                "interval": wilson_interval(kept["successes"], kept["episodes"]),
                                                "recipe_equal": kept.get("recipe") == cl.recipe(table, job["kind"])},
            "same_weights": theirs.is_file() and sha256(ours) == sha256(theirs),
            "cpu_s": round(cpu.children_user + cpu.children_system - cpu0.children_user - cpu0.children_system, 1),
            "wall_s": round(time.time() - t0, 1)}  # fmt: skip


def markdown(result: dict) -> str:
    u, t, job = result["user"], result["table"], result["job"]
    lines = [f"# {NAME}", "", f"{job['task']}, target {job['hand']}, {job['arm']}, seed {job['seed']}: the stock command "
             f"lines ({len(result['commands'])}, in `commands.log`), {result['cpu_s'] / 60:.1f} CPU-minutes, "
             f"{result['wall_s'] / 60:.1f} min wall.", "",
             f"- the user's path: {u['successes']}/{u['episodes']} ({100 * u['interval'][0]:.0f}-"
             f"{100 * u['interval'][1]:.0f} %)"]  # fmt: skip
    if t is None:
        lines.append("- the table's run: none kept (run closed_loop.py's command first)")
    else:
        lines += [f"- the table's run: {t['successes']}/{t['episodes']} ({100 * t['interval'][0]:.0f}-"
                  f"{100 * t['interval'][1]:.0f} %){'' if t['recipe_equal'] else ', kept with another recipe'}",
                  f"- the same model.safetensors: {'yes' if result['same_weights'] else 'no'}"]  # fmt: skip
    return "\n".join(lines)


def run_and_write(cfg: UserPathConfig) -> dict:
    """`run`, its JSON and Markdown written to `output_root`."""
    result = run(cfg)
    root = Path(cfg.output_root)
    (root / f"{NAME}.json").write_text(json.dumps(result, indent=1))
    (root / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def main(argv: list[str] | None = None) -> None:
    runtime.cli(UserPathConfig, run_and_write, markdown, argv)


if __name__ == "__main__":
    main()
