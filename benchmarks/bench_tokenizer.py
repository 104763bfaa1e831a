"""UniDexTok speed on CPU: encode+decode states/s per preset at batch 1 and 1024, training samples/s.

Reference in the same run: uniform binning (baselines/binning.py, 256 bins, no network) encode+decode
on the same states, so figures can be compared across machines and loads. CPU time is the primary
clock (the machine is shared); wall time is printed too.

    .venv/bin/python benchmarks/bench_tokenizer.py [--presets tiny small paper] [--seconds 3]
"""

import argparse
import functools
import time

import numpy as np
import torch

from lerobot_unidextok.baselines.binning import HandRange, UniformBinning
from lerobot_unidextok.samples.motion import gesture_track
from lerobot_unidextok.tokenizer import PRESETS, UniDexTok, UniDexTokConfig, count_parameters
from lerobot_unidextok.training.optim import make_optimizer


def _timed(fn, min_seconds: float, min_iters: int = 3) -> tuple[float, float, int]:
    """Run fn until min_seconds of CPU time; returns (cpu s, wall s, iterations)."""
    fn()  # warm-up
    c0, w0, n = time.process_time(), time.perf_counter(), 0
    while n < min_iters or time.process_time() - c0 < min_seconds:
        fn()
        n += 1
    return time.process_time() - c0, time.perf_counter() - w0, n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--seconds", type=float, default=3.0, help="CPU seconds per measurement")
    ap.add_argument("--train_batch", type=int, default=256)
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads (1 = the training default)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    states = torch.as_tensor(gesture_track(np.random.default_rng(0), 2048, 30.0).angles_rad, dtype=torch.float32)

    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}")
    print(
        "| tokenizer | params | batch | encode+decode states / CPU-s | states / wall-s | train samples / CPU-s (batch) |"
    )
    print("|---|---|---|---|---|---|")

    binning = UniformBinning({"human": HandRange(np.full(22, -np.pi / 2), np.full(22, np.pi / 2), np.ones(22, bool))})
    for b in (1, 1024):
        x = states[:b]
        cpu, wall, n = _timed(lambda x=x: binning.decode(binning.encode(x, "human"), "human"), args.seconds)
        print(f"| uniform binning (reference) | 0 | {b} | {n * b / cpu:,.0f} | {n * b / wall:,.0f} | - |")

    for name in args.presets:
        model = UniDexTok(UniDexTokConfig.from_preset(name)).eval()
        params = count_parameters(model)
        for b in (1, 1024):
            x = states[:b]
            cpu, wall, n = _timed(lambda x=x, m=model: m.decode(m.encode(x, "human"), "human"), args.seconds)
            train_cell = "" if b == 1 else "see next row"
            print(f"| {name} | {params:,} | {b} | {n * b / cpu:,.0f} | {n * b / wall:,.0f} | {train_cell} |")
        model.train()
        opt = make_optimizer(model, 1e-3, 0.01, (0.9, 0.99))
        xb = states[: args.train_batch]
        mask = torch.ones_like(xb, dtype=torch.bool)
        cpu, wall, n = _timed(functools.partial(_train_step, model, opt, xb, mask), args.seconds)
        print(f"| {name} (train step) | {params:,} | {args.train_batch} | - | - | "
              f"{n * args.train_batch / cpu:,.0f} ({n * args.train_batch / wall:,.0f} / wall-s) |")  # fmt: skip


def _train_step(model: UniDexTok, opt: torch.optim.Optimizer, xb: torch.Tensor, mask: torch.Tensor) -> None:
    out = model(xb, "human", mask=mask)
    opt.zero_grad(set_to_none=True)
    out.loss.backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
    opt.step()


if __name__ == "__main__":
    main()
