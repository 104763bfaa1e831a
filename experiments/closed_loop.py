"""Closed loop: success rates of policies on simulated dexterous tasks, per hand, for the policy questions.

    python experiments/closed_loop.py                                    # 2 tasks x 3 hands x 8 arms x 3 seeds
    python experiments/closed_loop.py --tasks='[FingerPress-v0]' --hands='[shadow]' --seeds='[0]'
    python experiments/closed_loop.py --tasks='[FingerPress-v0]' --targets='[inspire_rh56_unitree]' \
        --arms='[alone,mix]' --demos='[10]' --seeds='[0]'            # one hand-task pair: its alone and mix arms

Data (`lerobot_env_unidextok`, 10 fps): per task and hand, `pool` scripted expert episodes recorded as a LeRobot v3
dataset in the hand's native units (`record.record`, what `unidextok-sim-record` runs), converted with
`unidextok-convert --source=lerobot` (semantic insertion, and `--mapping=append_pad` for the packed arm, no test
split: the test is the simulator), and mixed with `unidextok-mix --keep=all` (per target, task and mapping one mix of
every hand of `hands`; per left-out hand, a mix of the others). The conversion and mix run in this process through the
functions the CLIs call.
Policy: `act_udt_cpu.yaml` through LeRobot's own `lerobot-train` code (`lerobot.scripts.lerobot_train.train`, in
this process; its dataset items read once per process and then served from memory, `_MemoryFrames`) with
absolute actions (`udt_relative_actions=false`, `udt_copy_start=false`), `steps` updates at `batch_size`, and each
predicted chunk of 10 actions run before the next prediction (`n_action_steps=10`: a state-only policy that
re-plans every step stalls where the demonstrations pause); mixed checkpoints bound to the target hand with
`unidextok-deploy`'s `deploy`. Scored by LeRobot's
`lerobot-eval` rollout (`eval_policy_all`, sync envs, no video) on `eval_episodes` episodes drawn from seeds
`eval_seed` + i, the same episodes for every arm; success as the simulator decides it (`info["is_success"]`).

Arms, per task, target hand and seed (the target's demonstrations: a seed's random subset of its pool). The recipe
of every arm is the `<type>_udt` defaults (per-hand statistics, no loss on the slots a hand lacks, each input's share
as a loss weight, wrist actions in the hand's grasp-centre frame) unless its row says what it turns off:
- `alone_<n>` for n in `demos`: that hand's n demonstrations alone (its UDHM state); `alone_no_frame_<n>`: the same
  with wrist actions in the robot's wrist frame; `both_<n>`: the same with the hands as the `<type>_udt` default
  gives them, the UDHM state and the tokenizer's (`--tokenizer`) tokens in its own encoding (`udt_hand_input=both`);
- `mix_<n>` for n in `mix_demos`: the target's n demonstrations and every demonstration of the other hands, in one
  UDHM layout (semantic insertion), the hand's identity one-hot (unidextok-mix, each episode written once, the
  target's share of every batch's loss `target_share`), bound to the target;
- `mix_rule_<n>`: `mix_<n>` trained for the budget rule's updates, `steps / target_share` (the target's frames seen
  as often as when it trains alone for `steps`), where every other arm trains `steps` (matched compute);
- `pooled_<n>`: the recipe before 2026-12-05 on the same demonstrations: LeRobot's one set of statistics for the
  mix, every slot trained, the target's pool written `target_weight` times (copies), the wrist frame of the robot;
- the ablations, each `mix_<n>` with one mechanism off: `no_hand_norm_<n>` (LeRobot's statistics),
  `state_norm_<n>` (the state per hand too, the default until commit 7d0a25a), `no_mask_<n>` (every slot
  trained), `copies_<n>` (the `target_weight` copies instead of the share),
  `no_frame_<n>` (wrist actions in the robot's wrist frame); these, `alone_no_frame`, `mix_rule` and `pooled` run on
  `ablation_targets` (default every target: `PRUNED`);
- `packed_<n>`: `mix_<n>` with each hand's native joints packed at the front of the block and zero-padded (on the
  finger task only: the grasp closes every finger together, and there the two tied in the first table);
- `tokens_nearest_<n>`, `tokens_search_<n>`: `mix_<n>` with the hands given to the model only as the tokenizer's
  (`--tokenizer`) tokens (dequantized; the nearest codes, or the tokenizer's own encoding unless `encoding` is
  set) instead of the UDHM state (`udt_hand_input=tokens`; every other arm reads the state);
- `zero_shot`: every demonstration of the other hands, none of the target's, bound with `--zero_shot=true`;
  `zero_shot_no_frame`: the same in the robots' wrist frames.
Also measured: the scripted expert on the same evaluation episodes. `plot` draws success against the target's
demonstrations per hand and task (`closed_loop.png`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import WHERE_TO, git_commit, md_table
from lerobot_env_unidextok.columns import TASKS as SIM_TASK_IDS
from lerobot_unidextok.conversion.mix import budget_steps
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig

logger = logging.getLogger(__name__)
NAME = "closed_loop"
TASKS = ("GraspLift-v0", "FingerPress-v0")  # the default; --tasks takes any of the simulator's (SIM_TASK_IDS)
# the issue's three hands, then every other hand the simulator models (docs/lerobot.md "The hands' models")
HANDS = ("inspire_rh56_unitree", "shadow", "allegro", "leap", "xhand1", "linkerhand_l10")
# arm -> (its dataset, lerobot-train flags beyond the recipe's); the dataset: the target alone, the mix with the target's
# share (`mix`), the mix of the target's copies (`copies`), the packed mix, or the other hands without it
NO_FRAME = ("--policy.udt_wrist_frame=robot",)
POOLED = ("--policy.udt_hand_norm=off", "--policy.udt_mask_slots=false", *NO_FRAME)
ARMS: dict[str, tuple[str, tuple[str, ...]]] = {
    "alone": ("alone", ()),
    "alone_no_frame": ("alone", NO_FRAME),
    "both": ("alone", ()),
    "mix": ("mix", ()),
    "mix_rule": ("mix", ()),
    "pooled": ("copies", POOLED),
    "no_hand_norm": ("mix", ("--policy.udt_hand_norm=off",)),
    "state_norm": ("mix", ("--policy.udt_hand_norm_state=true",)),
    "no_mask": ("mix", ("--policy.udt_mask_slots=false",)),
    "copies": ("copies", ()),
    "no_frame": ("mix", NO_FRAME),
    "packed": ("packed", ('--policy.udt_range_check="off"',)),  # packed blocks are not UDHM: no range check
    "tokens_nearest": ("mix", ()),
    "tokens_search": ("mix", ()),
    "zero_shot": ("without", ()),
    "zero_shot_no_frame": ("without", NO_FRAME),
}
MIX_ARMS = tuple(a for a, (data, _) in ARMS.items() if data != "alone")
ABLATIONS = ("no_hand_norm", "state_norm", "no_mask", "copies", "no_frame")
# run on ablation_targets: the ablations, the old recipe and the budget rule's arm (10x the updates at a tenth)
PRUNED = (*ABLATIONS, "alone_no_frame", "pooled", "mix_rule")
FINGER_ONLY = ("packed",)  # the grasp closes every finger together: insertion and packing tie there (docs/lerobot.md)
EXPERT_NOISE_SEED = 2_000_000  # the expert's noise on evaluation episode i: this + i (never a recording's)
RECORD_SEED = 100_000  # recording: episode draws from RECORD_SEED + k, the expert's noise from RECORD_NOISE + k
RECORD_NOISE = 200_000


@dataclass
class ClosedLoopConfig:
    tasks: list[str] = field(default_factory=lambda: list(TASKS))
    hands: list[str] = field(default_factory=lambda: list(HANDS))
    # the hands scored as the target (every policy arm, the expert); empty = each of `hands`. The mixes still pool
    # every hand of `hands`: `--targets='[inspire_rh56_unitree]'` runs one hand-task pair of the full table
    targets: list[str] = field(default_factory=list)
    demos: list[int] = field(default_factory=lambda: [10, 25])  # target demonstrations of the `alone` arms
    mix_demos: list[int] = field(default_factory=lambda: [10])  # target demonstrations of the mix arms
    # the main table; docs/lerobot.md "Pooling hands" adds the ablations and the budget rule's arm
    arms: list[str] = field(default_factory=lambda: ["alone", "mix", "packed", "zero_shot"])
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    pool: int = 50  # expert episodes recorded per task and hand (the most `alone` trains on, a mix's other hands)
    # the target's share of every batch's loss in a mix (`unidextok-mix --weights`, as a loss weight); the other
    # hands share the rest equally. A tenth: with 10 target demonstrations among six hands' it beat half on 11 of
    # 12 pairs (tied on the 12th) and no weights on the grasp (docs/lerobot.md "Pooling hands"). 0 = no weights:
    # each episode once, the target at its frame share (`unidextok-mix` without --weights; no budget-rule arm)
    target_share: float = 0.1
    # the `pooled` and `copies` arms: how many times the mix writes the target's demonstrations (the recipe before
    # 2026-12-05): 10 of them x 10 make the target half of the frames beside two other hands' 50 each, 29 % beside
    # five
    target_weight: float = 10.0
    steps: int = 400  # lerobot-train updates per policy (`mix_rule`: steps / target_share)
    batch_size: int = 32
    n_action_steps: int = 10  # actions of each predicted chunk (act_udt_cpu.yaml: chunk 10) run before predicting again
    # the encoding of `tokens_search`: None = the shipped tokenizer's own, the package's default (greedy code search,
    # docs/tokenizer.md "Code search"); an EncodingConfig (--encoding.rounds=1 ...) replaces it. `tokens_nearest`
    # always uses the nearest codes.
    encoding: EncodingConfig | None = None
    tokenizer: str = DEFAULT_TOKENIZER  # the tokens arms' tokenizer (shipped id, folder or Hub repo id)
    eval_episodes: int = 50
    eval_seed: int = 1000  # lerobot-eval's default: episode i is drawn from eval_seed + i
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_sim"  # recorded, converted and mixed datasets (reused when complete)
    figure_to: str = ""  # also write the figure there (e.g. docs/images/closed_loop.png)
    # the targets of the ablations, the old recipe and the budget rule (`PRUNED`; empty = every target): prune
    # pairs, not seeds or episodes
    ablation_targets: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        for name, given, allowed in (("tasks", self.tasks, SIM_TASK_IDS), ("arms", self.arms, tuple(ARMS))):
            unknown = sorted(set(given) - set(allowed))
            if unknown:
                raise ValueError(f"unknown {name} {unknown}; choose from {list(allowed)}")
        for name, demos in (("demos", self.demos), ("mix_demos", self.mix_demos)):
            if not demos or any(not 1 <= d <= self.pool for d in demos):
                raise ValueError(f"{name} {demos} must be 1..pool ({self.pool})")
        if not 0 <= self.target_share < 1:
            raise ValueError(f"target_share must be in [0, 1) (0: no weights), got {self.target_share}")
        if self.target_share == 0 and "mix_rule" in self.arms:
            raise ValueError("mix_rule needs a target share to divide the updates by: --target_share in (0, 1)")
        stray = sorted(set(self.ablation_targets) - set(self.hands))
        if stray:
            raise ValueError(f"ablation_targets {stray} are not among hands {self.hands}")
        stray = sorted(set(self.targets) - set(self.hands))
        if stray:
            raise ValueError(f"targets {stray} are not among hands {self.hands}; a target must be one of the pooled hands")
        if len(self.hands) < 2 and set(self.arms) & set(MIX_ARMS):
            raise ValueError("the mix arms need at least two hands: --hands='[a,b]' or --arms='[alone]'")

    @property
    def target_hands(self) -> list[str]:
        return [h for h in self.hands if h in self.targets] if self.targets else list(self.hands)


# ---------------------------------------------------------------------------------------------
# data: record, convert, mix (cached)
# ---------------------------------------------------------------------------------------------
def _done(folder: Path) -> bool:
    return (folder / "meta" / "info.json").is_file()


def recorded(cfg: ClosedLoopConfig, task: str, hand: str) -> dict:
    """The native expert dataset of (task, hand) and its conversions: {"native", "semantic", "packed": Path, ...}."""
    from lerobot_env_unidextok.columns import HAND_PREFIX
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    base = Path(cfg.cache_dir) / task / hand
    native = base / f"native_{cfg.pool}"
    info = {"native": native}
    if not _done(native):
        shutil.rmtree(native, ignore_errors=True)
        cpu = time.process_time()
        report = record(RecordConfig(hand=hand, task=task, episodes=cfg.pool, root=str(native), seed=RECORD_SEED,
                                     noise_seed=RECORD_NOISE, repo_id=f"sim/{hand}_{task}"))  # fmt: skip
        (base / f"native_{cfg.pool}.json").write_text(json.dumps(
            {"episodes": report.episodes, "attempts": report.attempts, "frames": report.frames,
             "cpu_s": round(time.process_time() - cpu, 1)}))  # fmt: skip
    info["record"] = json.loads((base / f"native_{cfg.pool}.json").read_text())
    info["cpu_s"] = info["record"]["cpu_s"]
    for mapping, key in (("semantic", "semantic"), ("append_pad", "packed")):
        out = base / f"{key}_{cfg.pool}"
        if not _done(out):
            shutil.rmtree(out, ignore_errors=True)
            cpu = time.process_time()
            convert(ConvertOptions(source="lerobot", input=str(native), root=str(out), repo_id=f"sim/{hand}_{task}_{key}",
                                   source_options={"hands": {"right": f"{hand}:{HAND_PREFIX}"}}, mapping=mapping,
                                   test_fraction=0.0, progress=False))  # fmt: skip
            (out.parent / f"{out.name}.cpu").write_text(f"{time.process_time() - cpu:.1f}")
        info[key] = out
        info["cpu_s"] += float((out.parent / f"{out.name}.cpu").read_text())
    return info


def mixed(cfg: ClosedLoopConfig, task: str, inputs: list[Path], name: str, weights: list[float] | None = None,
          weights_by: str = "sampling") -> Path:
    """`unidextok-mix --keep=all` of `inputs` (a training-frame share per input with `weights`, honoured by
    `weights_by`: sampling, a share recorded; copies, episodes written again)."""
    from lerobot_unidextok.conversion.mix import MixOptions, mix

    out = Path(cfg.cache_dir) / task / name
    if not _done(out):
        shutil.rmtree(out, ignore_errors=True)
        cpu = time.process_time()
        mix(MixOptions(inputs=[str(p) for p in inputs], root=str(out), repo_id=f"sim/{task}_{name}", keep="all",
                       weights=weights or [], weights_by=weights_by, progress=False))  # fmt: skip
        (out.parent / f"{out.name}.cpu").write_text(f"{time.process_time() - cpu:.1f}")
    return out


def mix_cpu_s(root: Path) -> float:
    return float((root.parent / f"{root.name}.cpu").read_text())


def mix_episodes(root: Path) -> dict[str, dict[int, list[int]]]:
    """{hand: {source episode: [its mixed episodes (the copies `--weights` wrote)]}} of a mix (from its record)."""
    from lerobot_unidextok.data.meta import UdhmDatasetMeta

    out: dict[str, dict[int, list[int]]] = {}
    for ep in UdhmDatasetMeta(root).record.episodes:
        source = int(ep.origin["source_episode_index"])
        out.setdefault(ep.hand_type.split(",")[0], {}).setdefault(source, []).append(ep.episode_index)
    return out


def every_episode(by_source: dict[int, list[int]]) -> list[int]:
    return sorted(e for copies in by_source.values() for e in copies)


def subset(n: int, pool: int, seed: int) -> list[int]:
    """The seed's `n` of `pool` demonstrations (sorted)."""
    return sorted(np.random.default_rng(seed).permutation(pool)[:n].tolist())


