"""One policy, several robots, the way a user runs it: `unidextok-mix`, the stock `lerobot-train` with
`act_udt_cpu.yaml`, `unidextok-deploy` onto each robot, `experiments/eval_policy.py` on each robot's held-out
episodes, next to copying the current state and to the same recipe on that robot alone.

    python experiments/mix_lerobot_train.py          # CPU-sized: 2 target sizes x 6 arms x 2 seeds + the L10 alone x 2
    python experiments/mix_lerobot_train.py --target_episodes='[2]' --seeds='[0]'

Target: the real Unitree G1 + Inspire recording (`g1-inspire`, converted), `target_episodes` of its training
episodes, scored on its recorded test episodes. Other robots, each written as a plain LeRobot v3 dataset of its
own joints in its SDK's units and converted with `unidextok-convert --source=lerobot` like any export:
- `l10_robot` (real poses, synthetic motion): a right LinkerHand L10 moving between the real L10 vendor presets
  (`linkerhand-ros2-sdk/L10_positions.yaml`, minimum-jerk moves), action = the next frame's state;
- `xhand_robot` (synthetic): a right XHand1 playing the sample gestures, action = the next frame's state.
Arms (same recipe, steps and seeds): `target_only` (`lerobot-train` on the G1 dataset's chosen episodes, the
whole robot: arms and hands); `target_hands_only` (the same episodes converted with `--keep=hands`, the layout the
mix has; the real G1 only);
`mix_hand_scaled` (the mix, relative actions z-scored per hand: `unidextok.hand_action_scale`, the default);
`mix_unscaled` (`--policy.udt_hand_action_scale=false`: relative actions as LeRobot leaves them, IDENTITY). Every
arm runs the recipe the figures were measured with (`MEASURED_WITH`: `--policy.udt_hand_norm=off
--policy.udt_mask_slots=false`, the defaults before 2026-12-05);
`l10_only` (the L10 robot's training episodes alone); and the same with `udt_copy_start` (act_udt_cpu.yaml's
default since it was measured here: the action head starts at zero, so the untrained policy copies the state):
`target_hands_copy_start`, `mix_copy_start` (hand-scaled), `l10_copy_start`; the other arms set it false.
Mixed checkpoints are scored on both robots. The
mix gives the target half of the training frames (its chosen episodes written several times, `--weights`), and
its per-hand scale is recomputed over the episodes each run trains on (`conversion.mix.action_delta_stats`;
`unidextok-mix` records it over every training episode, here the G1's others too).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table

logger = logging.getLogger(__name__)
NAME = "mix_lerobot_train"
NO_COPY = "--policy.udt_copy_start=false"
# the recipe these figures were measured with, before per-hand normalisation and masked slots became the <type>_udt
# defaults (2026-12-05): LeRobot's statistics, hand_action_scale on the mix's relative actions, every slot trained
MEASURED_WITH = ("--policy.udt_hand_norm=off", "--policy.udt_mask_slots=false")
# arm -> (training data: the target whole / its hands only / the mix / the L10 robot alone, lerobot-train flags)
ARM_RECIPES = {
    "target_only": ("target", (NO_COPY,)),
    "target_hands_only": ("hands", (NO_COPY,)),
    "mix_hand_scaled": ("mix", (NO_COPY,)),
    "mix_unscaled": ("mix", (NO_COPY, "--policy.udt_hand_action_scale=false")),
    "l10_only": ("l10", (NO_COPY,)),
    "target_hands_copy_start": ("hands", ()),
    "mix_copy_start": ("mix", ()),
    "l10_copy_start": ("l10", ()),
}
ARMS = tuple(ARM_RECIPES)
METRICS = ("hands_udhm_deg_first", "hands_udhm_deg_chunk", "hands_native_first", "hands_native_chunk")
PREFIX = "r_"  # the other robots' column names: r_<joint>
BIN = Path(sys.executable).parent


@dataclass
class MixTrainConfig:
    target_episodes: list[int] = field(default_factory=lambda: [2, 4])  # target training episodes per run
    arms: list[str] = field(default_factory=lambda: list(ARMS))
    seeds: list[int] = field(default_factory=lambda: [0, 1])
    steps: int = 1000  # act_udt_cpu.yaml's
    other_episodes: int = 8  # per other robot
    other_frames: int = 300  # per episode (10 s at 30 fps)
    jobs: int = 2  # lerobot-train runs at once (one torch thread each)
    target: str = ""  # a converted dataset instead of the real G1 (the tests: the synthetic G1 sample)
    l10_poses: str = "real"  # "real": the L10 vendor presets in ../shared/data/real; "synthetic": drawn in range
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_data"  # where the real G1 recording is converted once

    def __post_init__(self) -> None:
        unknown = sorted(set(self.arms) - set(ARMS))
        if unknown:
            raise ValueError(f"unknown arms {unknown}; choose from {list(ARMS)}")
        if self.l10_poses not in ("real", "synthetic"):
            raise ValueError(f"l10_poses must be real or synthetic, got {self.l10_poses!r}")


# ---------------------------------------------------------------------------------------------
# the other robots: raw LeRobot datasets in their own units, converted like any export
# ---------------------------------------------------------------------------------------------
def write_robot(root: Path, hand: str, native: list[np.ndarray], fps: int = 30) -> Path:
    """A right-handed robot's raw LeRobot v3 dataset: per episode (T + 1, J) native values; state = frame t,
    action = frame t + 1."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok import hands

    names = [f"{PREFIX}{j}" for j in hands.get(hand).joint_names]
    shape = {"dtype": "float32", "shape": (len(names),), "names": names}
    ds = LeRobotDataset.create(repo_id=f"local/{hand}_robot", fps=fps, root=root, robot_type=f"{hand}_right",
                               features={"observation.state": shape, "action": shape}, use_videos=False)  # fmt: skip
    for values in native:
        for state, action in zip(values[:-1], values[1:], strict=True):
            ds.add_frame({"observation.state": state.astype(np.float32), "action": action.astype(np.float32),
                          "task": "move the hand"})  # fmt: skip
        ds.save_episode()
    ds.finalize()
    return root


