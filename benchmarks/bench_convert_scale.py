"""Conversion past one process: the process pool (1 vs 2 reader workers) against datatrove's local executor
(shards as tasks, 1 vs 2 at a time, then the merge) on the same input, measured in the same run.

    .venv/bin/python benchmarks/bench_convert_scale.py [--source dexycb] [--episodes 16] [--frames 3000]

Each configuration converts the same synthetic sample (written first, not timed) into a new folder; the
results are checked to hold the same frames as the reference (pool, 1 worker). The datatrove runs
include what they add: one process per task, each shard's validation (`load=False`) and the merge
(LeRobot's `aggregate_datasets`); tasks run `--num_workers=1` each. Wall time and CPU time of
this process plus every worker process (forkservers stopped and reaped after each run so their workers'
CPU is counted) are printed with ratios against the reference. On shared cores wall-time speed-ups are
bounded by what the other jobs leave free: the load average is printed next to the figures.
"""

from __future__ import annotations

import argparse
import logging
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _cpu_seconds() -> float:
    """User + system CPU of this process and every child reaped so far."""
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        ru = resource.getrusage(who)
        total += ru.ru_utime + ru.ru_stime
    return total


def _reap_forkservers() -> None:
    """Stop the forkservers (multiprocessing's for the pool, multiprocess's for datatrove) so that their
    workers' CPU time reaches RUSAGE_CHILDREN; they restart on the next run."""
    import multiprocessing.forkserver as mp_fs

    mp_fs._forkserver._stop()
    try:
        import multiprocess.forkserver as mpx_fs

        mpx_fs._forkserver._stop()
    except ImportError:
        pass


def _frames(root: Path) -> np.ndarray:
    import pyarrow.parquet as pq

    table = pq.read_table(sorted((root / "data").rglob("*.parquet")), columns=["observation.state"])
    col = table.column("observation.state").combine_chunks()
    return np.asarray(col.flatten().to_numpy()).reshape(len(col), -1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", default="dexycb", help="sample source (dexycb: IK-bound, linkerhand: ROS 2 bags)")
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--frames", type=int, default=3000, help="frames per episode (+-20 %)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    logging.getLogger("datatrove").setLevel(logging.WARNING)
    from loguru import logger as loguru_logger  # datatrove's own logging: keep the bench output readable

    loguru_logger.remove()

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.conversion.sharded import ExecutorOptions, convert_with_executor
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

    tmp = Path(tempfile.mkdtemp(prefix="bench-convert-scale-"))
    try:
        raw = write_samples(tmp / "raw", sources=[args.source], episodes_per_source=args.episodes,
                            frames_per_episode=args.frames)[args.source]  # fmt: skip
        options = dict(source=args.source, input=raw, source_options=SAMPLE_SOURCE_OPTIONS.get(args.source, {}),
                       progress=False)  # fmt: skip
        runs = [
            ("process pool, 1 worker (reference)", dict(num_workers=1), None),
            ("process pool, 2 workers", dict(num_workers=2), None),
            ("datatrove local, 2 tasks, 1 at a time", {}, ExecutorOptions("local", tasks=2, workers=1)),
            ("datatrove local, 2 tasks, 2 at a time", {}, ExecutorOptions("local", tasks=2, workers=2)),
            ("datatrove local, 4 tasks, 2 at a time", {}, ExecutorOptions("local", tasks=4, workers=2)),
        ]
        rows, reference = [], None
        for i, (name, extra, executor) in enumerate(runs):
            root = tmp / f"out{i}"
            opts = ConvertOptions(root=root, **options, **extra)
            load = os.getloadavg()[0]
            c0, w0 = _cpu_seconds(), time.perf_counter()
            if executor is None:
                convert(opts)
            else:
                convert_with_executor(opts, executor)
            wall = time.perf_counter() - w0
            _reap_forkservers()
            cpu = _cpu_seconds() - c0
            frames = _frames(root)
            if reference is None:
                reference = frames
            elif not np.array_equal(frames, reference):
                raise SystemExit(f"{name}: the converted frames differ from the reference")
            rows.append((name, len(frames), wall, cpu, load))

        print(f"\n{args.source}: {args.episodes} episodes, {rows[0][1]:,} frames, same frames in every run")
        print(f"{'configuration':40s} {'wall s':>7s} {'CPU s':>7s} {'frames/s':>9s} {'speed-up':>8s} {'CPU ratio':>9s} "
              f"{'load':>5s}")  # fmt: skip
        _, _, ref_wall, ref_cpu, _ = rows[0]
        for name, n, wall, cpu, load in rows:
            print(f"{name:40s} {wall:7.1f} {cpu:7.1f} {n / wall:9,.0f} {ref_wall / wall:7.2f}x {cpu / ref_cpu:8.2f}x "
                  f"{load:5.1f}")  # fmt: skip
        print(f"cores: {os.cpu_count()}; speed-up = reference wall / wall; CPU ratio = CPU / reference CPU "
              "(process start-up, imports and the merge are the cost of going parallel)")  # fmt: skip
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