# ---------------------------------------------------------------------------------------------
# train (LeRobot's lerobot-train code), bind, evaluate (LeRobot's lerobot-eval rollout)
# ---------------------------------------------------------------------------------------------
def train_policy(cfg: ClosedLoopConfig, root: Path, episodes: list[int], out: Path, seed: int, flags: list[str],
                 steps: int | None = None) -> Path:
    """Train act_udt_cpu.yaml on `episodes` of `root` for `steps` (default `cfg.steps`); the `pretrained_model`."""
    import draccus
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.scripts.lerobot_train import train

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies, as LeRobot's CLIs discover them)
    from lerobot_unidextok.configs import resolve_config_path

    model = out / "checkpoints" / "last" / "pretrained_model"
    if (model / "model.safetensors").is_file():
        return model
    shutil.rmtree(out, ignore_errors=True)
    _serve_frames_from_memory()
    steps = steps or cfg.steps
    args = [f"--dataset.repo_id=sim/{root.name}", f"--dataset.root={root}", f"--dataset.episodes={episodes}",
            "--policy.udt_relative_actions=false", "--policy.udt_copy_start=false", f"--steps={steps}",
            f"--batch_size={cfg.batch_size}", f"--policy.n_action_steps={cfg.n_action_steps}", f"--save_freq={steps}",
            f"--log_freq={max(steps, 1)}", f"--seed={seed}", f"--output_dir={out}", *flags]  # fmt: skip
    train(draccus.parse(TrainPipelineConfig, config_path=resolve_config_path("lerobot/act_udt_cpu"), args=args))
    return model


