"""The training data of the universal tokenizer (`configs/train/universal.yaml`): every real recording in
../shared/data/real that a converter reads, converted with `unidextok-convert` into `--out`.

    python experiments/universal_data.py                       # -> outputs/universal_data/{g1_inspire,human_clip,mediapipe}
    python experiments/universal_data.py --real=../shared/data/real --out=outputs/universal_data

- `g1_inspire`: `g1-inspire/` (LeRobot v2.1, Unitree G1 + two Inspire hands), the `lerobot` source; the
  converter's episode split (2 of 10 episodes are test episodes, never trained on).
- `human_clip`: `dex-retargeting/human_joint_right.npy` (621 frames of one real right hand, MediaPipe world
  landmarks, 30 fps) cut into consecutive 2 s segments, one `.npy` per segment, the `keypoints` source; the
  converter's split holds out 2 of its 10 segments.
- `mediapipe`: the six HandLandmarker results with world landmarks in `mediapipe/mediapipe_hand_fixtures.json`
  (real photos, right hands), one single-frame `.npy` each, the `keypoints` source; 1 of 6 held out.

Not converted (no converter reads them): the LinkerHand vendor presets (`linkerhand-ros2-sdk/`, hand-tuned
poses, not recordings; `linker-sim/` is channel metadata) and the single Allegro home pose.

Deterministic: the files written depend only on the input files, and the converter's test split only on the
episode keys (sha1). Each run rebuilds `--out` from scratch.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from lerobot_unidextok.converters.lerobot import G1_INSPIRE_HANDS as G1_HANDS
from lerobot_unidextok.utils.shared_data import real_data_dir

REPO = Path(__file__).resolve().parents[1]
DEFAULT_REAL = real_data_dir(REPO)
CLIP_FPS = 30  # upstream video rate (../shared/data/real/README.md)
SEGMENT_FRAMES = 2 * CLIP_FPS  # 2 s segments, as experiments/real_data.py cuts the clip
DATASETS = ("g1_inspire", "human_clip", "mediapipe")


def convert(source: str, input_path: Path, root: Path, repo_id: str, **extra: object) -> None:
    """One `unidextok-convert` run (the real CLI, in a subprocess)."""
    cmd = [sys.executable, "-m", "lerobot_unidextok.scripts.convert", f"--source={source}", f"--input={input_path}",
           f"--root={root}", f"--repo_id={repo_id}", "--progress=false"]  # fmt: skip
    cmd += [f"--{k}={json.dumps(v) if isinstance(v, dict) else v}" for k, v in extra.items()]
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def write_clip_segments(clip: Path, folder: Path) -> int:
    """The clip as consecutive `SEGMENT_FRAMES` segments (the last short one merged), one `.npy` + sidecar each."""
    kp = np.load(clip)  # (T, 21, 3) m
    n_seg = max(1, len(kp) // SEGMENT_FRAMES)
    folder.mkdir(parents=True)
    for i in range(n_seg):
        end = len(kp) if i == n_seg - 1 else (i + 1) * SEGMENT_FRAMES
        np.save(folder / f"clip_right_seg{i:02d}.npy", kp[i * SEGMENT_FRAMES : end])
        (folder / f"clip_right_seg{i:02d}.json").write_text(json.dumps({"side": "right", "fps": CLIP_FPS}))
    return n_seg


def write_mediapipe_results(fixtures: Path, folder: Path) -> int:
    """Each HandLandmarker result with 3D world landmarks as a one-frame `.npy` (side from its label)."""
    data = json.loads(fixtures.read_text())
    folder.mkdir(parents=True)
    n = 0
    for name, entry in sorted(data.items()):
        if not isinstance(entry, dict) or "world_landmarks_m" not in entry:
            continue
        kp = np.asarray(entry["world_landmarks_m"], dtype=np.float64).reshape(1, 21, 3)
        stem = Path(name).name.split(".")[0]
        np.save(folder / f"{stem}.npy", kp)
        side = str(entry["handedness"]).lower()
        (folder / f"{stem}.json").write_text(json.dumps({"side": side, "fps": CLIP_FPS}))
        n += 1
    return n


def build(real: Path, out: Path) -> list[Path]:
    """Convert every recording into `out` (rebuilt); returns the dataset roots in `DATASETS` order."""
    if not (real / "g1-inspire" / "meta" / "info.json").is_file():
        raise SystemExit(f"{real} has no g1-inspire/ recording: pass --real=<copy of shared/data/real>")
    if out.exists():
        shutil.rmtree(out)
    raw = out / "_raw"
    convert("lerobot", real / "g1-inspire", out / "g1_inspire", "local/universal_g1_inspire",
            source_options={"hands": G1_HANDS})  # fmt: skip
    write_clip_segments(real / "dex-retargeting" / "human_joint_right.npy", raw / "human_clip")
    convert("keypoints", raw / "human_clip", out / "human_clip", "local/universal_human_clip")
    write_mediapipe_results(real / "mediapipe" / "mediapipe_hand_fixtures.json", raw / "mediapipe")
    convert("keypoints", raw / "mediapipe", out / "mediapipe", "local/universal_mediapipe")
    return [out / name for name in DATASETS]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--real", type=Path, default=DEFAULT_REAL, help="copy of shared/data/real")
    p.add_argument("--out", type=Path, default=Path("outputs/universal_data"), help="converted datasets go here")
    args = p.parse_args(argv)
    roots = build(args.real, args.out)
    print("datasets: [" + ",".join(str(r) for r in roots) + "]")


if __name__ == "__main__":
    main()