def convert_robot(raw: Path, root: Path, hand: str) -> Path:
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    convert(ConvertOptions(source="lerobot", input=raw, root=root, repo_id=f"local/{hand}_udhm",
                           source_options={"hands": {"right": f"{hand}:{PREFIX}"}}, progress=False))  # fmt: skip
    return root


def l10_episodes(real: Path | None, episodes: int, frames: int) -> list[np.ndarray]:
    """Minimum-jerk moves between the real L10 vendor presets (`real`), or between poses drawn in its range."""
    import yaml

    from lerobot_unidextok import hands
    from lerobot_unidextok.samples.motion import key_pose_motion

    if real is not None:
        data = yaml.safe_load((real / "linkerhand-ros2-sdk" / "L10_positions.yaml").read_text())
        presets = np.array([p["POSITION"] for p in data.get("RIGHT_HAND") or []], dtype=np.float64)
    else:
        low, high = hands.get("linkerhand_l10").raw_range("right").T
        presets = np.random.default_rng(7).uniform(low, high, size=(12, len(low)))
    return [key_pose_motion(presets, frames + 1, seed=e) for e in range(episodes)]


def xhand_episodes(episodes: int, frames: int) -> list[np.ndarray]:
    from lerobot_unidextok import hands
    from lerobot_unidextok.samples.motion import gesture_track

    spec, rng = hands.get("xhand1"), np.random.default_rng(123)
    return [np.clip(spec.from_udhm(gesture_track(rng, frames + 1, 30.0).angles_rad, "right"), *spec.raw_range("right").T)
            for _ in range(episodes)]  # fmt: skip


def target_hands(cfg: MixTrainConfig) -> Path | None:
    """The real G1 converted with `--keep=hands` (the mix's layout: its two UDHM blocks), once; None for `--target`."""
    if cfg.target:
        return None
    from experiments.unseen_data import real_data_dir
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.converters.lerobot import G1_INSPIRE_HANDS

    root = Path(cfg.cache_dir) / f"{NAME}_g1_hands"
    if not (root / "meta" / "unidextok_conversion.json").is_file():
        convert(ConvertOptions(source="lerobot", input=real_data_dir() / "g1-inspire", root=root, keep="hands",
                               repo_id="local/g1_hands", source_options={"hands": G1_INSPIRE_HANDS},
                               overwrite=True, progress=False))  # fmt: skip
    return root