_FRAMES: dict[tuple, dict] = {}  # (dataset root, frame index, delta timestamps) -> LeRobot's item


class _MemoryFrames:
    """A LeRobotDataset whose items (its own `__getitem__`: the frame and its action chunk, padded at the episode's
    end) are read once per process, then served from memory. lerobot-train's loader reads a frame's chunk anew
    for every batch (75 % of an update's CPU here); the sampler, batches and everything after are unchanged."""

    def __init__(self, dataset) -> None:
        self._dataset = dataset
        rel = dataset.absolute_to_relative_idx
        self._absolute = {r: a for a, r in rel.items()} if rel is not None else None
        self._key = (str(dataset.root), json.dumps(dataset.delta_timestamps, sort_keys=True, default=str))

    def __getattr__(self, name: str):
        return getattr(self._dataset, name)

    def __len__(self) -> int:
        return len(self._dataset)

    def __getitem__(self, idx: int) -> dict:
        key = (*self._key, self._absolute[idx] if self._absolute is not None else idx)
        if key not in _FRAMES:
            _FRAMES[key] = self._dataset[idx]
        return _FRAMES[key]


def _serve_frames_from_memory() -> None:
    import lerobot.scripts.lerobot_train as lerobot_train

    make = lerobot_train.make_train_eval_datasets
    if getattr(make, "_memory_frames", False):
        return

    def make_train_eval_datasets(cfg):
        train, evaluation = make(cfg)
        return _MemoryFrames(train), evaluation

    make_train_eval_datasets._memory_frames = True
    lerobot_train.make_train_eval_datasets = make_train_eval_datasets


