"""`make demo`: the whole pipeline on built-in synthetic sample data, printed as tables.

1. UDHM: sample human hands (FK of named gestures) -> keypoints -> IK -> keypoints, and real MediaPipe
   hands when ../shared/data/real is present.
2. Hand registry: each hand's native joints and the UDHM slots they fill.
3. Conversion: every sample source (native file formats) -> UDHM LeRobotDataset v3.
4. UniDexTok: train the `small` preset on the converted mixture (a short schedule on the recorded rows),
   evaluate per hand on the test episodes.
5. Pictures: 3D ground truth vs reconstruction, per-joint errors, codebook usage.
6. LeRobot: the processor step on converted frames (tokens next to decoded states), and the tokenizer
   saved into the local hub cache and loaded back by repo id, offline.

Run `python -m lerobot_unidextok.demo --help` for options (`--quick`: less data, 300 steps). The full demo
takes ~3 CPU-minutes (docs/tokenizer.md, "Demo").
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import argparse
import logging
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.shared_data import real_data_dir

DEFAULT_OUT = Path("outputs/demo")
# Training schedule of the full demo: short enough for a first command, on the recordings only (no coverage
# sampling; `unidextok-train` keeps it on by default). How it compares with longer schedules and with coverage
# sampling, in accuracy and CPU time: docs/tokenizer.md, "Demo".
DEMO_STEPS = 2500
DEMO_BATCH_SIZE = 128
DEMO_LR = 1e-2
DEMO_SOURCES = {"recorded": 1.0}  # coverage sources of every hand kind: the recorded rows only


def _banner(title: str) -> None:
    print(f"\n{'=' * 100}\n{title}\n{'=' * 100}", flush=True)


def _table(header: list[str], rows: list[list[object]]) -> str:
    cells = [header, *[[str(c) for c in r] for r in rows]]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    fmt = lambda r: "  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths, strict=True)))  # noqa: E731
    return "\n".join([fmt(cells[0]), fmt(["-" * w for w in widths]), *map(fmt, cells[1:])])


# ---------------------------------------------------------------------------------------------
# 1. UDHM kinematics
# ---------------------------------------------------------------------------------------------
def demo_udhm(seed: int) -> None:
    from lerobot_unidextok import udhm
    from lerobot_unidextok.samples.motion import GESTURES, gesture_track

    _banner("1. UDHM: 21 keypoints -> inverse kinematics (22 angles) -> forward kinematics -> 21 keypoints")
    rng = np.random.default_rng(seed)
    rows = []
    track = gesture_track(rng, num_frames=600, fps=30)  # synthetic gesture motion, (600, 22) rad
    skeleton = udhm.Skeleton.default().scaled(1.05)
    for side in ("right", "left"):
        keypoints_m = udhm.forward_kinematics(track.angles_rad, skeleton, side=side)
        t0 = time.perf_counter()
        res = udhm.inverse_kinematics(keypoints_m, side=side)
        dt = time.perf_counter() - t0
        err_mm = 1000 * np.linalg.norm(res.keypoints_m() - keypoints_m, axis=-1).mean()
        ang_err_deg = np.degrees(np.abs(res.angles_rad - track.angles_rad)).mean()
        rows.append([f"synthetic gestures ({side})", len(keypoints_m), f"{err_mm:.4f}", f"{ang_err_deg:.4f}",
                     f"{len(keypoints_m) / dt:,.0f}"])  # fmt: skip
    clip = real_data_dir() / "dex-retargeting" / "human_joint_right.npy"
    if clip.is_file():
        keypoints_m = np.load(clip)  # (621, 21, 3) real MediaPipe right hand, metres
        t0 = time.perf_counter()
        res = udhm.inverse_kinematics(keypoints_m, side="right")
        dt = time.perf_counter() - t0
        err_mm = 1000 * np.linalg.norm(res.keypoints_m() - keypoints_m, axis=-1).mean()
        rows.append(["real MediaPipe clip (right)", len(keypoints_m), f"{err_mm:.3f}", "n/a (no ground truth)",
                     f"{len(keypoints_m) / dt:,.0f}"])  # fmt: skip
    else:
        rows.append(["real MediaPipe clip", "-", "skipped: ../shared/data/real not found", "", ""])
    print(_table(["hands", "frames", "keypoint error (mm)", "angle error (deg)", "IK frames/s"], rows))
    names = ", ".join(GESTURES)
    print(f"\nGestures in the synthetic motion: {names}")


# ---------------------------------------------------------------------------------------------
# 2. hand registry
# ---------------------------------------------------------------------------------------------
def demo_hands() -> None:
    from lerobot_unidextok import hands

    _banner("2. Hand registry: native joints -> UDHM slots (semantic insertion)")
    print(hands.describe())


# ---------------------------------------------------------------------------------------------
# 3. conversion
# ---------------------------------------------------------------------------------------------
def demo_convert(out: Path, episodes: int, frames: int, seed: int) -> dict[str, Path]:
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, available_sample_sources, write_samples

    _banner("3. Converters: synthetic sample data in each source's native format -> UDHM LeRobotDataset v3")
    sources, skipped = available_sample_sources()
    for note in skipped:
        print(note)
    raw = write_samples(out / "raw", sources, episodes_per_source=episodes, frames_per_episode=frames, seed=seed,
                        overwrite=True)  # fmt: skip
    roots, rows = {}, []
    for source, folder in raw.items():
        root = out / "converted" / source
        report = convert(ConvertOptions(source=source, input=folder, root=root, repo_id=f"demo/{source}_udhm",
                                        source_options=SAMPLE_SOURCE_OPTIONS.get(source, {}), overwrite=True,
                                        progress=False))  # fmt: skip
        roots[source] = report.root
        rows.append([source, report.num_episodes, f"{report.num_train}/{report.num_test}", report.num_frames,
                     ",".join(report.hands), f"{report.seconds:.2f}", f"{report.frames_per_second:,.0f}"])  # fmt: skip
    print(_table(["source", "episodes", "train/test", "frames", "hands", "seconds", "frames/s"], rows))
    print(f"\nRaw samples (SYNTHETIC) in {out / 'raw'}; converted datasets in {out / 'converted'}")
    return roots


# ---------------------------------------------------------------------------------------------
# 4. tokenizer training + evaluation
# ---------------------------------------------------------------------------------------------
def demo_train(out: Path, roots: dict[str, Path], preset: str, steps: int, seed: int,
               batch_size: int = DEMO_BATCH_SIZE):  # fmt: skip
    from lerobot_unidextok.evaluation import evaluate_tokenizer, write_report
    from lerobot_unidextok.evaluation.report import describe_scored
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import TrainConfig, load_hand_states, train_tokenizer
    from lerobot_unidextok.training.coverage import CoverageConfig
    from lerobot_unidextok.training.splits import split_by_episode

    _banner(f"4. UniDexTok: train the `{preset}` preset on the converted mixture ({steps} steps, batch {batch_size}, "
            "recorded rows only), evaluate on held-out episodes")  # fmt: skip
    datasets = [str(r) for r in roots.values()]
    coverage = CoverageConfig(robot=dict(DEMO_SOURCES), human=dict(DEMO_SOURCES))
    cfg = TrainConfig(datasets=datasets, preset=preset, steps=steps, batch_size=batch_size, lr=DEMO_LR,
                      coverage=coverage, seed=seed, output_dir=str(out / "training"), eval_every=max(50, steps // 8),
                      save_last_every=steps)  # fmt: skip
    # as unidextok-train: whole training episodes choose the checkpoint, the test episodes are only scored
    train_data, select_data = split_by_episode(load_hand_states(datasets, split="train"), cfg.select_fraction, seed)
    test_data = load_hand_states(datasets, split="test")
    print(f"{len(train_data):,} training rows, {len(select_data):,} checkpoint-selection rows, {len(test_data):,} "
          f"test rows (other episodes), hands: {', '.join(train_data.hand_names())}")  # fmt: skip
    result = train_tokenizer(cfg, train_data, select_data)
    print(f"trained {result.steps} steps (batch {batch_size}) in {result.seconds:.0f} s; best selection-episode "
          f"joint MAE {result.best_mae_deg:.3f} deg at step {result.best_step}")  # fmt: skip
    model = UniDexTok.from_pretrained(result.best_dir)
    tok_dir = out / "tokenizer"
    if tok_dir.exists():
        shutil.rmtree(tok_dir)
    model.save_pretrained(tok_dir)
    report = evaluate_tokenizer(model, test_data)
    report["scored"] = describe_scored(test_data, datasets, "test", result.best_dir)
    md = write_report(report, out / "eval")
    print(md.split("\n\nPer-joint")[0])
    print(f"\nFull report (per joint): {out / 'eval.md'}, {out / 'eval.json'}; tokenizer: {tok_dir}")
    return model, test_data, report


# ---------------------------------------------------------------------------------------------
# 5. pictures
# ---------------------------------------------------------------------------------------------
def demo_pictures(out: Path, model, test_data, seed: int) -> None:
    """The default shipped tokenizer (what `UniDexTok.from_pretrained(DEFAULT_TOKENIZER)` gives, its own
    encoding) beside the one trained above and 8-bit binning, on the same held-out rows: a table and pictures."""
    from lerobot_unidextok import hands, udhm
    from lerobot_unidextok.baselines import HandRange, UniformBinning
    from lerobot_unidextok.evaluation import reconstruct
    from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.viz import plot_codebook_usage, plot_hand_reconstructions, plot_per_joint_errors

    _banner(f"5. The shipped tokenizer ({DEFAULT_TOKENIZER}) vs the one trained above vs 8-bit binning: table, pictures")
    plots = out / "plots"
    rng = np.random.default_rng(seed)
    shipped = UniDexTok.from_pretrained(DEFAULT_TOKENIZER)
    ranges = {}
    for hand in test_data.hand_names():
        spec = hands.get(hand)
        limits = udhm.JOINT_LIMITS_RAD if hand == "human" else np.stack(spec.udhm_limits_rad(), axis=1)
        ranges[hand] = HandRange.from_limits(limits, spec.active_mask)
    binning = UniformBinning(ranges)  # RT-2 / OpenVLA style: 256 bins per active joint, no training
    shipped_name, own_name, bins_name = "UniDexTok shipped", "trained here", "binning 8 bit"
    states = {
        shipped_name: reconstruct(shipped, test_data.states_rad, test_data.hands, allow_unknown=True,
                                  masks=test_data.masks).states_rad,
        own_name: (own := reconstruct(model, test_data.states_rad, test_data.hands, allow_unknown=True,
                                      masks=test_data.masks)).states_rad,
        bins_name: np.zeros_like(test_data.states_rad),
    }  # fmt: skip
    for hand in test_data.hand_names():
        rows = np.flatnonzero(test_data.hands == hand)
        states[bins_name][rows] = binning.decode(binning.encode(test_data.states_rad[rows], hand), hand).numpy()
    for name, rec in states.items():  # the slots a hand lacks are not decoded targets: drawn as recorded (0)
        states[name] = np.where(test_data.masks, rec, test_data.states_rad)
    errors_deg = {}
    for name, rec in states.items():
        err = np.degrees(np.abs(rec - test_data.states_rad))
        err[~test_data.masks] = np.nan
        errors_deg[name] = err
    table = [[hand, *(f"{np.nanmean(e[test_data.hands == hand]):.3f}" for e in errors_deg.values())]
             for hand in test_data.hand_names()]  # fmt: skip
    table.append(["all test rows", *(f"{np.nanmean(e):.3f}" for e in errors_deg.values())])
    print("MPJAE (deg) on the test episodes, active joints:")
    print(_table(["hand", shipped_name, own_name, bins_name], table))
    how = "the code search" if shipped.config.encoding.rounds else "the nearest codes"
    print(f"{shipped_name}: {DEFAULT_TOKENIZER}, in the package for every registered hand (its own encoding, "
          f"{how}); {own_name}: the tokenizer of step 4, trained on this synthetic mixture only")  # fmt: skip
    paths = []
    for hand in test_data.hand_names():
        pick = rng.choice(np.flatnonzero(test_data.hands == hand), size=min(3, int((test_data.hands == hand).sum())),
                          replace=False)  # fmt: skip
        paths.append(plot_hand_reconstructions(test_data.states_rad[pick], {n: r[pick] for n, r in states.items()},
                                               hand, plots / f"hands_{hand}.png", title=f"{hand}: ground truth "
                                               "(grey) vs the shipped UniDexTok (green) vs the demo's own and binning"))  # fmt: skip
    paths.append(plot_per_joint_errors(errors_deg, plots / "per_joint_error.png",
                                       title="per-joint error on the held-out split"))  # fmt: skip
    paths.append(plot_codebook_usage(own.codes, model.config.codebook_size, plots / "codebook_usage.png"))
    for p in paths:
        print(f"wrote {p}")


# ---------------------------------------------------------------------------------------------
# 6. LeRobot processor step + hub cache
# ---------------------------------------------------------------------------------------------
def demo_lerobot(out: Path, roots: dict[str, Path]) -> None:
    import torch
    from lerobot.datasets import LeRobotDataset
    from lerobot.processor import PolicyProcessorPipeline

    from lerobot_unidextok.data import UdhmDatasetMeta
    from lerobot_unidextok.hub import cache_via_loopback
    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep, token_preview
    from lerobot_unidextok.tokenizer import UniDexTok

    _banner("6. LeRobot: the tokenizer as a processor step on converted frames, and the local hub cache")
    root = roots.get("lerobot") or next(iter(roots.values()))
    ds = LeRobotDataset(f"demo/{root.name}_udhm", root=root, video_backend="pyav")  # state-only: no decoder probe
    layout = UdhmDatasetMeta(root).hand_layout()
    step = UniDexTokStateTokenizerStep.from_dataset(root, pretrained=str(out / "tokenizer"))  # blocks found by name
    pipeline = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    frames = torch.stack([ds[i]["observation.state"] for i in (0, len(ds) // 2)])  # (2, D): passthrough + 22 * H
    processed = pipeline({"observation.state": frames})
    print(f"dataset {root.name}: {len(ds)} frames, layout {layout.hands}; processor output keys: "
          f"{sorted(k for k in processed if k.startswith('observation'))}")  # fmt: skip
    print(token_preview(step, frames))

    repo_id = "demo/unidextok-small"
    if os.environ.get("HF_HUB_OFFLINE", "0").upper() in ("1", "ON", "YES", "TRUE"):
        # huggingface_hub refuses every transfer under HF_HUB_OFFLINE, loopback ones included
        print("\nlocal hub cache step skipped: HF_HUB_OFFLINE is set (unset it to publish the tokenizer into the "
              "local hub cache through a loopback Hub on 127.0.0.1; nothing leaves the machine)")  # fmt: skip
        return
    snapshot = cache_via_loopback(out / "tokenizer", repo_id)
    reloaded = UniDexTok.from_pretrained(repo_id, local_files_only=True)
    same = all(
        torch.equal(a, b)
        for a, b in zip(reloaded.state_dict().values(), step.tokenizer.state_dict().values(), strict=True)
    )
    print(f"\nsaved into the local hub cache: {snapshot}\nloaded back by repo id {repo_id!r} offline: "
          f"weights identical = {same}")  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default: outputs/demo)")
    parser.add_argument(
        "--quick", action="store_true", help="less data (4 episodes x 100 frames per source) and 300 training steps"
    )
    parser.add_argument("--preset", default="small", help="tokenizer size preset (paper | small | tiny)")
    parser.add_argument(
        "--steps", type=int, default=None, help=f"training steps (default: {DEMO_STEPS}, or 300 with --quick)"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    os.environ.setdefault("MPLBACKEND", "Agg")
    run_cli(lambda: run(args))


def run(args: argparse.Namespace) -> None:
    """The tour, in order (module docstring)."""
    steps = args.steps or (300 if args.quick else DEMO_STEPS)
    episodes, frames = (4, 100) if args.quick else (10, 150)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    demo_udhm(args.seed)
    demo_hands()
    roots = demo_convert(out, episodes, frames, args.seed)
    model, test_data, _ = demo_train(out, roots, args.preset, steps, args.seed)
    demo_pictures(out, model, test_data, args.seed)
    demo_lerobot(out, roots)
    print(f"\nDemo finished in {time.perf_counter() - t0:.0f} s; everything is in {out}/", flush=True)


if __name__ == "__main__":
    sys.exit(main())
