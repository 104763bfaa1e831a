"""Latency of the UniDexTok processor step (CPU), batch 1 and batch 256, small and paper presets.

Measured in the same run against a reference: the bare tokenizer `encode` + `decode` on the same
rows, so the figure for the step = tokenizer cost + LeRobot pipeline/step overhead (block gather by
name, range guard, reshapes). Inputs are synthetic G1-like frames from tests/fixtures/robot_udhm.py
(two Inspire hands in UDHM; `--layout robot` adds the 14 arm joints in front: a 58-wide whole-robot
state), tiled to the batch size. Weights are untrained (latency does not depend on them).
Target: <= 1 ms per single state (one hand), small preset.

`--native` also times `unidextok.native_to_udhm` (the robot's native state -> the converted layout: arm
columns copied, 6 Inspire values per hand through the hand spec into its UDHM block) on the same frames in
their native form: the step alone in a pipeline, and native state -> tokens (both steps) against the
tokenizer step on the converted state.

    .venv/bin/python benchmarks/bench_processor.py
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --repeats_large 3
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --num_hands 1 --presets small --batches 1
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --layout robot --presets small --batches 1
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --layout robot --presets small --native
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --presets small --search_rounds 2   # code search
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
from lerobot_unidextok.processor import NativeLayout, NativeToUDHMStateStep, UniDexTokStateTokenizerStep

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "fixtures"))
from robot_udhm import ARM_NAMES, INSPIRE, STATE_NAMES, native_motion, to_converted


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
    parser.add_argument("--native", action="store_true", help="also time unidextok.native_to_udhm (native input)")
    parser.add_argument("--search_rounds", type=int, default=0, help="code search rounds of the step (0 = nearest)")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    hands = [INSPIRE] * args.num_hands
    names = STATE_NAMES[14 : 14 + 22 * args.num_hands]
    g1 = native_motion(64, seed=0).astype(np.float32)  # (P, 26): 14 arm rad, left and right Inspire in [0, 1]
    start = 0 if args.layout == "robot" else 14  # robot: the 14 arm joints first
    native = torch.from_numpy(g1[:, start : 14 + 6 * args.num_hands])  # (P, [14 +] 6*H)
    poses = torch.from_numpy(to_converted(g1)[:, start : 14 + 22 * args.num_hands]).float()  # (P, [14 +] 22*H) rad
    if args.layout == "robot":
        names = ARM_NAMES + names
    native_layout = NativeLayout.from_hands(hands, ["left", "right"][: args.num_hands], names)
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} threads, CPU, load average "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; median of {args.repeats} (batch 1) / "
        f"{args.repeats_large} (larger) calls; state layout {args.layout} ({len(names)} columns); code search "
        f"rounds {args.search_rounds}"
    )
    print(
        f"{'preset':<7} {'batch':>5} {'states':>6} | {'step CPU ms':>11} {'CPU ms/state':>12} {'wall ms':>9} | "
        f"{'bare tok CPU ms':>15} {'step overhead CPU ms':>20}"
    )
    native_rows = []
    for preset in args.presets:
        step = UniDexTokStateTokenizerStep(hand_layout=hands, state_names=names, preset=preset,
                                           search_rounds=args.search_rounds)
        pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
        to_udhm = NativeToUDHMStateStep.from_layout(native_layout)
        native_pipe = PolicyProcessorPipeline(steps=[to_udhm], name="policy_preprocessor")
        native_tok_pipe = PolicyProcessorPipeline(steps=[to_udhm, step], name="policy_preprocessor")
        tok = step.tokenizer
        for batch in args.batches:
            x = poses[np.arange(batch) % len(poses)]  # (B, D)
            xn = native[np.arange(batch) % len(native)]  # (B, D_native) the same frames, native
            if batch == 1:
                x, xn = x[0], xn[0]  # one unbatched frame, as at inference
            rows = x.reshape(-1, x.shape[-1])[:, -22 * args.num_hands :].reshape(-1, 22)  # (B*H, 22) the blocks
            row_hands = hands * (rows.shape[0] // args.num_hands)

            def run_step(x=x, pipe=pipe):
                pipe({OBS_STATE: x})

            def run_bare(rows=rows, row_hands=row_hands, tok=tok):
                tok.decode(tok.encode(rows, row_hands, search_rounds=args.search_rounds), row_hands)

            def run_native(xn=xn, native_pipe=native_pipe):
                native_pipe({OBS_STATE: xn})

            def run_native_tok(xn=xn, native_tok_pipe=native_tok_pipe):
                native_tok_pipe({OBS_STATE: xn})

            repeats = args.repeats if batch == 1 else args.repeats_large
            fns = [run_step, run_bare] + ([run_native, run_native_tok] if args.native else [])
            with torch.inference_mode():
                timed = median_ms(fns, repeats)
            (step_cpu, step_wall), (bare_cpu, _) = timed[:2]
            n_states = batch * args.num_hands
            print(f"{preset:<7} {batch:>5} {n_states:>6} | {step_cpu:>11.3f} {step_cpu / n_states:>12.4f} "
                  f"{step_wall:>9.3f} | {bare_cpu:>15.3f} {step_cpu - bare_cpu:>20.3f}")  # fmt: skip
            if args.native:
                (native_cpu, native_wall), (both_cpu, _) = timed[2:]
                native_rows.append((preset, batch, native_cpu, native_wall, both_cpu, both_cpu - step_cpu))
    if native_rows:
        print(f"\nunidextok.native_to_udhm, native state ({native_layout.native_dim} columns) -> converted "
              f"({native_layout.converted_dim})")  # fmt: skip
        print(f"{'preset':<7} {'batch':>5} | {'native step CPU ms':>18} {'CPU ms/frame':>12} {'wall ms':>9} | "
              f"{'native -> tokens CPU ms':>23} {'vs converted -> tokens':>22}")  # fmt: skip
        for preset, batch, native_cpu, native_wall, both_cpu, extra in native_rows:
            print(f"{preset:<7} {batch:>5} | {native_cpu:>18.3f} {native_cpu / batch:>12.4f} {native_wall:>9.3f} | "
                  f"{both_cpu:>23.3f} {extra:>+22.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