def bind(checkpoint: Path, robot: Path, out: Path, zero_shot: bool = False) -> Path:
    from lerobot_unidextok.policies.deploy import deploy

    if not (out / "model.safetensors").is_file():
        shutil.rmtree(out, ignore_errors=True)
        deploy(checkpoint, robot, out, zero_shot=zero_shot)
    return out


def evaluate(cfg: ClosedLoopConfig, checkpoint: Path, task: str, hand: str) -> dict:
    """What `lerobot-eval --policy.path=<checkpoint> --env.type=unidextok` computes, without videos."""
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.factory import make_env, make_env_pre_post_processors
    from lerobot.envs.utils import close_envs
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies and steps, as lerobot-eval discovers them)
    from lerobot_env_unidextok.configuration import UniDexTokEnvConfig

    env_cfg = UniDexTokEnvConfig(task=task, hand=hand)
    envs = make_env(env_cfg, n_envs=min(cfg.eval_episodes, 50), use_async_envs=False)
    policy_cfg = PreTrainedConfig.from_pretrained(checkpoint)
    policy_cfg.pretrained_path, policy_cfg.device = str(checkpoint), "cpu"
    policy = make_policy(cfg=policy_cfg, env_cfg=env_cfg).eval()
    pre, post = make_pre_post_processors(policy_cfg, pretrained_path=str(checkpoint),
                                         preprocessor_overrides={"device_processor": {"device": "cpu"},
                                                                 "rename_observations_processor": {"rename_map": {}}})  # fmt: skip
    env_pre, env_post = make_env_pre_post_processors(env_cfg=env_cfg, policy_cfg=policy_cfg)
    with torch.no_grad():
        info = eval_policy_all(envs, policy, env_pre, env_post, pre, post, cfg.eval_episodes,
                               max_episodes_rendered=0, start_seed=cfg.eval_seed)  # fmt: skip
    close_envs(envs)
    overall = info["overall"]
    n = int(overall["n_episodes"])
    return {"successes": round(float(overall["pc_success"]) * n / 100), "episodes": n}


def expert_success(cfg: ClosedLoopConfig, task: str, hand: str) -> dict:
    """The scripted expert on the evaluation episodes (its own noise)."""
    from lerobot_env_unidextok.env import UniDexTokEnv
    from lerobot_env_unidextok.record import expert_episode

    cpu = time.process_time()
    env = UniDexTokEnv(hand, task, render_mode=None)
    wins = sum(expert_episode(env, cfg.eval_seed + i, EXPERT_NOISE_SEED + i, 50)[2] for i in range(cfg.eval_episodes))
    return {"successes": int(wins), "episodes": cfg.eval_episodes, "cpu_s": round(time.process_time() - cpu, 1)}


# ---------------------------------------------------------------------------------------------
# the runs
# ---------------------------------------------------------------------------------------------
def jobs(cfg: ClosedLoopConfig) -> list[dict]:
    """Every (task, target, seed, arm label, target demonstrations) to run: `alone_<n>` for n in demos, `<arm>_<n>`
    for n in mix_demos, `zero_shot*` once."""
    out = []
    for task in cfg.tasks:
        for hand in cfg.target_hands:
            for seed in cfg.seeds:
                for arm in (a for a in ARMS if a in cfg.arms):
                    if arm in PRUNED and cfg.ablation_targets and hand not in cfg.ablation_targets:
                        continue
                    if arm in FINGER_ONLY and task != "FingerPress-v0":
                        continue
                    counts = [0] if ARMS[arm][0] == "without" else cfg.demos if ARMS[arm][0] == "alone" else cfg.mix_demos
                    out += [{"task": task, "hand": hand, "seed": seed, "arm": arm_label(arm, n), "kind": arm, "demos": n}
                            for n in counts]  # fmt: skip
    return out


def arm_label(arm: str, demos: int) -> str:
    return arm if ARMS[arm][0] == "without" else f"{arm}_{demos}"


def encoding_flags(encoding: EncodingConfig | None) -> list[str]:
    """The lerobot-train flags giving a `<type>_udt` policy this encoding override (None: none, the tokenizer's)."""
    return [] if encoding is None else [f"--policy.udt_encoding.{k}={v}" for k, v in dataclasses.asdict(encoding).items()]


