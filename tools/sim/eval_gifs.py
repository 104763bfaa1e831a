"""One GIF per task of what a trained policy does: LeRobot's own `lerobot-eval` video of a closed-loop episode.

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python tools/sim/eval_gifs.py --hand shadow \
        --tasks GraspLift-v0 FingerPress-v0 ChordPress-v0 FingerSequence-v0 PinchPlace-v0 PinchLift-v0

For each task, the user's path of docs/lerobot.md section 8 ("From a pip install to a success rate"), each step
its real CLI in a subprocess, into `--work_dir/<hand>/<task>/` (not committed):

1. `unidextok-sim-record` of `--episodes` expert episodes (`native/`);
2. `unidextok-convert --source=lerobot --test_fraction=0` with the hand's columns (`udhm/`);
3. `lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu)` with the section's closed-loop flags
   (absolute actions, chunks of 10 run in full) for `--steps` updates (`train/`);
4. `lerobot-eval --env.type=unidextok` on `--eval_episodes` episodes (seeds `--eval_seed` + i), which writes the
   video of each of its first 10 episodes (`eval/videos/<suite>_<task id>/eval_episode_<i>.mp4`);

then picks the first successful episode by `eval/eval_info.json` (else the first episode, said in the log), and
turns its mp4 into `--out_dir/eval_<task>.gif`: every n-th frame (about `--gif_fps`), `--gif_width` px wide, one
64-colour palette drawn from all of them, the last frame held 1 s. A step whose output is there is not run again;
`--fresh` redoes the task's work folder. Prints per task: the policy's success, the episode shown, the GIF's
size, and each CLI's CPU seconds (its user + system time, kept in `cpu_s.json` from the run that made the step's
output). EGL or OSMesa render on a CPU; with neither, the videos are black.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import av
import numpy as np
from PIL import Image

TASKS = ("GraspLift-v0", "FingerPress-v0", "ChordPress-v0", "FingerSequence-v0", "PinchPlace-v0", "PinchLift-v0")
# docs/lerobot.md section 8, step 3: the flags a user adds to act_udt_cpu.yaml for closed-loop control
CLOSED_LOOP_FLAGS = ("--policy.udt_relative_actions=false", "--policy.udt_copy_start=false",
                     "--policy.n_action_steps=10")  # fmt: skip
HAND_PREFIX = "right_"  # the simulator's native columns (lerobot_env_unidextok.columns.HAND_PREFIX)
PALETTE_COLOURS = 64  # octree palette: median cut gave small objects (the blue cylinder) a grey
HOLD_LAST_S = 1.0  # the last frame shown this long, so the outcome can be seen before the GIF loops


@dataclass
class TaskResult:
    """What one task's run gave."""

    task: str
    successes: list[bool]  # per evaluated episode, lerobot-eval's
    seeds: list[int]  # episode i's seed (lerobot-eval: --seed + i)
    shown: int  # the episode the GIF shows
    gif: Path
    gif_bytes: int
    cpu_s: dict[str, float]  # step -> CPU seconds of its CLI, from the run that made its output


# subprocess helpers


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_cli(args: list[str], log: Path) -> float:
    """Run one CLI (its output into `log`); its CPU seconds. A failure exits with the log's last lines."""
    env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1"),
           "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "HF_HUB_OFFLINE": "1"}  # fmt: skip
    print("$", " ".join(args), flush=True)
    before = _children_cpu_s()
    with log.open("w") as out:
        code = subprocess.run(args, stdout=out, stderr=subprocess.STDOUT, env=env, check=False).returncode
    if code != 0:
        tail = "\n".join(log.read_text().splitlines()[-15:])
        sys.exit(f"error: {args[0]} exited with {code} (log {log}):\n{tail}")
    return _children_cpu_s() - before


def _bin(name: str) -> str:
    """The CLI beside this Python (the venv's), else on PATH."""
    here = Path(sys.executable).parent / name
    return str(here) if here.exists() else name


# the user's path, one CLI per step


def record(task: str, hand: str, episodes: int, root: Path, log: Path) -> float:
    return run_cli([_bin("unidextok-sim-record"), f"--hand={hand}", f"--task={task}", f"--episodes={episodes}",
                    f"--root={root}"], log)  # fmt: skip


