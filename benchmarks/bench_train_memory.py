"""Peak memory of tokenizer training against dataset size: in memory (`load_hand_states`, every frame) vs
streaming (`--streaming=true`: memory-mapped per-hand row store), at 1x and 10x the `make demo` sample.

    .venv/bin/python benchmarks/bench_train_memory.py [--scales 1,10] [--steps 100] [--eval_max_frames 2000]

1x = the demo's sample mixture (the 6 sample sources, 10 episodes x ~150 frames each: human, Inspire,
BrainCo, LinkerHand L10/L20, XHand); 10x = 100 episodes per source. The samples are written and converted
first (not measured). Each training run is `unidextok-train` in a fresh process (tiny preset, a few
steps, evaluation once). Reported: its max RSS (`wait4`; includes the pages of the memory-mapped store
it touched, which the kernel can drop and re-read) and its peak anonymous RSS (sampled from /proc: the
arrays and tensors it holds). A process that imports the same modules and builds the model, without
data, gives the fixed part (baseline); the growth from one scale to the next is what the data costs.
Both modes select checkpoints on `--eval_max_frames` held-out rows; streaming also writes its final
report on those rows, while the in-memory path loads every held-out frame and reports on all of them.
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BASELINE = """
import lerobot_unidextok.scripts.train, torch
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from accelerate import Accelerator
model = Accelerator(cpu=True).prepare(UniDexTok(UniDexTokConfig.from_preset("tiny")))
"""


def _status_kb(pid: int) -> dict[str, int]:
    """VmRSS / RssAnon / RssFile of a live process (kB), {} once it is gone."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return {}
    return {k: int(v.split()[0]) for k, v in (ln.split(":", 1) for ln in text.splitlines() if ":" in ln)
            if k in ("VmRSS", "RssAnon", "RssFile")}  # fmt: skip


def _measure(cmd: list[str]) -> tuple[float, float, float, float]:
    """(max RSS MB, peak anonymous RSS MB, CPU s, wall s) of one child process.

    Max RSS (wait4) counts file-backed pages too: a memory-mapped store's pages, which the kernel can drop
    and re-read, count there once touched. The anonymous part (heap: arrays, tensors) is what the data
    costs for good; it is sampled from /proc/<pid>/status every 10 ms (a spike shorter than that can be
    missed)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    anon = 0
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        anon = max(anon, _status_kb(proc.pid).get("RssAnon", 0))
        time.sleep(0.01)
    wall = time.perf_counter() - t0
    stderr = proc.stderr.read()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd[:4])} ... failed:\n{stderr[-3000:]}")
    return usage.ru_maxrss / 1024, anon / 1024, usage.ru_utime + usage.ru_stime, wall


def _convert_scale(tmp: Path, scale: int) -> tuple[list[str], int, float]:
    """Converted datasets of one scale: (roots, frames, parquet MB)."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, SAMPLE_SOURCES, write_samples

    raw = write_samples(tmp / f"raw{scale}", sources=list(SAMPLE_SOURCES), episodes_per_source=10 * scale,
                        frames_per_episode=150)  # fmt: skip
    roots, frames = [], 0
    for source, folder in raw.items():
        root = tmp / f"conv{scale}" / source
        frames += convert(ConvertOptions(source=source, input=folder, root=root, progress=False, num_workers=2,
                                         source_options=SAMPLE_SOURCE_OPTIONS.get(source, {}))).num_frames  # fmt: skip
        roots.append(str(root))
    size = sum(f.stat().st_size for r in roots for f in Path(r, "data").rglob("*.parquet")) / 2**20
    return roots, frames, size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scales", default="1,10", help="dataset sizes in units of the demo sample")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--eval_max_frames", type=int, default=2000, help="held-out rows for checkpoint selection")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    scales = [int(s) for s in args.scales.split(",")]

    tmp = Path(tempfile.mkdtemp(prefix="bench-train-memory-"))
    try:
        base_mb, base_anon, _, _ = _measure([sys.executable, "-c", BASELINE])
        rows = []
        for scale in scales:
            roots, frames, size = _convert_scale(tmp, scale)
            for streaming in (False, True):
                out = tmp / f"run{scale}_{streaming}"
                cmd = [sys.executable, "-m", "lerobot_unidextok.scripts.train", f"--datasets=[{','.join(roots)}]",
                       "--preset=tiny", f"--steps={args.steps}", "--batch_size=256", f"--eval_every={args.steps}",
                       f"--save_last_every={args.steps}", "--warmup_steps=10", "--progress=false",
                       f"--streaming={str(streaming).lower()}", f"--eval_max_frames={args.eval_max_frames}",
                       f"--output_dir={out}"]  # fmt: skip
                load = os.getloadavg()[0]
                peak, anon, cpu, wall = _measure(cmd)
                mode = "streaming" if streaming else "in memory"
                rows.append((scale, frames, size, mode, peak, anon, cpu, wall, load))
                shutil.rmtree(out, ignore_errors=True)

        print(f"\nbaseline (imports + tiny model, no data): {base_mb:,.0f} MB max RSS, {base_anon:,.0f} MB anonymous; "
              f"{args.steps} steps, batch 256")  # fmt: skip
        print(f"{'scale':>5s} {'frames':>9s} {'parquet MB':>10s} {'mode':10s} {'max RSS MB':>10s} {'anon. MB':>9s} "
              f"{'CPU s':>6s} {'wall s':>6s} {'load':>5s}")  # fmt: skip
        for scale, frames, size, mode, peak, anon, cpu, wall, load in rows:
            print(f"{scale:>4d}x {frames:9,d} {size:10.1f} {mode:10s} {peak:10,.0f} {anon:9,.0f} {cpu:6.1f} {wall:6.1f} "
                  f"{load:5.1f}")  # fmt: skip
        by = {(r[0], r[3]): (r[4], r[5]) for r in rows}
        for scale in scales:
            (m_rss, m_anon), (s_rss, s_anon) = by[(scale, "in memory")], by[(scale, "streaming")]
            print(f"{scale}x: above the baseline, streaming {s_rss - base_mb:,.0f} MB max RSS / {s_anon - base_anon:,.0f}"
                  f" MB anonymous; in memory {m_rss - base_mb:,.0f} / {m_anon - base_anon:,.0f} MB")  # fmt: skip
        for a, b in zip(scales, scales[1:], strict=False):
            for mode in ("in memory", "streaming"):
                (ra, aa), (rb, ab) = by[(a, mode)], by[(b, mode)]
                print(f"{mode}: {a}x -> {b}x data: {rb - ra:+,.0f} MB max RSS, {ab - aa:+,.0f} MB anonymous")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