def arm_flags(cfg: ClosedLoopConfig, arm: str, task: str) -> list[str]:
    """The arm's lerobot-train flags: its hand view (the UDHM state, or the tokenizer's tokens) and what it turns off.
    On a task that grasps nothing (`Task.grasps`) every arm keeps the robot's wrist frame, as a recording made since
    2026-12-05 carries no grasp centre there (one made before carried it: the flag makes both the same)."""
    from lerobot_env_unidextok.task_classes import TASKS as SIM_TASKS

    # the token view is zeroed for the state arms, so the tokenizer behind it cannot matter: an untrained one (what
    # act_udt_cpu.yaml gave until 2026-12-04) through its nearest codes, the cheapest
    state = ["--policy.udt_hand_input=state", "--policy.udt_pretrained=null", *encoding_flags(NEAREST_CODES)]
    tokens = ["--policy.udt_hand_input=tokens", f"--policy.udt_pretrained={cfg.tokenizer}"]
    view = {"tokens_nearest": [*tokens, *encoding_flags(NEAREST_CODES)],
            "tokens_search": [*tokens, *encoding_flags(cfg.encoding)],
            "both": ["--policy.udt_hand_input=both", f"--policy.udt_pretrained={cfg.tokenizer}"],
            }.get(arm, state)  # fmt: skip
    own = list(ARMS[arm][1])
    return [*view, *own, *([] if SIM_TASKS[task].grasps or NO_FRAME[0] in own else NO_FRAME)]


def run_one(cfg: ClosedLoopConfig, job: dict, data: dict, folder: Path) -> dict:
    task, hand, seed, arm, label = job["task"], job["hand"], job["seed"], job["kind"], job["arm"]
    key = f"{task}/{hand}/{label}/seed{seed}"
    done = folder / "runs" / f"{key.replace('/', '__')}.json"
    if done.is_file():
        return json.loads(done.read_text())
    own = data[task][hand]
    target = subset(job["demos"], cfg.pool, seed) if job["demos"] else []
    out = folder / "policies" / task / hand / f"{label}_seed{seed}"
    flags, kind = arm_flags(cfg, arm, task), ARMS[arm][0]
    steps = budget_steps(cfg.steps, cfg.target_share) if arm == "mix_rule" else cfg.steps
    cpu0, t0 = time.process_time(), time.time()
    if kind == "alone":
        model = train_policy(cfg, own["semantic"], target, out, seed, flags)
        bound = model
    elif kind == "without":
        mix_root = data[task]["without"][hand]
        episodes = sorted(e for by_source in mix_episodes(mix_root).values() for e in every_episode(by_source))
        model = train_policy(cfg, mix_root, episodes, out, seed, flags)
        bound = bind(model, own["semantic"], out / "bound", zero_shot=True)
    else:
        mix_root = data[task][kind][hand]
        by_hand = mix_episodes(mix_root)
        chosen = [e for i in target for e in by_hand[hand][i]]
        episodes = sorted(chosen + [e for h, by_source in by_hand.items() if h != hand for e in every_episode(by_source)])
        model = train_policy(cfg, mix_root, episodes, out, seed, flags, steps)
        bound = bind(model, own["packed" if kind == "packed" else "semantic"], out / "bound")
    train_cpu = time.process_time() - cpu0
    cpu1 = time.process_time()
    scores = evaluate(cfg, bound, task, hand)
    result = {**job, **scores, "steps": steps, "train_cpu_s": round(train_cpu, 1),
              "eval_cpu_s": round(time.process_time() - cpu1, 1), "wall_s": round(time.time() - t0, 1)}  # fmt: skip
    done.parent.mkdir(parents=True, exist_ok=True)
    done.write_text(json.dumps(result))
    shutil.rmtree(out / "checkpoints" / "last" / "training_state", ignore_errors=True)
    logger.info("%s: %d/%d (%.0f CPU-s)", key, result["successes"], result["episodes"], train_cpu + result["eval_cpu_s"])
    return result


def prepare(cfg: ClosedLoopConfig) -> tuple[dict, dict]:
    """All datasets, and the CPU seconds spent making them (when they were made, so a rerun counts them too)."""
    data: dict = {}
    kinds = {ARMS[a][0] for a in cfg.arms}
    others = len(cfg.hands) - 1
    share = [cfg.target_share] + [(1 - cfg.target_share) / others] * others if others and cfg.target_share else []
    copies = [cfg.target_weight] + [1.0] * others
    # per target: its whole pool, the target first (the chosen demonstrations are selected at training); `mix` and
    # `packed` write each episode once and record the shares, `copies` writes the target's `target_weight` times
    tag = f"s{cfg.target_share:g}" if cfg.target_share else "frames"
    plans = {"mix": ("semantic", share, "sampling", tag),
             "packed": ("packed", share, "sampling", tag),
             "copies": ("semantic", copies, "copies", f"w{cfg.target_weight:g}")}  # fmt: skip
    for task in cfg.tasks:
        data[task] = {hand: recorded(cfg, task, hand) for hand in cfg.hands}
        for kind, (mapping, weights, weights_by, tag) in plans.items():
            if kind in kinds:
                data[task][kind] = {
                    hand: mixed(cfg, task, [data[task][h][mapping] for h in [hand, *(h for h in cfg.hands if h != hand)]],
                                f"mix_{mapping}_for_{hand}_{tag}", weights, weights_by)
                    for hand in cfg.target_hands
                }  # fmt: skip
        if "without" in kinds:
            data[task]["without"] = {
                hand: mixed(cfg, task, [data[task][h]["semantic"] for h in cfg.hands if h != hand], f"mix_without_{hand}")
                for hand in cfg.target_hands
            }  # fmt: skip
    cpu = 0.0
    for task in cfg.tasks:
        cpu += sum(data[task][h]["cpu_s"] for h in cfg.hands)
        for key in ("mix", "packed", "copies", "without"):
            cpu += sum(mix_cpu_s(root) for root in data[task].get(key, {}).values())
    return data, {"data_cpu_s": round(cpu, 1)}