def other_robots(cfg: MixTrainConfig, folder: Path) -> list[Path]:
    from experiments.unseen_data import real_data_dir

    out = []
    real = real_data_dir() if cfg.l10_poses == "real" else None
    for hand, native in (("linkerhand_l10", l10_episodes(real, cfg.other_episodes, cfg.other_frames)),
                         ("xhand1", xhand_episodes(cfg.other_episodes, cfg.other_frames))):  # fmt: skip
        root = folder / f"{hand}_udhm"
        if not (root / "meta" / "unidextok_conversion.json").is_file():
            convert_robot(write_robot(folder / f"{hand}_raw", hand, native), root, hand)
        out.append(root)
    return out


# ---------------------------------------------------------------------------------------------
# one arm
# ---------------------------------------------------------------------------------------------
def _run(cmd: list[str], log: Path) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1", "TQDM_DISABLE": "1"}
    with log.open("w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:2])} failed (exit {r.returncode}); its output: {log}")


def train(dataset: Path, repo_id: str, episodes: list[int], out: Path, seed: int, steps: int, *flags: str) -> Path:
    """`lerobot-train` with act_udt_cpu.yaml on `episodes` of `dataset`; the checkpoint's pretrained_model."""
    from lerobot_unidextok.configs import shipped_config

    if not (out / "checkpoints" / "last" / "pretrained_model" / "model.safetensors").is_file():
        _run([str(BIN / "lerobot-train"), f"--config_path={shipped_config('lerobot/act_udt_cpu')}",
              "--policy.udt_pretrained=unidextok/universal-small", f"--dataset.repo_id={repo_id}",
              f"--dataset.root={dataset}", f"--dataset.episodes={json.dumps(episodes)}", f"--seed={seed}",
              f"--steps={steps}", f"--save_freq={steps}", f"--output_dir={out}", *flags], out.with_suffix(".log"))  # fmt: skip
    return out / "checkpoints" / "last" / "pretrained_model"


def score(checkpoint: Path, robot: Path, name: str, out: Path, mixed: bool) -> dict:
    """eval_policy.py's figures of `checkpoint` (bound to `robot` first when trained on a mix) on the robot's
    recorded test episodes."""
    if mixed:
        bound = out.with_name(f"{out.name}_{name}")
        if not bound.is_dir():
            _run([str(BIN / "unidextok-deploy"), f"--checkpoint={checkpoint}", f"--robot={robot}",
                  f"--output={bound}"], out.with_name(f"{out.name}_{name}_deploy.log"))  # fmt: skip
        checkpoint = bound
    result = out.with_name(f"{out.name}_{name}_eval.json")
    _run([sys.executable, str(Path(__file__).with_name("eval_policy.py")), f"--checkpoint={checkpoint}",
          f"--dataset={robot}", f"--output={result}"], out.with_name(f"{out.name}_{name}_eval.log"))  # fmt: skip
    return json.loads(result.read_text())


