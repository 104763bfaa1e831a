"""Latency of the UniDexTok processor step (CPU), batch 1 and batch 256, small and paper presets.

Measured in the same run against a reference: the bare tokenizer `encode` + `decode` on the same
rows, so the figure for the step = tokenizer cost + LeRobot pipeline/step overhead (block gather by
name, range guard, reshapes). Inputs are synthetic G1-like frames from tests/fixtures/robot_udhm.py
(two Inspire hands in UDHM; `--layout robot` adds the 14 arm joints in front: a 58-wide whole-robot
state), tiled to the batch size. Weights are untrained (latency does not depend on them).
Target: <= 1 ms per single state (one hand), small preset.

    .venv/bin/python benchmarks/bench_processor.py
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --repeats_large 3
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --num_hands 1 --presets small --batches 1
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --layout robot --presets small --batches 1
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.processor import UniDexTokStateTokenizerStep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "fixtures"))
from robot_udhm import ARM_NAMES, INSPIRE, STATE_NAMES, inspire_states


def median_ms(fns, repeats: int) -> list[tuple[float, float]]:
    """Median (CPU ms, wall ms) per call of each function, calls interleaved (f0, f1, f0, f1, ...) so every
    function sees the same load on shared cores; CPU time is the clock that survives them best."""
    for fn in fns:  # warm-up
        fn()
        fn()
    cpu, wall = [[] for _ in fns], [[] for _ in fns]
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            cpu[i].append(time.process_time() - c0)
            wall[i].append(time.perf_counter() - t0)
    return [(1e3 * statistics.median(c), 1e3 * statistics.median(w)) for c, w in zip(cpu, wall, strict=True)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", nargs="+", default=["small", "paper"])
    parser.add_argument("--batches", nargs="+", type=int, default=[1, 256])
    parser.add_argument("--repeats", type=int, default=100, help="timed calls at batch 1")
    parser.add_argument("--repeats_large", type=int, default=5, help="timed calls at batch > 1")
    parser.add_argument("--num_hands", type=int, choices=(1, 2), default=2, help="UDHM blocks per frame")
    parser.add_argument("--layout", choices=("hands", "robot"), default="hands", help="robot: 14 arm joints first")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0 = torch default)")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    poses = torch.from_numpy(inspire_states(64, seed=0))[:, : 22 * args.num_hands]  # (P, 22*H) UDHM rad
    hands = [INSPIRE] * args.num_hands
    names = STATE_NAMES[14 : 14 + 22 * args.num_hands]
    if args.layout == "robot":
        names = ARM_NAMES + names
        poses = torch.cat([0.3 * torch.randn(len(poses), len(ARM_NAMES)), poses], dim=1)  # (P, 14 + 22*H)
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} threads, CPU, load average "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; median of {args.repeats} (batch 1) / "
        f"{args.repeats_large} (larger) calls; state layout {args.layout} ({len(names)} columns)"
    )
    print(
        f"{'preset':<7} {'batch':>5} {'states':>6} | {'step CPU ms':>11} {'CPU ms/state':>12} {'wall ms':>9} | "
        f"{'bare tok CPU ms':>15} {'step overhead CPU ms':>20}"
    )
    for preset in args.presets:
        step = UniDexTokStateTokenizerStep(hand_layout=hands, state_names=names, preset=preset)
        pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
        tok = step.tokenizer
        for batch in args.batches:
            x = poses[np.arange(batch) % len(poses)]  # (B, D)
            if batch == 1:
                x = x[0]  # one unbatched frame, as at inference
            rows = x.reshape(-1, x.shape[-1])[:, -22 * args.num_hands :].reshape(-1, 22)  # (B*H, 22) the blocks
            row_hands = hands * (rows.shape[0] // args.num_hands)

            def run_step(x=x, pipe=pipe):
                pipe({OBS_STATE: x})

            def run_bare(rows=rows, row_hands=row_hands, tok=tok):
                tok.decode(tok.encode(rows, row_hands), row_hands)

            repeats = args.repeats if batch == 1 else args.repeats_large
            with torch.inference_mode():
                step_ms, bare_ms = median_ms([run_step, run_bare], repeats)
            (step_cpu, step_wall), (bare_cpu, _) = step_ms, bare_ms
            n_states = batch * args.num_hands
            print(f"{preset:<7} {batch:>5} {n_states:>6} | {step_cpu:>11.3f} {step_cpu / n_states:>12.4f} "
                  f"{step_wall:>9.3f} | {bare_cpu:>15.3f} {step_cpu - bare_cpu:>20.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