def run(cfg: ClosedLoopConfig) -> dict:
    from lerobot_env_unidextok.success import wilson_interval

    t0, cpu0 = time.time(), time.process_time()
    folder = Path(cfg.output_root) / NAME
    data, costs = prepare(cfg)
    experts = {f"{t}/{h}": expert_success(cfg, t, h) for t in cfg.tasks for h in cfg.target_hands}
    runs = [run_one(cfg, job, data, folder) for job in jobs(cfg)]
    summary = summarise(runs, cfg)
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "runs": runs, "summary": summary,
              "experts": {k: {**v, "interval": wilson_interval(v["successes"], v["episodes"])} for k, v in experts.items()},
              "recording": {f"{t}/{h}": data[t][h]["record"] for t in cfg.tasks for h in cfg.hands},
              "costs": {**costs, "train_cpu_s": round(sum(r["train_cpu_s"] for r in runs), 1),
                        "eval_cpu_s": round(sum(r["eval_cpu_s"] for r in runs), 1),
                        "expert_cpu_s": round(sum(e["cpu_s"] for e in experts.values()), 1),
                        "runs_wall_s": round(sum(r["wall_s"] for r in runs), 1),
                        "this_process_cpu_s": round(time.process_time() - cpu0, 1)},
              "git_commit": git_commit(), "wall_seconds": round(time.time() - t0, 1),
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    # a command split over processes by task reuses finished runs: its wall time is at least theirs, summed
    result["wall_seconds"] = round(max(result["wall_seconds"], result["costs"]["runs_wall_s"]), 1)
    result["slot_scales"] = slot_scales(cfg, data)
    result["goals"] = goals(result, cfg)
    result["command"] = command_line(cfg)
    result["provenance"] = {
        "data": {"source": "sim", "synthetic_sample": False,
                 "datasets": [f"{cfg.pool} expert episodes per task and hand (lerobot_env_unidextok)"],
                 "train_rows": f"{min(cfg.demos)}-{max(cfg.demos)} target demonstrations (+ the other hands' {cfg.pool})",
                 "test_rows": f"{cfg.eval_episodes} closed-loop episodes per policy", "hands": list(cfg.hands)},
        "preset": "act_udt_cpu.yaml (lerobot-train), absolute actions", "seed": cfg.seeds,
        "git_commit": result["git_commit"], "config": {"steps": cfg.steps}, "wall_seconds": result["wall_seconds"],
        "date_utc": result["date_utc"],
    }  # fmt: skip
    folder.mkdir(parents=True, exist_ok=True)
    png = plot(result, folder / f"{NAME}.png")
    if cfg.figure_to:
        shutil.copyfile(png, cfg.figure_to)
    result["figures"] = {"success": str(png)}
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def slot_scales(cfg: ClosedLoopConfig, data: dict) -> dict:
    """Per task and target: the mean action std (rad) of the UDHM slots the target hand lacks and another hand has,
    in the mix the target trains in and in the mix of the others alone. LeRobot z-scores each action column by
    its dataset std; a target whose empty slots fill most rows of a mix shrinks that std, which weighs the other
    hands' values in those slots up in the loss."""
    from lerobot_unidextok import hands
    from lerobot_unidextok.data.meta import UdhmDatasetMeta

    out: dict = {}
    for task in cfg.tasks:
        mix = data[task].get("copies") or data[task].get("mix")  # the pooled arm's mix when it ran
        if mix is None or "without" not in data[task]:
            continue
        for hand in cfg.target_hands:
            lacks = ~hands.get(hand).active_mask & np.any([hands.get(h).active_mask for h in cfg.hands if h != hand], 0)
            if not lacks.any():
                continue
            cols = [f"right_{j}" for j, lacked in zip(_udhm_names(), lacks, strict=True) if lacked]
            scale = {}
            for key, root in (("mix", mix[hand]), ("others_only", data[task]["without"][hand])):
                meta = UdhmDatasetMeta(root)
                names = meta.names("action")
                std = np.asarray(json.loads((Path(root) / "meta" / "stats.json").read_text())["action"]["std"])
                scale[key] = float(np.mean([std[names.index(c)] for c in cols]))
            out.setdefault(task, {})[hand] = {"slots": int(lacks.sum()), **scale}
    return out


def _udhm_names() -> tuple[str, ...]:
    from lerobot_unidextok.constants import UDHM_JOINT_NAMES

    return UDHM_JOINT_NAMES


def summarise(runs: list[dict], cfg: ClosedLoopConfig) -> dict:
    """{task: {hand: {arm: {"mean", "std" (over seeds, %), "successes", "episodes" (pooled)}}}}."""
    from lerobot_env_unidextok.success import wilson_interval

    out: dict = {}
    for r in runs:
        out.setdefault(r["task"], {}).setdefault(r["hand"], {}).setdefault(r["arm"], []).append(r)
    for by_hand in out.values():
        for by_arm in by_hand.values():
            for arm, rows in by_arm.items():
                rates = [100 * r["successes"] / r["episodes"] for r in rows]
                k, n = sum(r["successes"] for r in rows), sum(r["episodes"] for r in rows)
                by_arm[arm] = {"mean": float(np.mean(rates)), "std": float(np.std(rates)), "seeds": len(rows),
                               "successes": k, "episodes": n, "interval": [100 * x for x in wilson_interval(k, n)]}  # fmt: skip
    return out