# ---------------------------------------------------------------------------------------------
# the experiment
# ---------------------------------------------------------------------------------------------
def run(cfg: MixTrainConfig) -> dict:
    from experiments.policy_data import recorded_test_episodes
    from experiments.unseen_data import converted_g1
    from lerobot_unidextok.conversion.mix import MixOptions, action_delta_stats, mix
    from lerobot_unidextok.data import UdhmDatasetMeta
    from lerobot_unidextok.data.record import write_record

    t0 = time.time()
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    target = Path(cfg.target) if cfg.target else converted_g1(cfg.cache_dir)
    others = other_robots(cfg, Path(cfg.cache_dir) / f"{NAME}_{cfg.l10_poses}_{cfg.other_episodes}x{cfg.other_frames}")
    g1 = UdhmDatasetMeta(target)
    hands_root = target_hands(cfg)
    test_eps = recorded_test_episodes(target)
    train_eps = np.random.default_rng(0).permutation(np.setdiff1d(np.arange(g1.total_episodes), test_eps)).tolist()
    lengths = g1.episode_lengths
    other_frames = [sum(n for e, n in UdhmDatasetMeta(o).episode_lengths.items()
                        if e not in UdhmDatasetMeta(o).record.test_episodes) for o in others]  # fmt: skip
    jobs = []  # (target episodes, arm, seed, dataset, repo id, episodes, flags)
    for n in cfg.target_episodes:
        chosen = sorted(train_eps[:n])
        # the target as half the training frames: its chosen episodes repeated up to the others' frames
        repeats = max(1, round(sum(other_frames) / sum(lengths[e] for e in chosen)))
        g1_train = sum(n_ for e, n_ in lengths.items() if e not in test_eps)
        root = folder / f"mix_{n}"
        if not (root / "meta" / "unidextok_conversion.json").is_file():
            mix(MixOptions(inputs=[str(target), *map(str, others)], root=str(root), repo_id=f"local/mix_{n}",
                           weights=[repeats * g1_train, *other_frames], weights_by="copies", progress=False))  # fmt: skip
        record = UdhmDatasetMeta(root).record
        mixed_eps = [e.episode_index for e in record.episodes if e.split == "train"
                     and (e.origin["mix_source"] != 0 or e.origin["source_episode_index"] in chosen)]  # fmt: skip
        # the per-hand scale from the episodes trained on (the mix records it over every training episode)
        record.action_delta_stats = action_delta_stats(root, mixed_eps)
        write_record(root, record)
        data = {"target": (target, "local/g1_udhm", chosen), "hands": (hands_root, "local/g1_hands", chosen),
                "mix": (root, f"local/mix_{n}", mixed_eps)}  # fmt: skip
        for seed in cfg.seeds:
            for arm in cfg.arms:
                kind, flags = ARM_RECIPES[arm]
                if kind in data and data[kind][0] is not None:
                    path, repo, eps = data[kind]
                    jobs.append(dict(n=n, arm=arm, kind=kind, seed=seed, data=path, repo=repo, eps=eps, flags=flags))
    l10 = others[0]
    l10_train = sorted(set(UdhmDatasetMeta(l10).episode_lengths) - set(UdhmDatasetMeta(l10).record.test_episodes))
    jobs += [
        dict(n=0, arm=arm, kind="l10", seed=seed, data=l10, repo="local/l10_udhm", eps=l10_train, flags=flags)
        for seed in cfg.seeds
        for arm, (kind, flags) in ARM_RECIPES.items()
        if kind == "l10" and arm in cfg.arms
    ]  # the second robot alone: the same recipe on all its training episodes

    def one(job: dict) -> dict:
        arm, n, seed = job["arm"], job["n"], job["seed"]
        out = folder / f"{arm}_{n}_s{seed}"
        logger.info("%s (%d target episodes), seed %d: lerobot-train (%d steps)", arm, n, seed, cfg.steps)
        c0 = time.time()
        checkpoint = train(job["data"], job["repo"], job["eps"], out, seed, cfg.steps, *MEASURED_WITH, *job["flags"])
        wall = time.time() - c0
        robots = (
            {"g1": target, "l10": l10}
            if job["kind"] == "mix"
            else {"l10" if job["kind"] == "l10" else "g1": job["data"]}
        )
        scores = {
            name: score(checkpoint, robot, name, out, mixed=job["kind"] == "mix") for name, robot in robots.items()
        }
        return {"arm": arm, "target_episodes": n, "seed": seed, "train_episodes": len(job["eps"]),
                "train_wall_s": round(wall, 1), "errors": {k: v["policy"] for k, v in scores.items()},
                "copy_state": {k: v["copy_state"] for k, v in scores.items()},
                "test_episodes": {k: v["episodes"] for k, v in scores.items()}}  # fmt: skip

    with ThreadPoolExecutor(max_workers=cfg.jobs) as pool:
        runs = list(pool.map(one, jobs))
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "test_episodes": list(map(int, test_eps)),
              "target": str(cfg.target) if cfg.target else "real G1 + Inspire (g1-inspire, converted)",
              "train_episode_order": train_eps,
              "others": {"linkerhand_l10": f"{cfg.l10_poses} poses, synthetic motion", "xhand1": "synthetic"},
              "summary": summarise(runs, cfg), "runs": runs,
              "git_commit": git_commit(), "wall_seconds": round(time.time() - t0, 1),
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    result["command"] = command_line(cfg)
    result["provenance"] = {
        "data": {"source": "datasets" if cfg.target else "real", "synthetic_sample": False,
                 "datasets": [result["target"], *(f"{h} robot ({label})" for h, label in result["others"].items())],
                 "train_rows": f"target {min(cfg.target_episodes)}-{max(cfg.target_episodes)} episodes + the others",
                 "test_rows": int(sum(lengths[e] for e in test_eps)), "hands": sorted({h for t in g1.hand_types for h in t.split(",")})},
        "preset": "act_udt_cpu.yaml (lerobot-train)", "seed": cfg.seeds, "git_commit": result["git_commit"],
        "config": {"steps": cfg.steps}, "wall_seconds": result["wall_seconds"], "date_utc": result["date_utc"],
    }  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def command_line(cfg: MixTrainConfig) -> str:
    """`python experiments/mix_lerobot_train.py` with the flags of the settings that differ from the defaults."""
    default = MixTrainConfig()
    flags = [f"--{f.name}={json.dumps(getattr(cfg, f.name)).replace(' ', '')}"
             for f in dataclasses.fields(cfg) if getattr(cfg, f.name) != getattr(default, f.name)]  # fmt: skip
    return " ".join([f"python experiments/{NAME}.py", *flags])