def convert(native: Path, root: Path, repo_id: str, hand: str, log: Path) -> float:
    hands = json.dumps({"hands": {"right": f"{hand}:{HAND_PREFIX}"}})
    return run_cli([_bin("unidextok-convert"), "--source=lerobot", f"--input={native}", f"--root={root}",
                    f"--repo_id={repo_id}", "--test_fraction=0", f"--source_options={hands}"], log)  # fmt: skip


def train(dataset: Path, repo_id: str, steps: int, out: Path, log: Path) -> float:
    config = subprocess.run([_bin("unidextok-config"), "lerobot/act_udt_cpu"], capture_output=True, text=True,
                            check=True).stdout.strip()  # fmt: skip
    return run_cli([_bin("lerobot-train"), f"--config_path={config}", f"--dataset.repo_id={repo_id}",
                    f"--dataset.root={dataset}", *CLOSED_LOOP_FLAGS, f"--steps={steps}", f"--output_dir={out}"],
                   log)  # fmt: skip


def evaluate(checkpoint: Path, task: str, hand: str, episodes: int, seed: int, out: Path, log: Path) -> float:
    return run_cli([_bin("lerobot-eval"), f"--policy.path={checkpoint}", "--env.type=unidextok", f"--env.task={task}",
                    f"--env.hand={hand}", f"--eval.n_episodes={episodes}", f"--eval.batch_size={episodes}",
                    "--eval.use_async_envs=false", "--policy.device=cpu", f"--seed={seed}", f"--output_dir={out}"],
                   log)  # fmt: skip


# lerobot-eval's output


def episodes_of(eval_info: dict) -> tuple[list[bool], list[Path]]:
    """(success per episode, video per rendered episode) of lerobot-eval's eval_info.json (one task)."""
    tasks = eval_info["per_task"]
    if len(tasks) != 1:
        raise ValueError(f"expected one task in eval_info.json, got {len(tasks)}")
    metrics = tasks[0]["metrics"]
    return [bool(s) for s in metrics["successes"]], [Path(p) for p in metrics.get("video_paths", [])]


def pick_episode(successes: list[bool], n_videos: int) -> int:
    """The first successful episode that has a video, else episode 0."""
    if n_videos == 0:
        raise ValueError("lerobot-eval wrote no video (is rendering off?)")
    return next((i for i, ok in enumerate(successes[:n_videos]) if ok), 0)


# mp4 -> GIF


def stack(images: list[Image.Image]) -> Image.Image:
    """The images one above the other (a palette drawn from it has every frame's colours)."""
    w, h = images[0].size
    sheet = Image.new("RGB", (w, h * len(images)))
    for i, im in enumerate(images):
        sheet.paste(im, (0, i * h))
    return sheet


def mp4_to_gif(mp4: Path, gif: Path, width_px: int, fps: float) -> int:
    """Every n-th frame of `mp4` (n: its rate over `fps`), `width_px` wide, as a looping GIF; its size in bytes."""
    with av.open(str(mp4)) as container:
        stream = container.streams.video[0]
        rate = float(stream.average_rate or stream.guessed_rate or fps)
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]  # [(H, W, 3) uint8]
    if not frames:
        raise ValueError(f"{mp4} has no frames")
    every = max(1, round(rate / fps))
    kept = frames[::every]
    if (len(frames) - 1) % every:
        kept.append(frames[-1])  # always end on the episode's last frame
    h, w = kept[0].shape[:2]
    size = (width_px, max(2, round(h * width_px / w)))
    images = [Image.fromarray(np.asarray(f)).resize(size, Image.LANCZOS) for f in kept]
    palette = stack(images).quantize(PALETTE_COLOURS, method=Image.Quantize.FASTOCTREE)  # one for all frames
    quantised = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    step_ms = round(1000 * every / rate)
    durations = [step_ms] * (len(quantised) - 1) + [max(step_ms, round(1000 * HOLD_LAST_S))]
    gif.parent.mkdir(parents=True, exist_ok=True)
    quantised[0].save(gif, save_all=True, append_images=quantised[1:], duration=durations, loop=0, optimize=True)
    return gif.stat().st_size


