"""The simulator's speed and its scripted experts' success, per hand and task.

For each hand and task: env steps per CPU-second (one step = 0.1 s of simulated time, 25 MuJoCo steps of 4 ms
with the hand's contacts; the expert's actions, so the steps include grasps and presses), the MuJoCo step's CPU
cost beside the real-time factor, and the expert's success over `--episodes` seeded episodes (episode i drawn
from seed `--seed` + i, the expert's noise from 2,000,000 + i, as experiments/closed_loop.py measures it on its
evaluation episodes) with its 95 % Wilson interval. CPU seconds are this process's (`time.process_time`), so
the figures hold on shared cores.

    .venv/bin/python benchmarks/bench_sim.py                          # 100 episodes per hand and task
    .venv/bin/python benchmarks/bench_sim.py --episodes 20 --hands shadow
    .venv/bin/python benchmarks/bench_sim.py --episodes 20 --hands leap --fingertips   # with the fingertip columns

Hands: by default every hand spec the simulator runs (`sim_hands.sim_hand_names()`: the model files', the shipped
built models, and every spec whose URDF is found under `$UNIDEXTOK_URDF_DIR`, else ../shared/data/urdf). The
failures column says how the failed episodes failed: a grasp's by the kind of grasp its object needed (power or
pinch), a press's as "wrong" (another button pressed: the episode ends) or "timeout" (the goal button not
pressed in 50 steps), a sequence's as "wrong order" (a button pressed out of turn), "wrong finger" (the button due
pressed by another finger) or "timeout (k of 3 done)", a chord's as "wrong button" (one outside the chord down),
"wrong finger" (a named button down by another finger) or "timeout (k of 2 down together)" (`Task.failure_reason`).
A hand a task refuses (too few fingers) gets a row saying so.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from lerobot_env_unidextok.columns import TASKS
from lerobot_env_unidextok.errors import SimInputError


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--hands", nargs="+", default=None, help="hand specs (default: every one the simulator runs)")
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), help=f"default: every task ({', '.join(TASKS)})")
    ap.add_argument("--fingertips", action="store_true", help="observe the fingertip columns too (--env.fingertips)")
    args = ap.parse_args()

    from lerobot_env_unidextok import sim_hands
    from lerobot_env_unidextok.env import SUBSTEPS, UniDexTokEnv
    from lerobot_env_unidextok.experts import Expert
    from lerobot_env_unidextok.scene import TIMESTEP_S
    from lerobot_env_unidextok.success import wilson_interval

    print("| hand | task | expert success | 95 % interval | failures | env steps / CPU-s | CPU ms / MuJoCo step | "
          "x real time |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for hand in args.hands or sim_hands.sim_hand_names():
        for task in args.tasks:
            try:
                env = UniDexTokEnv(hand, task, render_mode=None, fingertips=args.fingertips)
            except SimInputError as err:  # a hand the task refuses
                print(f"| {hand} | {task} | refused | - | {err} | - | - | - |")
                continue
            wins, steps, cpu, failures = 0, 0, 0.0, {}
            for i in range(args.episodes):
                obs, _ = env.reset(seed=args.seed + i)
                expert = Expert(env, np.random.default_rng(2_000_000 + i))
                expert.reset(obs)
                for _ in range(50):
                    action = expert.act(obs)
                    t0 = time.process_time()
                    obs, _, terminated, _, info = env.step(action)
                    cpu += time.process_time() - t0
                    steps += 1
                    if terminated:
                        break
                wins += bool(info["is_success"])
                if not info["is_success"]:
                    kind = env.task.failure_reason(terminated)
                    failures[kind] = failures.get(kind, 0) + 1
            lo, hi = wilson_interval(wins, args.episodes)
            per_step = cpu / steps
            failed = ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "-"
            print(f"| {hand} | {task} | {wins}/{args.episodes} = {100 * wins / args.episodes:.0f} % | "
                  f"{100 * lo:.0f}-{100 * hi:.0f} % | {failed} | {1 / per_step:.0f} | "
                  f"{1000 * per_step / SUBSTEPS:.3f} | "
                  f"{SUBSTEPS * TIMESTEP_S / per_step:.0f} |")  # fmt: skip


if __name__ == "__main__":
    main()