def summarise(runs: list[dict], cfg: MixTrainConfig) -> dict:
    """{robot: {"<arm> <target episodes>": {metric: {mean, std}}, "copy_state": {metric: value}}} over seeds."""
    out: dict[str, dict] = {}
    for robot in ("g1", "l10"):
        scored = [r for r in runs if robot in r["errors"]]
        for key in dict.fromkeys(f"{r['arm']} {r['target_episodes']}" for r in scored):
            rows = [r["errors"][robot] for r in scored if f"{r['arm']} {r['target_episodes']}" == key]
            out.setdefault(robot, {})[key] = {m: {"mean": float(np.mean([r[m] for r in rows])),
                                                  "std": float(np.std([r[m] for r in rows]))} for m in METRICS}  # fmt: skip
        if scored:
            out[robot]["copy_state"] = scored[0]["copy_state"][robot]
    return out


def markdown(result: dict) -> str:
    cfg, s = result["config"], result["summary"]
    titles = {"g1": f"the real G1 ({result['target']}), test episodes {result['test_episodes']}",
              "l10": f"the LinkerHand L10 robot ({result['others']['linkerhand_l10']}), its converter's test episodes"}  # fmt: skip
    lines = [
        f"`lerobot-train` with act_udt_cpu.yaml ({cfg['steps']} steps, seeds {cfg['seeds']}) on a few of the G1's "
        "training episodes alone, on the L10 robot's training episodes alone, or on both mixed with an XHand1 robot "
        f"(unidextok-mix); mixed checkpoints bound to each robot (unidextok-deploy). Open-loop MAE "
        f"({result['wall_seconds'] / 60:.1f} min wall), hands in UDHM degrees and native units:", ""]  # fmt: skip
    for robot, title in titles.items():
        if robot not in s:
            continue
        rows = []
        for key, e in s[robot].items():
            if key == "copy_state":
                continue
            arm, n = key.split(" ")
            rows.append([n if n != "0" else "-", arm, *[f"{e[m]['mean']:.4f} +- {e[m]['std']:.4f}" if "native" in m
                                                        else f"{e[m]['mean']:.2f} +- {e[m]['std']:.2f}" for m in METRICS]])  # fmt: skip
        copy = s[robot]["copy_state"]
        rows.append(["-", "copy_state", *[f"{copy[m]:.4f}" if "native" in m else f"{copy[m]:.2f}" for m in METRICS]])
        lines += [f"Scored on {title}:", "", md_table(["G1 episodes", "arm", *METRICS], rows), ""]
    return "\n".join(lines).rstrip()


def main(argv: list[str] | None = None) -> None:
    runtime.cli(MixTrainConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