def goals(result: dict, cfg: ClosedLoopConfig) -> list[dict]:
    """The issue's goals (#47), each with the figure it is judged on, whether it is met and the figures that say
    why; `None` value when the arms it needs did not run."""
    s, out = result["summary"], []
    n, more = cfg.mix_demos[0], next((d for d in cfg.demos if d > cfg.mix_demos[0]), None)
    mix, alone, scales = f"mix_{n}", f"alone_{n}", result.get("slot_scales", {})

    def rate(arms: dict, arm: str) -> str:
        a = arms.get(arm)
        return f"{a['mean']:.0f} % ({a['interval'][0]:.0f}-{a['interval'][1]:.0f})" if a else "-"

    def goal(text: str, value: float, met: bool, why: str = "") -> None:
        out.append({"goal": text, "value": value, "met": bool(met), "why": why})

    pairs = [(task, hand, arms) for task, by_hand in s.items() for hand, arms in by_hand.items()]
    for task, hand, arms in pairs:
        if mix in arms and alone in arms:
            gain = arms[mix]["mean"] - arms[alone]["mean"]
            scale = scales.get(task, {}).get(hand)
            why = (f"mix {rate(arms, mix)}, alone {rate(arms, alone)}, pooled recipe {rate(arms, f'pooled_{n}')}, "
                   f"zero-shot {rate(arms, 'zero_shot')}"
                   + (f"; the {scale['slots']} slots it lacks scaled {scale['mix']:.3f} rad in the pooled mix, "
                      f"{scale['others_only']:.3f} without it" if scale else ""))  # fmt: skip
            goal(f"{task} {hand}: mix beats the hand alone by >= 10 points at {n} demos", gain, gain >= 10, why)
        if "zero_shot" in arms:
            worse = [a for a in arms if a.split("_")[-1].isdigit() and a.startswith("mix_")
                     and arms[a]["mean"] < arms["zero_shot"]["mean"]]  # fmt: skip
            goal(f"{task} {hand}: no policy with target demonstrations below zero-shot", float(len(worse)), not worse,
                 f"zero-shot {rate(arms, 'zero_shot')}" + (f"; below it: {', '.join(f'{a} {rate(arms, a)}' for a in worse)}"
                                                           if worse else ""))  # fmt: skip
        if "zero_shot" in arms and alone in arms:
            half = arms[alone]["mean"] / 2
            goal(f"{task} {hand}: zero-shot at least half the hand alone at {n} demos", arms["zero_shot"]["mean"],
                 arms["zero_shot"]["mean"] >= half, f"zero-shot {rate(arms, 'zero_shot')}, half of alone {half:.0f} %, "
                 f"without the grasp-centre frame {rate(arms, 'zero_shot_no_frame')}")  # fmt: skip
        if task == "FingerPress-v0" and mix in arms and f"packed_{n}" in arms:
            gain = arms[mix]["mean"] - arms[f"packed_{n}"]["mean"]
            goal(f"{task} {hand}: semantic insertion beats packing by >= 10 points", gain, gain >= 10,
                 f"semantic {rate(arms, mix)}, packed {rate(arms, f'packed_{n}')}")  # fmt: skip
    both = [(a[mix]["mean"], a[f"alone_{more}"]["mean"]) for _, _, a in pairs if mix in a and f"alone_{more}" in a]
    if both:
        m, a = np.mean([b[0] for b in both]), np.mean([b[1] for b in both])
        goal(f"mix at {n} demos reaches the hand alone at {more}, on average over {len(both)} pairs", float(m - a),
             m >= a, f"mix {m:.1f} %, alone at {more} {a:.1f} %")
    for key, e in result["experts"].items():
        value = 100 * e["successes"] / e["episodes"]
        goal(f"{key.replace('/', ' ')}: expert at least 95 %", value, value >= 95, f"{e['successes']}/{e['episodes']}")
    return out




def command_line(cfg: ClosedLoopConfig) -> str:
    default = ClosedLoopConfig()
    flags = [f"--{f.name}={json.dumps(getattr(cfg, f.name)).replace(' ', '')}" for f in dataclasses.fields(cfg)
             if f.name not in WHERE_TO and getattr(cfg, f.name) != getattr(default, f.name)]  # fmt: skip
    return " ".join([f"python experiments/{NAME}.py", *flags])


ARM_TITLES = {"mix": "mix", "mix_rule": "mix, budget rule", "pooled": "mix, pooled statistics (before 2026-12-05)",
              "no_hand_norm": "mix without per-hand statistics", "state_norm": "mix, per-hand statistics for the state too", "no_mask": "mix without masked slots",
              "copies": "mix with copies, not shares", "no_frame": "mix without the grasp-centre frame",
              "packed": "mix, packed native", "tokens_nearest": "mix, tokens (nearest)",
              "tokens_search": "mix, tokens (tokenizer's encoding)", "zero_shot": "zero-shot (other hands only)",
              "zero_shot_no_frame": "zero-shot without the grasp-centre frame", "alone": "alone",
              "alone_no_frame": "alone without the grasp-centre frame",
              "both": "alone, state and tokens (the default view)"}  # fmt: skip


def arm_title(label: str) -> str:
    kind, _, demos = label.rpartition("_")
    if not demos.isdigit():
        return ARM_TITLES.get(label, label)
    return f"{ARM_TITLES.get(kind, kind)}, {demos} demos"


def share_words(steps: int, target_share: float) -> str:
    """How a run's mixes weight the target, for its table's caption (0: no weights)."""
    if not target_share:
        return "(no budget-rule arm), the target at its frame share of a mix (no weights)"
    return f"(the budget rule's arm: {budget_steps(steps, target_share)}), the target's share of a mix {target_share:g}"


