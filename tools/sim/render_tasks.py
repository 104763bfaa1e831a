"""One picture per task: the env's own frames (its `front` camera, `UniDexTokEnv.render`) of the scripted expert's
episode, one frame per phase, for two hands (a row each).

    MUJOCO_GL=egl .venv/bin/python tools/sim/render_tasks.py --task FingerSequence-v0 \
        --hands inspire_rh56_unitree allegro --out docs/images/task_fingersequence.png

The phases are the expert's own: the start, the end of each segment of its plan (`Expert.segment_ends`), and each
step at which its closed-loop part moves on (a sequence's press due, `SequencePresses.due`; a pinch's lift, carry,
set-down, release, `PinchCarry.phase`), and the last step. The episode is seed `--seed` (the expert's noise
from 2,000,000 + seed, as `benchmarks/bench_sim.py`); each frame is labelled with its step. The sheet is quantised
to 64 colours to stay small. EGL and OSMesa both render on a CPU; without either the env's frames are black.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

from lerobot_env_unidextok.env import UniDexTokEnv  # noqa: E402
from lerobot_env_unidextok.experts import Expert  # noqa: E402

SIZE = (240, 180)  # width, height of a frame (px)


def closed_loop_phase(expert: Expert) -> object:
    """Where the expert's closed-loop part is (None before it starts)."""
    if expert.presses is not None:
        return expert.presses.due
    return expert.carry.phase if expert.carry is not None else None


def pressed(env: UniDexTokEnv, obs: dict) -> int:
    """A sequence's presses done, as the observation says."""
    return int(round(float(obs["agent_pos"][env.state_names.index("presses_done")])))


def phase_frames(hand: str, task: str, seed: int) -> tuple[list[tuple[int, tuple[np.ndarray, str]]], bool]:
    """[(step, (frame, phase label))] at each phase of the expert's episode, and whether it succeeded."""
    env = UniDexTokEnv(hand, task, width=SIZE[0], height=SIZE[1])
    obs, _ = env.reset(seed=seed)
    expert = Expert(env, np.random.default_rng(2_000_000 + seed))
    expert.reset(obs)
    marks = {0, *(e for e in expert.segment_ends if e < 50)}
    frames, phase, success = {0: (env.render(), "start")}, None, False
    for step in range(1, 51):
        obs, _, terminated, _, info = env.step(expert.act(obs))
        now = closed_loop_phase(expert) if step > len(expert.plan) else None
        if step in marks or now != phase or terminated:
            label = "" if now is None else now if isinstance(now, str) else f"{pressed(env, obs)} of 3 pressed"
            frames[step] = (env.render(), label)
        phase, success = now, bool(info["is_success"])
        if terminated:
            break
    env.close()
    return sorted(frames.items()), success


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", required=True)
    ap.add_argument("--hands", nargs=2, default=["inspire_rh56_unitree", "allegro"])
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    rows = []
    for hand in args.hands:
        frames, success = phase_frames(hand, args.task, args.seed)
        row = Image.new("RGB", (SIZE[0] * len(frames), SIZE[1]))
        for i, (step, (frame, phase)) in enumerate(frames):
            tile = Image.fromarray(frame)
            label = f"{hand}, step {step}" if i == 0 else f"step {step}" + (f", {phase}" if phase else "")
            label += f" ({'success' if success else 'failed'})" if i == len(frames) - 1 else ""
            ImageDraw.Draw(tile).text((5, 4), label, fill=(255, 255, 255))
            row.paste(tile, (i * SIZE[0], 0))
        rows.append(row)
    sheet = Image.new("RGB", (max(r.width for r in rows), sum(r.height for r in rows)))
    for i, row in enumerate(rows):
        sheet.paste(row, (0, i * SIZE[1]))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.convert("P", palette=Image.Palette.ADAPTIVE, colors=64).save(args.out, optimize=True)
    print(f"wrote {args.out} ({args.task}: {', '.join(args.hands)}; {args.out.stat().st_size // 1024} kB)")


if __name__ == "__main__":
    main()
