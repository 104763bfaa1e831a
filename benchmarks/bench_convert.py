"""Conversion speed: end-to-end frames/s per source, and LeRobot's own per-frame writer on the same mapped
episodes, measured in the same run (one process, one core). CPU time (time.process_time) is the primary
clock on shared cores; wall time is printed too.

    .venv/bin/python benchmarks/bench_convert.py [--episodes 30] [--frames 1000] [--human_frames 300]

Sources timed end to end (list, read the native files, map to UDHM, write LeRobotDataset v3.0, card):
- `lerobot`: a LeRobot v2.1 dataset shaped like Unitree G1 + two Inspire hands, converted whole-robot
  (14 arm passthrough columns + 2 x 22 UDHM, state and action, 44-bool mask): the robot write path;
- `linkerhand`: ROS 2 bags (sqlite3 / MCAP) of the SDK topics, resampled onto 30 fps: bounded by
  decoding the messages in pure Python (rosbags);
- `dexycb`: MANO-21 keypoints through the UDHM IK: bounded by the IK.
Then the mapped `lerobot` episodes through `UdhmDatasetWriter` alone and through LeRobot 0.6.1's own
`add_frame`/`save_episode`/`finalize` (the reference). Input: synthetic samples written first, not timed.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _lerobot_per_frame(episodes, features, root: Path) -> float:
    """CPU seconds of LeRobot 0.6's add_frame/save_episode/finalize on the same episodes and features."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.features import episode_frames

    t0 = time.process_time()
    ds = LeRobotDataset.create(
        "bench/lerobot", fps=30, features=features, root=root, robot_type="udhm", use_videos=False
    )
    for ep in episodes:
        arrays = episode_frames(ep)
        for t in range(ep.num_frames):
            frame = {k: (v if isinstance(v, str) else v[t]) for k, v in arrays.items()}
            frame["task"] = ep.task
            ds.add_frame(frame)
        ds.save_episode()
    ds.finalize()
    return time.process_time() - t0


def _writer_only(episodes, features, root: Path) -> float:
    from lerobot_unidextok.conversion.features import episode_frames
    from lerobot_unidextok.conversion.writer import UdhmDatasetWriter

    t0 = time.process_time()
    w = UdhmDatasetWriter(root, "bench/fast", 30, features, robot_type="udhm")
    for ep in episodes:
        w.add_episode(episode_frames(ep), task=ep.task)
    w.finalize()
    return time.process_time() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30, help="robot episodes (lerobot and linkerhand sources)")
    parser.add_argument("--frames", type=int, default=1000, help="frames per robot episode")
    parser.add_argument("--human_episodes", type=int, default=4)
    parser.add_argument("--human_frames", type=int, default=300)
    parser.add_argument("--lerobot_episodes", type=int, default=5, help="episodes given to LeRobot's per-frame writer")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from lerobot_unidextok.conversion.features import episode_features
    from lerobot_unidextok.conversion.mapping import map_episode
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.conversion.registry import make_reader
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

    tmp = Path(tempfile.mkdtemp(prefix="bench-convert-"))
    try:
        raw = write_samples(tmp / "raw", sources=["lerobot", "linkerhand"], episodes_per_source=args.episodes,
                            frames_per_episode=args.frames)  # fmt: skip
        raw |= write_samples(tmp / "raw_h", sources=["dexycb"], episodes_per_source=args.human_episodes,
                             frames_per_episode=args.human_frames)  # fmt: skip
        rows = []
        for source in ("lerobot", "linkerhand", "dexycb"):
            t0, w0 = time.process_time(), time.perf_counter()
            rep = convert(ConvertOptions(source=source, input=raw[source], root=tmp / f"out_{source}",
                                         source_options=SAMPLE_SOURCE_OPTIONS.get(source, {}), progress=False))  # fmt: skip
            sec, wall = time.process_time() - t0, time.perf_counter() - w0
            rows.append((f"convert {source} end to end (wall {rep.num_frames / wall:,.0f}/s)", rep.num_episodes,
                         rep.num_frames, sec))  # fmt: skip

        # the same mapped whole-robot episodes through our writer alone and through LeRobot's per-frame writer
        reader = make_reader("lerobot", SAMPLE_SOURCE_OPTIONS["lerobot"])
        episodes = [map_episode(reader.read_episode(r)) for r in reader.list_episodes(raw["lerobot"])]
        features = episode_features(episodes[0])
        sec = _writer_only(episodes, features, tmp / "writer_only")
        rows.append(("UdhmDatasetWriter only (same lerobot episodes)", len(episodes),
                     sum(e.num_frames for e in episodes), sec))  # fmt: skip
        subset = episodes[: args.lerobot_episodes]
        sec = _lerobot_per_frame(subset, features, tmp / "lerobot_per_frame")
        rows.append(("LeRobot 0.6.1 add_frame/save_episode", len(subset), sum(e.num_frames for e in subset), sec))

        print(f"\n{'what':58s} {'episodes':>8s} {'frames':>8s} {'CPU s':>8s} {'frames/CPU-s':>12s}")
        for name, eps, frames, sec in rows:
            print(f"{name:58s} {eps:8d} {frames:8d} {sec:8.2f} {frames / sec:12,.0f}")
        ref = rows[-1][2] / rows[-1][3]
        ratio = lambda i: rows[i][2] / rows[i][3] / ref
        print(
            f"\nspeed-up vs LeRobot's per-frame writer (frames/CPU-s): lerobot source end to end {ratio(0):.1f}x, "
            f"linkerhand bags end to end {ratio(1):.1f}x, dexycb (IK) {ratio(2):.2f}x, writer only {ratio(3):.1f}x; "
            f"state/action {features['observation.state']['shape'][0]} floats (14 arm + 44 UDHM) + 44-bool mask"
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