def markdown(result: dict) -> str:
    cfg, s, costs = result["config"], result["summary"], result["costs"]
    cpu_min = sum(costs[k] for k in ("data_cpu_s", "train_cpu_s", "eval_cpu_s", "expert_cpu_s")) / 60
    lines = [
        f"Success rate (%) in closed loop, mean +- std over seeds {cfg['seeds']} ({cfg['eval_episodes']} episodes each, "
        f"the same episodes for every policy), and the 95 % Wilson interval of the pooled episodes. Policies: "
        f"act_udt_cpu.yaml through LeRobot's lerobot-train code, {cfg['steps']} steps at batch {cfg['batch_size']} "
        f"{share_words(cfg['steps'], cfg['target_share'])}, "
        f"absolute actions, chunks of {cfg['n_action_steps']} actions; mixes bound with unidextok-deploy. {cpu_min:.1f} "
        f"CPU-minutes in all ({costs['data_cpu_s']:.0f} s data, {costs['train_cpu_s']:.0f} s training, "
        f"{costs['eval_cpu_s']:.0f} s evaluation, {costs['expert_cpu_s']:.0f} s experts); the policies took "
        f"{costs['runs_wall_s'] / 60:.0f} min of wall time summed over them (on shared cores; runs already done are "
        "reused, so one command may be split over processes by task).", ""]  # fmt: skip
    for task, by_hand in s.items():
        hands = list(by_hand)
        arms = list(dict.fromkeys(a for h in hands for a in by_hand[h]))
        rows = []
        for arm in ["expert", *arms]:
            cells = []
            for hand in hands:
                if arm == "expert":
                    e = result["experts"].get(f"{task}/{hand}")
                    cells.append(f"{100 * e['successes'] / e['episodes']:.0f} ({100 * e['interval'][0]:.0f}-"
                                 f"{100 * e['interval'][1]:.0f})" if e else "-")  # fmt: skip
                    continue
                e = by_hand[hand].get(arm)
                cells.append(f"{e['mean']:.1f} +- {e['std']:.1f} ({e['interval'][0]:.0f}-{e['interval'][1]:.0f})" if e else "-")
            title = "scripted expert" if arm == "expert" else arm_title(arm)
            rows.append([title, *cells])
        lines += [f"**{task}**:", "", md_table(["policy", *hands], rows), ""]
    scales = result.get("slot_scales", {})
    if scales:
        lines += ["Action scale of the UDHM slots a target lacks (mean std, rad, of those action columns; LeRobot z-scores "
                  "each column by it in the pooled arm): in the mix it trains in / in the other hands' mix:", ""]
        lines += [f"- {task} {hand} ({e['slots']} slots): {e['mix']:.3f} / {e['others_only']:.3f}"
                  for task, by_hand in scales.items() for hand, e in by_hand.items()]
        lines += [""]
    lines += ["Goals:", ""]
    lines += [f"- {'met' if g['met'] else 'NOT met'}: {g['goal']} ({g['value']:+.1f}; {g['why']})" if g.get("why")
              else f"- {'met' if g['met'] else 'NOT met'}: {g['goal']} ({g['value']:+.1f})" for g in result["goals"]]
    return "\n".join(lines).rstrip()


CURVES = (("alone", "#0074d9", "o", "alone"), ("mix", "#2ecc40", "s", "mix"), ("mix_rule", "#3d9970", "D", "mix, budget rule"),
          ("pooled", "#ff4136", "^", "mix, pooled statistics (before)"))  # fmt: skip


def plot(result: dict, out_path: Path) -> Path:
    """Success (%) against the target's demonstrations, one panel per task (rows) and target hand (columns): the
    hand alone, the mix (and its other recipes) as curves, zero-shot at 0 (hollow: without the grasp-centre frame),
    the expert as a dashed line; bars are the 95 % Wilson intervals of the pooled episodes."""
    from matplotlib.figure import Figure

    from lerobot_unidextok.viz.style import save

    s = result["summary"]
    tasks = list(s)
    hands = list(dict.fromkeys(h for t in tasks for h in s[t]))
    fig = Figure(figsize=(3.6 * len(hands), 3.3 * len(tasks) + 0.6))
    handles, labels = [], []
    for r, task in enumerate(tasks):
        for c, hand in enumerate(hands):
            ax = fig.add_subplot(len(tasks), len(hands), r * len(hands) + c + 1)
            arms = s[task].get(hand, {})
            for kind, color, marker, label in CURVES:
                points = sorted((int(a.rpartition("_")[2]), v) for a, v in arms.items()
                                if a.rpartition("_")[0] == kind and a.rpartition("_")[2].isdigit())  # fmt: skip
                if points:
                    x = [p[0] for p in points]
                    y = [p[1]["mean"] for p in points]
                    # clipped at 0: a mean at the floor may sit outside its rounded interval (all seeds at 0 %)
                    err = [[max(0.0, p[1]["mean"] - p[1]["interval"][0]) for p in points],
                           [max(0.0, p[1]["interval"][1] - p[1]["mean"]) for p in points]]
                    ax.errorbar(x, y, yerr=err, color=color, marker=marker, ms=5, lw=1.4, capsize=3, label=label)
            for arm, face, label in (("zero_shot", "#b10dc9", "zero-shot"), ("zero_shot_no_frame", "none", "zero-shot, robot frame")):
                if arm in arms:
                    z = arms[arm]
                    ax.errorbar([0], [z["mean"]], yerr=[[max(0.0, z["mean"] - z["interval"][0])],
                                                        [max(0.0, z["interval"][1] - z["mean"])]],
                                color="#b10dc9", mfc=face, marker="o", ms=7, capsize=3, ls="none", label=label)  # fmt: skip
            mix = sorted((int(a.rpartition("_")[2]), v) for a, v in arms.items() if a.rpartition("_")[0] == "mix"
                         and a.rpartition("_")[2].isdigit())  # fmt: skip
            if "zero_shot" in arms and mix:  # the mix curve starts at zero-shot: the same other hands, no target
                ax.plot([0, mix[0][0]], [arms["zero_shot"]["mean"], mix[0][1]["mean"]], color="#2ecc40", ls=":", lw=1.2)
            expert = result["experts"].get(f"{task}/{hand}")
            if expert:
                ax.axhline(100 * expert["successes"] / expert["episodes"], color="#888888", ls="--", lw=1, label="expert")
            ax.set_ylim(0, 102)
            ax.set_title(f"{task} · {hand}", fontsize=9)
            ax.set_xlabel("target demonstrations", fontsize=8)
            ax.set_ylabel("success (%)", fontsize=8)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            if r == 0 and c == 0:
                handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.subplots_adjust(hspace=0.45, bottom=0.16)
    fig.suptitle(f"Closed loop, {len(result['config']['seeds'])} seeds x {result['config']['eval_episodes']} episodes "
                 "per point (95 % intervals)", fontsize=10)  # fmt: skip
    return save(fig, out_path)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(ClosedLoopConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
