"""Tokenizer training throughput, 1 process vs 2 processes (`accelerate launch`, gloo on CPU), same data.

    .venv/bin/python benchmarks/bench_train_scale.py [--preset small] [--steps 300] [--batch_size 256]

Data: the robot sources of the `make demo` sample (lerobot G1 + Inspire, LinkerHand L10/L20, Dexora
XHand; 10 episodes x ~150 frames each), written and converted first (not measured). Each run is
`unidextok-train` in fresh processes (one thread per process, evaluation only at the end):

- 1 process, `batch_size` rows per step (the reference);
- 2 processes, `batch_size` rows each: effective batch 2 x batch_size per step;
- 2 processes, `batch_size / 2` rows each: the reference's effective batch.

Steps/s and rows/s come from the training loop's own clock (`eval.json` -> training.seconds: model
steps, gradient all-reduce, the final evaluation; not imports or data loading); CPU is the whole run's
(launcher and workers, from `wait4`). On shared cores a second process only helps if a core is free: the
load average is printed next to each run.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _run(cmd: list[str], env: dict) -> tuple[float, float]:
    """(CPU s of the process tree, wall s)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"failed: {' '.join(cmd[:6])} ...\n{proc.stderr.read()[-3000:]}")
    return usage.ru_utime + usage.ru_stime, wall


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="small")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--batch_size", type=int, default=256)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

    tmp = Path(tempfile.mkdtemp(prefix="bench-train-scale-"))
    try:
        sources = ["lerobot", "linkerhand", "dexora"]
        raw = write_samples(tmp / "raw", sources=sources, episodes_per_source=10, frames_per_episode=150)
        roots = []
        for source in sources:
            roots.append(str(tmp / "conv" / source))
            convert(ConvertOptions(source=source, input=raw[source], root=roots[-1], progress=False,
                                   source_options=SAMPLE_SOURCE_OPTIONS.get(source, {})))  # fmt: skip
        bin_dir = Path(sys.executable).parent
        env = dict(os.environ, OMP_NUM_THREADS="1", CUDA_VISIBLE_DEVICES="")
        runs = [
            ("1 process", 1, args.batch_size),
            ("2 processes, same batch per process", 2, args.batch_size),
            ("2 processes, same effective batch", 2, args.batch_size // 2),
        ]
        rows = []
        for name, procs, batch in runs:
            out = tmp / f"run{procs}_{batch}"
            flags = [f"--datasets=[{','.join(roots)}]", f"--preset={args.preset}", f"--steps={args.steps}",
                     f"--batch_size={batch}", f"--eval_every={args.steps}", f"--save_last_every={args.steps}",
                     "--device=cpu", "--progress=false", f"--output_dir={out}"]  # fmt: skip
            if procs == 1:
                cmd = [sys.executable, "-m", "lerobot_unidextok.scripts.train", *flags]
            else:
                cmd = [str(bin_dir / "accelerate"), "launch", "--multi_gpu", f"--num_processes={procs}",
                       "--num_machines=1", "--mixed_precision=no", "--dynamo_backend=no",
                       f"--main_process_port={_free_port()}", "-m", "lerobot_unidextok.scripts.train", *flags]  # fmt: skip
            load = os.getloadavg()[0]
            cpu, wall = _run(cmd, env)
            seconds = json.loads((out / "eval.json").read_text())["training"]["seconds"]
            rows.append((name, procs, batch, seconds, cpu, wall, load))

        print(f"\n{args.preset} preset, {args.steps} steps, data: {', '.join(sources)} samples")
        print(f"{'run':38s} {'batch/proc':>10s} {'eff. batch':>10s} {'loop s':>7s} {'steps/s':>7s} {'rows/s':>7s} "
              f"{'CPU s':>6s} {'wall s':>6s} {'load':>5s}")  # fmt: skip
        ref_steps = args.steps / rows[0][3]
        for name, procs, batch, seconds, cpu, wall, load in rows:
            sps = args.steps / seconds
            print(f"{name:38s} {batch:10d} {batch * procs:10d} {seconds:7.1f} {sps:7.2f} {sps * batch * procs:7,.0f} "
                  f"{cpu:6.1f} {wall:6.1f} {load:5.1f}")  # fmt: skip
        for name, procs, batch, seconds, *_ in rows[1:]:
            sps = args.steps / seconds
            print(f"{name}: {sps / ref_steps:.2f}x the steps/s, {sps * batch * procs / (ref_steps * args.batch_size):.2f}x "
                  "the rows/s of 1 process")  # fmt: skip
        print(f"cores: {os.cpu_count()}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