# one task


def gif_name(task: str) -> str:
    """eval_<task>.gif: the task id lower-cased, without its version (GraspLift-v0 -> eval_grasplift.gif)."""
    return f"eval_{task.split('-v')[0].lower()}.gif"


def run_task(task: str, args: argparse.Namespace) -> TaskResult:
    work = Path(args.work_dir) / args.hand / task
    if args.fresh:
        shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True, exist_ok=True)
    native, udhm, trained, evaluated = work / "native", work / "udhm", work / "train", work / "eval"
    repo_id = f"sim/{args.hand}_{task.split('-v')[0].lower()}"
    checkpoint = trained / "checkpoints" / "last" / "pretrained_model"
    cpu_file = work / "cpu_s.json"
    cpu: dict[str, float] = json.loads(cpu_file.read_text()) if cpu_file.exists() else {}
    if not (native / "meta" / "info.json").exists():
        cpu["record"] = record(task, args.hand, args.episodes, native, work / "record.log")
    if not (udhm / "meta" / "info.json").exists():
        cpu["convert"] = convert(native, udhm, repo_id, args.hand, work / "convert.log")
    if not (checkpoint / "config.json").exists():
        shutil.rmtree(trained, ignore_errors=True)  # lerobot-train refuses an existing output dir
        cpu["train"] = train(udhm, repo_id, args.steps, trained, work / "train.log")
    if not (evaluated / "eval_info.json").exists():
        shutil.rmtree(evaluated, ignore_errors=True)
        cpu["eval"] = evaluate(checkpoint, task, args.hand, args.eval_episodes, args.eval_seed, evaluated,
                               work / "eval.log")  # fmt: skip
    cpu_file.write_text(json.dumps(cpu))
    successes, videos = episodes_of(json.loads((evaluated / "eval_info.json").read_text()))
    shown = pick_episode(successes, len(videos))
    gif = Path(args.out_dir) / gif_name(task)
    size = mp4_to_gif(videos[shown], gif, args.gif_width, args.gif_fps)
    seeds = [args.eval_seed + i for i in range(len(successes))]
    return TaskResult(task, successes, seeds, shown, gif, size, cpu)


def report(r: TaskResult, hand: str, episodes: int, steps: int) -> str:
    k, n = sum(r.successes), len(r.successes)
    which = "succeeded" if r.successes[r.shown] else "failed (no episode succeeded)"
    cpu = ", ".join(f"{name} {s:.0f}" for name, s in r.cpu_s.items())
    return (f"{r.task} ({hand}, {episodes} demonstrations, {steps} updates): success {k}/{n} "
            f"(seeds {r.seeds[0]}-{r.seeds[-1]}); GIF: episode {r.shown} (seed {r.seeds[r.shown]}), {which}; "
            f"{r.gif} {r.gif_bytes / 1000:.0f} kB; CPU s: {cpu} (total {sum(r.cpu_s.values()):.0f})")  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--hand", default="shadow")
    parser.add_argument("--episodes", type=int, default=25, help="expert demonstrations recorded")
    parser.add_argument("--steps", type=int, default=400, help="lerobot-train updates")
    parser.add_argument("--eval_episodes", type=int, default=10, help="lerobot-eval episodes (videos: the first 10)")
    parser.add_argument("--eval_seed", type=int, default=1000, help="lerobot-eval --seed: episode i is seed + i")
    parser.add_argument("--gif_width", type=int, default=240, help="px")
    parser.add_argument("--gif_fps", type=float, default=5.0)
    parser.add_argument("--work_dir", default="outputs/eval_gifs")
    parser.add_argument("--out_dir", default="docs/images")
    parser.add_argument("--fresh", action="store_true", help="redo each task's work folder from the recording")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.steps < 1 or args.eval_episodes < 1:
        parser.error("--episodes, --steps and --eval_episodes must be at least 1")
    results = [run_task(task, args) for task in args.tasks]
    print()
    for r in results:
        print(report(r, args.hand, args.episodes, args.steps))
    print(f"CPU s in all: {sum(sum(r.cpu_s.values()) for r in results):.0f}")


if __name__ == "__main__":
    main()
