"""A human-hand UniDexTok trained on one real tracked recording, scored on human hands it never saw: the
recording's own last fifth, SYNTHETIC gesture motion (validation, used to choose the mixture) and real
tracker output of other people (the unseen set, never used to choose anything), next to 8-bit binning.

    python experiments/unseen_human.py                         # dex-retargeting clip -> MediaPipe gestures
    python experiments/unseen_human.py --variants='[shipped,no_coverage]' --steps=5000
    python experiments/unseen_human.py --train_keypoints='[a.npy,b.npy]' --unseen_keypoints='[c.npy,d.json]'

Keypoint files: `.npy` (T, 21, 3) metres in MANO-21 order (one recording each), or a MediaPipe fixtures
`.json` (entries with `world_landmarks_m`); all are solved to UDHM by UDHM IK as right hands.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from experiments.unseen_episodes import VARIANTS, Variant
from lerobot_unidextok.training import HandStates, TrainConfig, train_tokenizer
from lerobot_unidextok.training.coverage import CoverageConfig

logger = logging.getLogger(__name__)
NAME = "unseen_human"

HUMAN_VARIANTS: dict[str, Variant] = {
    "shipped": VARIANTS["shipped"],
    "no_coverage": VARIANTS["no_coverage"],
    "uniform_heavy": Variant(
        "human rows: recorded 0.2, recombine 0.2, noise 0.2, interpolate 0.1, uniform 0.3",
        {"coverage": {"human": {"recorded": 0.2, "recombine": 0.2, "noise": 0.2, "interpolate": 0.1, "uniform": 0.3}}},
    ),
    "augment_only": Variant(
        "human rows: recorded 0.3, recombine 0.3, noise 0.3, interpolate 0.1 (no uniform)",
        {"coverage": {"human": {"recorded": 0.3, "recombine": 0.3, "noise": 0.3, "interpolate": 0.1}}},
    ),
}


@dataclass
class HumanConfig:
    train_keypoints: list[str] = field(default_factory=list)  # empty = the real dex-retargeting clip
    train_fraction: float = 0.8  # of each training recording (the rest is its "own last part")
    unseen_keypoints: list[str] = field(default_factory=list)  # empty = the real MediaPipe gesture fixtures
    variants: list[str] = field(default_factory=lambda: ["shipped", "no_coverage"])
    steps: int = 0  # 0 = the TrainConfig default
    seed: int = 0
    synthetic_frames: int = 600  # SYNTHETIC gesture frames for validation
    output_root: str = "outputs/experiments"
    tiny: bool = False


def load_sets(cfg: HumanConfig) -> dict[str, HandStates]:
    """train / own_rest / synthetic / unseen rows."""
    from experiments.unseen_data import human_rows_from_keypoints, load_keypoints, real_data_dir
    from lerobot_unidextok.samples.motion import gesture_track

    train_files = cfg.train_keypoints or [str(real_data_dir() / "dex-retargeting" / "human_joint_right.npy")]
    unseen_files = cfg.unseen_keypoints or [str(real_data_dir() / "mediapipe" / "mediapipe_hand_fixtures.json")]
    train, rest = [], []
    for i, path in enumerate(train_files):
        for kp in load_keypoints(path).values():
            cut = int(round(cfg.train_fraction * len(kp)))
            train.append(human_rows_from_keypoints(kp[:cut], episode=i))
            if cut < len(kp):
                rest.append(human_rows_from_keypoints(kp[cut:], episode=i))
    unseen = [human_rows_from_keypoints(kp, episode=j) for path in unseen_files
              for j, kp in enumerate(load_keypoints(path).values())]  # fmt: skip
    q = gesture_track(np.random.default_rng(cfg.seed + 7), cfg.synthetic_frames, 30.0).angles_rad.astype(np.float32)
    synthetic = HandStates(q, np.full(len(q), "human"), np.ones(q.shape, bool))
    sets = {"train": HandStates.concat(train), "synthetic (validation)": synthetic, "unseen": HandStates.concat(unseen)}
    if rest:
        sets["own last part"] = HandStates.concat(rest)
    return sets


def run(cfg: HumanConfig) -> dict:
    import torch

    from experiments.unseen_data import binning_reconstruction
    from lerobot_unidextok.evaluation import mpjae_deg, reconstruct
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training.loop import build_model

    unknown = sorted(set(cfg.variants) - set(HUMAN_VARIANTS))
    if unknown:
        raise ValueError(f"unknown variants {unknown}; choose from {sorted(HUMAN_VARIANTS)}")
    folder = Path(cfg.output_root) / NAME
    sets = load_sets(cfg)
    train = sets["train"]
    scored = {k: v for k, v in sets.items() if k != "train"}
    rows = {"binning_8bit": {k: mpjae_deg(binning_reconstruction(v), v.states_rad, v.masks) for k, v in scored.items()}}
    info = {}
    for name in cfg.variants:
        v = HUMAN_VARIANTS[name]
        kw = dict(v.train)
        if "coverage" in kw:
            kw["coverage"] = CoverageConfig(**kw["coverage"])
        if cfg.steps:
            kw["steps"] = cfg.steps
        if cfg.tiny:
            kw |= {"preset": "tiny", "steps": 12, "batch_size": 32, "warmup_steps": 2}
        # one recording: no held-out episode to choose a checkpoint on, so the final model is kept
        tcfg = TrainConfig(output_dir=str(folder / "models" / name), progress=False, save_last_every=10**9,
                           select_fraction=0.0, seed=cfg.seed, **kw)  # fmt: skip
        torch.manual_seed(cfg.seed)
        cpu0 = time.process_time()
        res = train_tokenizer(tcfg, train, None, model=build_model(tcfg, train, **v.model))
        info[name] = {"steps": res.steps, "train_cpu_s": round(time.process_time() - cpu0, 1), "note": v.note}
        model = UniDexTok.from_pretrained(res.best_dir)
        rows[name] = {k: mpjae_deg(reconstruct(model, d.states_rad, d.hands, masks=d.masks).states_rad, d.states_rad, d.masks)
                      for k, d in scored.items()}  # fmt: skip
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "train_rows": len(train),
              "rows": {k: len(v) for k, v in scored.items()}, "mpjae_deg": rows, "training": info,
              "git_commit": git_commit(), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def markdown(result: dict) -> str:
    sets = list(result["rows"])
    header = ["method", *[f"{s} ({result['rows'][s]} rows)" for s in sets], "CPU s", "what"]
    body = []
    for name, scores in result["mpjae_deg"].items():
        t = result["training"].get(name, {})
        body.append([name, *[f"{scores[s]:.3f}" for s in sets], f"{t.get('train_cpu_s', 0):.0f}",
                     t.get("note", "per-joint 256 bins over the UDHM limits, no training")])  # fmt: skip
    return "\n".join([f"# {NAME}", "", f"Trained on {result['train_rows']} real human frames (UDHM IK); MPJAE (deg).",
                      "", md_table(header, body)])  # fmt: skip


def parse(argv: list[str] | None = None) -> HumanConfig:
    return runtime.parse(HumanConfig, argv)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(HumanConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
