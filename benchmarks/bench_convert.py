"""Conversion speed: end-to-end frames/s for a robot and a human source, and LeRobot's own
per-frame writer on the same UDHM episodes, measured in the same run (one process, one core).
CPU time (time.process_time) is the primary clock on shared cores; wall time is printed too.

    .venv/bin/python benchmarks/bench_convert.py [--episodes 30] [--frames 1000] [--human_frames 300]

Input: synthetic samples in the sources' native formats (written to a temp dir first, not timed).
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
    """Seconds for LeRobot 0.6's add_frame/save_episode/finalize on the same episodes."""
    from lerobot.datasets import LeRobotDataset

    t0 = time.process_time()
    ds = LeRobotDataset.create(
        "bench/lerobot",
        fps=30,
        features=features,
        root=root,
        robot_type="udhm",
        use_videos=False,
    )
    for ep in episodes:
        for t in range(ep.num_frames):
            frame = {
                "observation.state": ep.state_rad[t],
                "hand_type": ep.hand_type,
                "udhm_mask": ep.mask[t],
                "task": ep.task,
            }
            if ep.action_rad is not None:
                frame["action"] = ep.action_rad[t]
            ds.add_frame(frame)
        ds.save_episode()
    ds.finalize()
    return time.process_time() - t0


def _writer_only(episodes, features, root: Path) -> float:
    from lerobot_unidextok.conversion.pipeline import _episode_frames
    from lerobot_unidextok.conversion.writer import UdhmDatasetWriter

    t0 = time.process_time()
    w = UdhmDatasetWriter(root, "bench/fast", 30, features, robot_type="udhm")
    for ep in episodes:
        w.add_episode(_episode_frames(ep), task=ep.task)
    w.finalize()
    return time.process_time() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30, help="robot episodes")
    parser.add_argument("--frames", type=int, default=1000, help="frames per robot episode")
    parser.add_argument("--human_episodes", type=int, default=4)
    parser.add_argument("--human_frames", type=int, default=300)
    parser.add_argument(
        "--lerobot_episodes",
        type=int,
        default=5,
        help="episodes given to LeRobot's per-frame writer",
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from lerobot_unidextok.conversion.mapping import map_episode
    from lerobot_unidextok.conversion.pipeline import (
        ConvertOptions,
        convert,
        udhm_features,
    )
    from lerobot_unidextok.conversion.registry import get_source
    from lerobot_unidextok.conversion.samples import write_samples

    tmp = Path(tempfile.mkdtemp(prefix="bench-convert-"))
    try:
        raw = write_samples(
            tmp / "raw",
            sources=["linkerhand"],
            episodes_per_source=args.episodes,
            frames_per_episode=args.frames,
        )
        raw |= write_samples(
            tmp / "raw_h",
            sources=["dexycb"],
            episodes_per_source=args.human_episodes,
            frames_per_episode=args.human_frames,
        )
        rows = []
        for source in ("linkerhand", "dexycb"):
            t0, w0 = time.process_time(), time.perf_counter()
            rep = convert(
                ConvertOptions(
                    source=source,
                    input=raw[source],
                    root=tmp / f"out_{source}",
                    progress=False,
                )
            )
            sec, wall = time.process_time() - t0, time.perf_counter() - w0
            rows.append(
                (
                    f"convert {source} end to end (wall {rep.num_frames / wall:,.0f}/s)",
                    rep.num_episodes,
                    rep.num_frames,
                    sec,
                )
            )

        # same UDHM episodes through our writer alone and through LeRobot's per-frame writer
        reader = get_source("linkerhand")()
        refs = reader.list_episodes(raw["linkerhand"])
        episodes = [map_episode(reader.read_episode(r)) for r in refs]
        by_layout = [e for e in episodes if e.layout == episodes[0].layout]
        features = udhm_features(by_layout[0].sides, by_layout[0].action_rad is not None)
        sec = _writer_only(by_layout, features, tmp / "writer_only")
        rows.append(
            (
                "UdhmDatasetWriter only (same episodes)",
                len(by_layout),
                sum(e.num_frames for e in by_layout),
                sec,
            )
        )
        subset = by_layout[: args.lerobot_episodes]
        sec = _lerobot_per_frame(subset, features, tmp / "lerobot_per_frame")
        rows.append(
            (
                "LeRobot 0.6.1 add_frame/save_episode",
                len(subset),
                sum(e.num_frames for e in subset),
                sec,
            )
        )

        print(f"\n{'what':52s} {'episodes':>8s} {'frames':>8s} {'CPU s':>8s} {'frames/CPU-s':>12s}")
        for name, eps, frames, sec in rows:
            print(f"{name:52s} {eps:8d} {frames:8d} {sec:8.2f} {frames / sec:12,.0f}")
        ref = rows[3][2] / rows[3][3]
        print(
            f"\nspeed-up vs LeRobot per-frame writer: end to end robot {rows[0][2] / rows[0][3] / ref:.1f}x, "
            f"writer only {rows[2][2] / rows[2][3] / ref:.1f}x; state dim {features['observation.state']['shape'][0]} "
            f"+ action + mask; human source is bounded by the UDHM IK"
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
