"""Closed loop: success rates of policies on simulated dexterous tasks, per hand, trained as a user trains them.

    python experiments/closed_loop.py                                    # 2 tasks x 6 hands, the six-hand pool
    python experiments/closed_loop.py --tasks='[GraspLift-v0]' --pools='[2,3,6]' \
        --demos='[10]' --mix_demos='[10]' --arms='[alone,mix,zero_shot]'    # the robustness table
    python experiments/closed_loop.py --tasks='[FingerPress-v0]' --targets='[inspire_rh56_unitree]' \
        --arms='[alone,mix]' --demos='[10]' --seeds='[0]'            # one hand-task pair: its alone and mix arms

Protocol. Every seed s draws what a user cannot choose: its own recording of every hand (`lerobot_env_unidextok`,
10 fps, the scripted expert's episode i drawn from `RECORD_SEED + s * SEED_STRIDE + i` with its noise from
`RECORD_NOISE + s * SEED_STRIDE + i`, what `unidextok-sim-record --seed --noise_seed` runs), its own evaluation
episodes (`eval_seed + s * SEED_STRIDE + i`, lerobot-eval's `--seed`; the expert is scored on the same episodes), and
the training seed. `seed_ranges` checks that no two of these ranges overlap. Every dataset an arm trains on holds
exactly the demonstrations the arm has: the target's `n` demonstrations are a recording of `n` episodes (the first
`n` of the seed's recording), converted on their own, so every statistic (the per-hand statistics of the
conversion record, LeRobot's `meta/stats.json`) comes from them alone; the other hands give the seed's recording of
`pool` episodes each. Nothing is selected at training (no `--dataset.episodes`).

Pools. For a target and pool size k (`pools`), the pool is the target and the k - 1 hands that follow it in
`hands` order, cyclically (`pool_hands`): with the default six hands, the Shadow's 2-hand pool is the Shadow and
the Allegro, its 3-hand pool adds the LEAP, and the Linker L10's 2-hand pool is the L10 and the Inspire.

Recipe. What a user runs: `unidextok-convert --source=lerobot --test_fraction=0` (the test is the simulator),
`unidextok-mix --keep=all` with no `--weights` (the mix's own default decides the shares; `target_share` overrides
it), `lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu)` with only `USER_FLAGS` (absolute actions,
each predicted chunk of 10 actions run before the next prediction: closed-loop control, and lerobot-rollout
refuses relative actions), `--steps`, `--batch_size` and the dataset, output and seed flags; so the hands go in as
the policy's default gives them (the UDHM state and the shipped tokenizer's tokens) and, on a mix, as the
recipe gives them (each hand told by its morphology, a residual output head per hand, and among four hands or more
each hand's statistics shrunk toward the pool's by 2 episodes per other hand). Mixed checkpoints are bound to
the target with `unidextok-deploy`, and scored by LeRobot's `lerobot-eval` rollout (`eval_policy_all`, sync envs,
no video) on `eval_episodes` episodes; success as the simulator decides it (`info["is_success"]`). Training runs
LeRobot's own `lerobot-train` code in this process (its dataset items read once per process, then served from
memory, `_MemoryFrames`); `user_commands` renders the same run as the stock command lines.

Arms, per task, target hand and seed; mix arms and zero-shot per pool size (`<arm>_<n>_pool<k>`, `zero_shot_pool<k>`):
- `alone_<n>` for n in `demos`: the target's n demonstrations alone; `alone_state_<n>`: the same with the hand given
  as the UDHM state only (`udt_hand_input=state`, no tokenizer); `alone_no_frame_<n>`: wrist actions in the robot's
  wrist frame;
- `mix_<n>` for n in `mix_demos`: the target's n demonstrations and the pool's other hands' `pool` each, mixed
  (semantic insertion), bound to the target; `mix_state_<n>`: the same, state input; `mix_own_stats_<n>` and
  `zero_shot_own_stats`: the recipe before the pool's prior (each hand's own statistics,
  `--policy.udt_hand_stats_prior_per_hand=0`), which the arms measured on it (`state_norm`, the mechanisms taken
  out, the fine-tunes) keep, so their runs stand;
- `mix_rule_<n>`: `mix_<n>` trained for the budget rule's updates, `steps / share` with the target's share the
  mix recorded (its frame share when it recorded none), where every other arm trains `steps` (matched compute);
- `pooled_<n>`: the recipe before 2026-12-05: LeRobot's one set of statistics for the mix, every slot trained, the
  target's demonstrations written `target_weight` times (copies), the wrist frame of the robot;
- the ablations, each `mix_<n>` with one mechanism off: `no_hand_norm_<n>` (LeRobot's statistics),
  `state_norm_<n>` (the state per hand too), `no_mask_<n>` (every slot trained), `copies_<n>` (the `target_weight`
  copies instead of the share), `no_frame_<n>` (wrist actions in the robot's wrist frame); these, `alone_no_frame`,
  `mix_rule` and `pooled` run on `ablation_targets` (default every target: `PRUNED`);
- `packed_<n>`: `mix_<n>` with each hand's native joints packed at the front of the block and zero-padded (finger
  task only);
- `tokens_nearest_<n>`, `tokens_search_<n>`: `mix_<n>` with the hands given only as the tokenizer's (`--tokenizer`)
  tokens (the nearest codes, or the tokenizer's own encoding unless `encoding` is set);
- the recipe's two pooling mechanisms (act_udt_cpu.yaml: `udt_hand_identity: morphology`, `udt_hand_heads:
  true`), each taken out: `mix_heads_<n>` keeps the per-hand output heads and tells each hand by a one-hot
  (`--policy.udt_hand_identity=onehot`), `mix_morph_<n>` and `zero_shot_morph` keep the morphology identity and
  have no heads (`--policy.udt_hand_heads=false`); `mix_onehot_<n>` and `zero_shot_onehot` have neither, the
  recipe before 2026-12-06 (with one other hand, zero-shot trains on that robot alone, where neither exists);
- `mix_shrink_<n>`: each hand's per-hand statistics shrunk toward the pool's (`--policy.udt_hand_stats_prior=10`:
  the pool lends each hand 10 episodes' worth of its statistics; `shrink_episodes` sets another prior), and
  `zero_shot_shrink` its zero-shot; `state_norm_shrink_<n>`: the same with the state
  normalised per hand too (`--policy.udt_hand_norm_state=true`), whose statistics are then shrunk as well, and
  `zero_shot_state_norm_shrink` the zero-shot arm with both;
- `mix_ft_<n>`: pool, then specialise at matched compute: `mix_<n>` trained for `steps // 2` updates, bound to the
  target, then trained further by the stock `lerobot-train --policy.path=<bound checkpoint>` on the target's own
  dataset (`alone_<n>`'s: the same n demonstrations) for the other `steps - steps // 2` (`fine_tune_args`); the
  fine-tune makes its episode map anew for that dataset (one robot: no shares), LeRobot's statistics
  (`meta/stats.json`: the state's normaliser) are the target dataset's, and the per-hand statistics stay the
  checkpoint's, whose target hand's are those of the same n demonstrations (the mix computes them from its rows of
  that hand), so they equal what the target's dataset gives; the action's wrist (passthrough) columns keep the
  mix's statistics (the per-hand step holds them, and lerobot-train overrides only LeRobot's normaliser);
  `mix_ft_state_norm_<n>`: the same with the state normalised per hand in both stages
  (`--policy.udt_hand_norm_state=true`), so the fine-tune keeps the mix's statistics of the state too;
  `mix_ft_default_<n>`: the path with no flag beyond the user's, the recipe's own mix (with the pool's prior from
  four hands on, where `mix_ft` lends none) then the same bind and stock fine-tune, whose state normaliser takes
  the target dataset's statistics;
- `zero_shot`: the pool's other hands, none of the target's demonstrations, bound with `--zero_shot=true` (one
  other hand: its converted recording, no mix); `zero_shot_no_frame`: the same in the robots' wrist frames;
  `zero_shot_state`: the same with the state-only view (`mix_state`'s flags); `zero_shot_nearest`: `zero_shot`'s
  policy (trained once) bound with `--zero_shot_slots=nearest` as well, so the target drives only the slots of
  the pool's hand nearest it in morphology (`hands/morphology.nearest_hand`).
Also measured: the scripted expert on each seed's evaluation episodes. `robustness` gives per task and pool size
the gain of the mix over the hand alone per target with 95 % intervals, its worst, median and mean; `plot` draws
those gains (`closed_loop.png`) and success against the target's demonstrations (`closed_loop_curves.png`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import math
import re
import shlex
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
# the issue's three hands, then every other hand the simulator models (docs/lerobot.md "The hands' models"); this
# order is the pool rule's (`pool_hands`)
HANDS = ("inspire_rh56_unitree", "shadow", "allegro", "leap", "xhand1", "linkerhand_l10")
# the lerobot-train flags a user adds to act_udt_cpu.yaml for closed-loop control, and nothing else (beside
# --steps, --batch_size and the dataset, output and seed flags): absolute actions, a chunk of 10 actions run
# before the next prediction (a policy that re-plans every step stalls where the demonstrations pause)
USER_FLAGS = ("--policy.udt_relative_actions=false", "--policy.udt_copy_start=false", "--policy.n_action_steps=10")
CONFIG = "lerobot/act_udt_cpu"  # unidextok-config's name of the recipe
# 2: the protocol of this module (issue 57: a recording and evaluation episodes per seed, datasets of exactly the
# arm's demonstrations, the user's recipe); results without it were measured before (the caption says how)
PROTOCOL = 2


def encoding_flags(encoding: EncodingConfig | None) -> list[str]:
    """The lerobot-train flags giving a `<type>_udt` policy this encoding override (None: none, the tokenizer's)."""
    return (
        [] if encoding is None else [f"--policy.udt_encoding.{k}={v}" for k, v in dataclasses.asdict(encoding).items()]
    )


# the state-only view (an ablation): an untrained tokenizer and the nearest codes, from when the step still encoded
# the view it then zeroed; since it no longer encodes with `udt_hand_input=state` (`encode: false`) the two
# further flags change only the seed's draws (docs/pooling.md "The hand input"), and stay so that the runs made
# with them are reused
STATE = ("--policy.udt_hand_input=state", "--policy.udt_pretrained=null", *encoding_flags(NEAREST_CODES))
NO_FRAME = ("--policy.udt_wrist_frame=robot",)
ONEHOT = "--policy.udt_hand_identity=onehot"
NO_HEADS = "--policy.udt_hand_heads=false"
# each hand's own statistics, no prior: the recipe before the pool's prior (act_udt_cpu.yaml's
# udt_hand_stats_prior_per_hand: 2, 2026-12-06; the same as the recipe in a mix of fewer than four hands); the arms
# measured on that recipe keep it, so their runs stand
OWN_STATS = "--policy.udt_hand_stats_prior_per_hand=0"
SHRINK_EPISODES = 10  # the pool's statistics lent to each hand, in episodes (about a 10-demonstration target's own)
SHRINK = f"--policy.udt_hand_stats_prior={SHRINK_EPISODES}"
STATE_SHRINK = ("--policy.udt_hand_norm_state=true", SHRINK)  # the state per hand, every statistic shrunk
POOLED = ("--policy.udt_hand_norm=off", "--policy.udt_mask_slots=false", *NO_FRAME)
# arm -> (its dataset, lerobot-train flags beyond the user's); the dataset: the target alone, the mix (`mix`), the
# mix of the target's copies (`copies`), the packed mix, or the pool's other hands without the target
ARMS: dict[str, tuple[str, tuple[str, ...]]] = {
    "alone": ("alone", ()),
    "alone_state": ("alone", STATE),
    "alone_no_frame": ("alone", NO_FRAME),
    "mix": ("mix", ()),
    "mix_own_stats": ("mix", (OWN_STATS,)),  # the recipe before the pool's prior: each hand's own statistics
    "mix_state": ("mix", STATE),
    "mix_rule": ("mix", ()),
    "pooled": ("copies", POOLED),
    "no_hand_norm": ("mix", ("--policy.udt_hand_norm=off",)),
    "state_norm": ("mix", ("--policy.udt_hand_norm_state=true", OWN_STATS)),
    "no_mask": ("mix", ("--policy.udt_mask_slots=false",)),
    "copies": ("copies", ()),
    "no_frame": ("mix", NO_FRAME),
    "packed": ("packed", ('--policy.udt_range_check="off"',)),  # packed blocks are not UDHM: no range check
    "tokens_nearest": ("mix", ()),
    "tokens_search": ("mix", ()),
    "zero_shot": ("without", ()),
    "zero_shot_own_stats": ("without", (OWN_STATS,)),
    "zero_shot_no_frame": ("without", NO_FRAME),
    "zero_shot_state": ("without", STATE),  # the state-only view's zero-shot, beside `alone_state` and `mix_state`
    # `zero_shot`'s policy bound with `unidextok-deploy --zero_shot_slots=nearest`: the target drives only the slots
    # of the trained hand nearest it in morphology (`BIND`; trained once, `SAME_POLICY`)
    "zero_shot_nearest": ("without", ()),
    # issue 57's mechanisms, both in the recipe (act_udt_cpu.yaml), each taken out: a residual output head per hand
    # around the shared trunk (policies/hand_heads.py), and the hand told by its morphology vector instead of a
    # one-hot (hands/morphology.py; a zero-shot hand gets its own vector, not zeros); measured on the recipe with
    # each hand's own statistics (OWN_STATS)
    "mix_heads": ("mix", (ONEHOT, OWN_STATS)),
    "mix_morph": ("mix", (NO_HEADS, OWN_STATS)),
    "zero_shot_morph": ("without", (NO_HEADS, OWN_STATS)),
    "mix_onehot": ("mix", (ONEHOT, NO_HEADS, OWN_STATS)),  # the recipe before 2026-12-06
    "zero_shot_onehot": ("without", (ONEHOT, NO_HEADS, OWN_STATS)),
    # per-hand statistics shrunk toward the pool's (issue 57; conversion/hand_stats.shrunk_hand_stats): each hand
    # lent `SHRINK_EPISODES` episodes' worth of the pool's statistics, whatever the pool (the fixed prior wins over
    # the recipe's per-hand one)
    "mix_shrink": ("mix", (SHRINK,)),
    "zero_shot_shrink": ("without", (SHRINK,)),  # its zero-shot (one other hand: one robot, where it does nothing)
    # the state normalised per hand too, every statistic shrunk toward the pool's: a candidate default
    "state_norm_shrink": ("mix", STATE_SHRINK),
    "zero_shot_state_norm_shrink": ("without", STATE_SHRINK),
    # pool, then specialise (issue 57): `mix_own_stats` for steps // 2, bound, then lerobot-train --policy.path= on
    # the target's own dataset for the rest (`FINE_TUNED`, `fine_tune_args`)
    "mix_ft": ("mix", (OWN_STATS,)),
    # the same with the state normalised per hand too: LeRobot's fine-tune swaps the state's normaliser for the
    # target dataset's statistics, this one keeps the checkpoint's (the per-hand step's)
    "mix_ft_state_norm": ("mix", ("--policy.udt_hand_norm_state=true", OWN_STATS)),
    # pool, then fine-tune with no flag beyond the user's: the recipe's own mix, bound, the stock fine-tune
    "mix_ft_default": ("mix", ()),
}
MIX_ARMS = tuple(a for a, (data, _) in ARMS.items() if data != "alone")
ABLATIONS = ("no_hand_norm", "state_norm", "no_mask", "copies", "no_frame")
# run on ablation_targets: the ablations, the old recipe and the budget rule's arm
PRUNED = (*ABLATIONS, "alone_no_frame", "pooled", "mix_rule")
# run on `mechanism_pools`, after every other arm
MECHANISMS = ("mix_own_stats", "zero_shot_own_stats", "mix_heads", "mix_morph", "mix_onehot", "zero_shot_morph",
              "zero_shot_onehot", "mix_shrink",
              "zero_shot_shrink", "state_norm_shrink", "zero_shot_state_norm_shrink", "mix_ft", "mix_ft_state_norm",
              "mix_ft_default", "zero_shot_nearest")
# arms that bind another arm's policy differently: the arm whose policy they take, and unidextok-deploy's options
SAME_POLICY = {"zero_shot_nearest": "zero_shot"}
BIND = {"zero_shot_nearest": {"zero_shot_slots": "nearest"}}
FINE_TUNED = ("mix_ft", "mix_ft_state_norm", "mix_ft_default")  # trained in two stages: the mix, then the target's own dataset (`pool_then_fine_tune`)
FINGER_ONLY = ("packed",)  # the grasp closes every finger together: insertion and packing tie there (docs/pooling.md)
MAPPINGS = {"semantic": "semantic", "packed": "append_pad"}  # a conversion's name -> unidextok-convert --mapping
# seeds: seed s offsets every range below by s * SEED_STRIDE (`seed_ranges` checks none overlaps another)
SEED_STRIDE = 10_000
RECORD_SEED = 100_000  # recording: episode draws from RECORD_SEED + k, the expert's noise from RECORD_NOISE + k
RECORD_NOISE = 200_000
EXPERT_NOISE_SEED = 2_000_000  # the expert's noise on evaluation episode i: this + i (never a recording's)
MAX_POOL = 1000  # recorded episodes per hand: at most 1.5x as many attempts (unidextok-sim-record) < SEED_STRIDE
MAX_ATTEMPTS_FACTOR = 1.5  # unidextok-sim-record's default --max_attempts_factor


@dataclass
class ClosedLoopConfig:
    tasks: list[str] = field(default_factory=lambda: list(TASKS))
    hands: list[str] = field(default_factory=lambda: list(HANDS))  # in the pool rule's order
    # the hands scored as the target (every policy arm, the expert); empty = each of `hands`
    targets: list[str] = field(default_factory=list)
    # pool sizes k (target + the k - 1 hands after it in `hands`, cyclically); empty = [len(hands)], every hand
    pools: list[int] = field(default_factory=list)
    demos: list[int] = field(default_factory=lambda: [10, 25])  # target demonstrations of the `alone` arms
    mix_demos: list[int] = field(default_factory=lambda: [10])  # target demonstrations of the mix arms
    arms: list[str] = field(default_factory=lambda: ["alone", "mix", "zero_shot"])
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])  # each: a recording, evaluation episodes, training
    pool: int = 50  # expert episodes recorded per task, hand and seed (a mix's other hands; the most `alone` takes)
    # the target's share of every batch's loss in a mix (`unidextok-mix --weights`, the other hands share the rest
    # equally); None or 0: no --weights, `unidextok-mix`'s own default decides
    target_share: float | None = None
    # the `pooled` and `copies` arms: how many times the mix writes the target's demonstrations (the recipe before
    # 2026-12-05)
    target_weight: float = 10.0
    steps: int = 400  # lerobot-train updates per policy (`mix_rule`: steps / the target's share)
    batch_size: int = 32
    # the encoding of `tokens_search`: None = the tokenizer's own; `tokens_nearest` always uses the nearest codes
    encoding: EncodingConfig | None = None
    tokenizer: str = DEFAULT_TOKENIZER  # the tokens arms' tokenizer (shipped id, folder or Hub repo id)
    eval_episodes: int = 50
    eval_seed: int = 1000  # lerobot-eval's default: seed s scores episodes eval_seed + s * SEED_STRIDE + i
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_sim"  # recorded, converted and mixed datasets (reused when complete)
    figure_to: str = ""  # also write the gain figure there (e.g. docs/images/closed_loop.png)
    # the targets of the ablations, the old recipe and the budget rule (`PRUNED`; empty = every target)
    ablation_targets: list[str] = field(default_factory=list)
    # the pool sizes of the mechanism arms (`MECHANISMS`; empty = every pool size): prune pools, not seeds or episodes
    mechanism_pools: list[int] = field(default_factory=list)
    # the pool sizes of the zero-shot arms (empty = every pool size): zero-shot from k - 1 other hands
    zero_shot_pools: list[int] = field(default_factory=list)
    # the shrunk arms' prior (`mix_shrink`, `state_norm_shrink`: --policy.udt_hand_stats_prior), in episodes
    shrink_episodes: float = SHRINK_EPISODES
    # record and evaluate with the fingertips' columns (`unidextok-sim-record --fingertips=true`, `lerobot-eval
    # --env.fingertips=true`): each fingertip's place from the grasp centre, the same space for every hand (issue 57)
    fingertips: bool = False

    def __post_init__(self) -> None:
        for name, given, allowed in (("tasks", self.tasks, SIM_TASK_IDS), ("arms", self.arms, tuple(ARMS))):
            unknown = sorted(set(given) - set(allowed))
            if unknown:
                raise ValueError(f"unknown {name} {unknown}; choose from {list(allowed)}")
        if not 1 <= self.pool <= MAX_POOL:
            raise ValueError(
                f"pool must be 1..{MAX_POOL} episodes (the seeds' recordings must not overlap), got {self.pool}"
            )
        for name, demos in (("demos", self.demos), ("mix_demos", self.mix_demos)):
            if not demos or any(not 1 <= d <= self.pool for d in demos):
                raise ValueError(f"{name} {demos} must be 1..pool ({self.pool})")
        if self.target_share is not None and not 0 <= self.target_share < 1:
            raise ValueError(f"target_share must be in [0, 1) (0 or None: the mix's default), got {self.target_share}")
        stray = sorted(set(self.targets) - set(self.hands)) or sorted(set(self.ablation_targets) - set(self.hands))
        if stray:
            raise ValueError(f"targets / ablation_targets {stray} are not among hands {self.hands}")
        if len(self.hands) < 2 and set(self.arms) & set(MIX_ARMS):
            raise ValueError("the mix arms need at least two hands: --hands='[a,b]' or --arms='[alone]'")
        self.pools = self.pools or [len(self.hands)]
        if set(self.arms) & set(MIX_ARMS) and any(not 2 <= k <= len(self.hands) for k in self.pools):
            raise ValueError(f"pools {self.pools} must be 2..{len(self.hands)} (the hands of --hands)")
        for name, given in (("mechanism_pools", self.mechanism_pools), ("zero_shot_pools", self.zero_shot_pools)):
            if set(given) - set(self.pools):
                raise ValueError(f"{name} {given} must be among pools {self.pools}")
        if not self.shrink_episodes > 0:
            raise ValueError(f"shrink_episodes must be > 0 (the shrunk arms' prior), got {self.shrink_episodes}")
        seed_ranges(self)

    @property
    def target_hands(self) -> list[str]:
        return [h for h in self.hands if h in self.targets] if self.targets else list(self.hands)

    @property
    def share(self) -> float | None:
        """The target's share asked of every mix; None: the mix's default."""
        return self.target_share or None


def seed_ranges(cfg: ClosedLoopConfig) -> dict[str, range]:
    """Every seed range the run draws from, by name; raises when two overlap (a recording that is also an
    evaluation episode, or two seeds sharing a recording)."""
    attempts = math.ceil(cfg.pool * MAX_ATTEMPTS_FACTOR)
    out = {}
    for s in cfg.seeds:
        start, noise = record_seeds(s)
        out |= {f"seed {s} recording": range(start, start + attempts), f"seed {s} expert noise": range(noise, noise + attempts),
                f"seed {s} evaluation": range(eval_start(cfg, s), eval_start(cfg, s) + cfg.eval_episodes),
                f"seed {s} evaluation expert noise": range(EXPERT_NOISE_SEED + s * SEED_STRIDE,
                                                           EXPERT_NOISE_SEED + s * SEED_STRIDE + cfg.eval_episodes)}  # fmt: skip
    spans = sorted(out.items(), key=lambda kv: kv[1].start)
    for (a, ra), (b, rb) in zip(spans, spans[1:], strict=False):
        if rb.start < ra.stop:
            raise ValueError(f"the {a} seeds {ra.start}-{ra.stop - 1} overlap the {b} seeds {rb.start}-{rb.stop - 1}: "
                             "change --eval_seed, --eval_episodes or --pool")  # fmt: skip
    return out


def record_seeds(seed: int) -> tuple[int, int]:
    """(episode seed, expert noise seed) of seed `seed`'s recordings (`unidextok-sim-record --seed --noise_seed`)."""
    return RECORD_SEED + seed * SEED_STRIDE, RECORD_NOISE + seed * SEED_STRIDE


def eval_start(cfg: ClosedLoopConfig, seed: int) -> int:
    """The first evaluation episode's seed of seed `seed` (lerobot-eval --seed)."""
    return cfg.eval_seed + seed * SEED_STRIDE


def pool_hands(hands: list[str] | tuple[str, ...], target: str, k: int) -> list[str]:
    """The pool of size k for `target`: the target, then the k - 1 hands after it in `hands`, cyclically."""
    i = list(hands).index(target)
    return [hands[(i + j) % len(hands)] for j in range(k)]


# ---------------------------------------------------------------------------------------------
# data: record, convert, mix (cached; each keyed by everything that defines it)
# ---------------------------------------------------------------------------------------------
def _done(folder: Path) -> bool:
    return (folder / "meta" / "info.json").is_file()


def _cpu_s(folder: Path) -> float:
    """The CPU seconds spent making a cached dataset (written beside it)."""
    return float((folder.parent / f"{folder.name}.cpu").read_text())


def task_dir(cfg: ClosedLoopConfig, task: str) -> str:
    """The cache folder of a task's datasets: recordings with the fingertips' columns are other datasets."""
    return f"{task}_fingertips" if cfg.fingertips else task


def native_root(cfg: ClosedLoopConfig, task: str, hand: str, seed: int, episodes: int) -> Path:
    return Path(cfg.cache_dir) / task_dir(cfg, task) / f"seed{seed}" / hand / f"native_{episodes}"


def converted_root(cfg: ClosedLoopConfig, task: str, hand: str, seed: int, episodes: int, mapping: str) -> Path:
    return native_root(cfg, task, hand, seed, episodes).with_name(f"{mapping}_{episodes}")


def mix_root(cfg: ClosedLoopConfig, task: str, seed: int, inputs: list[Path], tag: str) -> Path:
    """A mix's folder, named by its inputs (hand and episodes each), their conversion and how the shares are set."""
    names = "__".join(f"{p.parent.name}-{p.name.rpartition('_')[2]}" for p in inputs)  # shadow-10__allegro-50
    return Path(cfg.cache_dir) / task_dir(cfg, task) / f"seed{seed}" / "mixes" / f"{inputs[0].name.rpartition('_')[0]}_{names}_{tag}"


# attempts per demonstration asked before a recording gives up: an expert at 84 % (the L10's pinch) fails 6 of 15
# now and then; the first n successes are kept either way, so a recording that needed fewer attempts is unchanged
RECORD_ATTEMPTS = 3.0


def repo_id(cfg: ClosedLoopConfig, root: Path) -> str:
    """A cached dataset's id: `sim/` and its path under `cache_dir` (`GraspLift-v0_seed0_shadow_semantic_10`)."""
    return "sim/" + "_".join(root.relative_to(cfg.cache_dir).parts).replace("_mixes_", "_")


def recorded(cfg: ClosedLoopConfig, task: str, hand: str, seed: int, episodes: int, mapping: str = "semantic") -> Path:
    """Seed `seed`'s recording of `episodes` expert episodes of (task, hand) (`unidextok-sim-record`), converted
    with `mapping` (`unidextok-convert --source=lerobot`); the converted folder. The first n episodes of a
    recording are the recording of n (episode i is drawn from seed + attempts)."""
    from lerobot_env_unidextok.columns import HAND_PREFIX
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    native = native_root(cfg, task, hand, seed, episodes)
    if not _done(native):
        shutil.rmtree(native, ignore_errors=True)
        cpu = time.process_time()
        start, noise = record_seeds(seed)
        report = record(RecordConfig(hand=hand, task=task, episodes=episodes, root=str(native), seed=start,
                                     noise_seed=noise, repo_id=repo_id(cfg, native), fingertips=cfg.fingertips,
                                     max_attempts_factor=RECORD_ATTEMPTS))  # fmt: skip
        (native.parent / f"{native.name}.json").write_text(json.dumps(
            {"episodes": report.episodes, "attempts": report.attempts, "frames": report.frames}))  # fmt: skip
        (native.parent / f"{native.name}.cpu").write_text(f"{time.process_time() - cpu:.1f}")
    out = converted_root(cfg, task, hand, seed, episodes, mapping)
    if not _done(out):
        shutil.rmtree(out, ignore_errors=True)
        cpu = time.process_time()
        convert(ConvertOptions(source="lerobot", input=str(native), root=str(out), repo_id=repo_id(cfg, out),
                               source_options={"hands": {"right": f"{hand}:{HAND_PREFIX}"}},
                               mapping=MAPPINGS[mapping], test_fraction=0.0, progress=False))  # fmt: skip
        (out.parent / f"{out.name}.cpu").write_text(f"{time.process_time() - cpu:.1f}")
    return out


def mixed(root: Path, inputs: list[Path], repo: str, weights: list[float], weights_by: str = "sampling") -> Path:
    """`unidextok-mix --keep=all` of `inputs` at `root` (`weights`: a training-frame share per input, honoured by
    `weights_by`: sampling, a share recorded; copies, episodes written again; []: the mix's default)."""
    from lerobot_unidextok.conversion.mix import MixOptions, mix

    if not _done(root):
        shutil.rmtree(root, ignore_errors=True)
        cpu = time.process_time()
        mix(MixOptions(inputs=[str(p) for p in inputs], root=str(root), repo_id=repo, keep="all",
                       weights=weights, weights_by=weights_by, progress=False))  # fmt: skip
        (root.parent / f"{root.name}.cpu").write_text(f"{time.process_time() - cpu:.1f}")
    return root


@functools.cache
def _mix_code() -> str:
    """A short hash of `unidextok-mix`'s code: a mix made with its default shares is keyed by it (the default may
    change). Hashed once a process (every job's plan asks)."""
    from lerobot_unidextok.conversion import mix

    return code_key(Path(mix.__file__).read_text())


def code_key(source: str) -> str:
    """A short hash of Python `source`'s syntax tree without its docstrings (comments are not in it): an edit of
    its prose keeps the key, an edit of its code does not."""
    import ast

    tree = ast.parse(source)
    for node in ast.walk(tree):
        documented = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
        if isinstance(node, documented) and ast.get_docstring(node, clean=False) is not None:
            node.body = node.body[1:] or [ast.Pass()]
    return hashlib.sha256(ast.dump(tree).encode()).hexdigest()[:8]


def plan(cfg: ClosedLoopConfig, job: dict) -> dict:
    """What a job trains on, without making it: {"inputs": [(hand, episodes)], "mapping", "weights", "weights_by",
    "root" (the training dataset), "robot" (the converted dataset a mix is bound to, or None), "zero_shot"}."""
    task, hand, seed, kind = job["task"], job["hand"], job["seed"], ARMS[job["kind"]][0]
    mapping = "packed" if kind == "packed" else "semantic"
    own = (hand, job["demos"])
    others = [(h, cfg.pool) for h in pool_hands(cfg.hands, hand, job["pool"])[1:]] if job["pool"] else []
    inputs = [own] if kind == "alone" else others if kind == "without" else [own, *others]
    paths = [converted_root(cfg, task, h, seed, n, mapping) for h, n in inputs]
    weights, weights_by, tag = [], "sampling", f"default-{_mix_code()}"
    if kind == "copies":
        weights, weights_by, tag = [cfg.target_weight] + [1.0] * len(others), "copies", f"w{cfg.target_weight:g}"
    elif cfg.share and kind not in ("without", "alone"):  # the hand alone has no share to set
        weights, tag = [cfg.share] + [(1 - cfg.share) / len(others)] * len(others), f"s{cfg.share:g}"
    root = paths[0] if len(paths) == 1 else mix_root(cfg, task, seed, paths, tag)
    robot = (
        None if kind == "alone" else converted_root(cfg, task, hand, seed, job["demos"] or cfg.mix_demos[0], mapping)
    )
    return {"inputs": inputs, "paths": paths, "mapping": mapping, "weights": weights,
            "weights_by": weights_by, "root": root, "robot": robot, "zero_shot": kind == "without"}  # fmt: skip


def make(cfg: ClosedLoopConfig, job: dict) -> dict:
    """The job's plan, its datasets made (cached)."""
    p = plan(cfg, job)
    for hand, n in p["inputs"]:
        recorded(cfg, job["task"], hand, job["seed"], n, p["mapping"])
    if p["robot"] is not None:
        recorded(cfg, job["task"], job["hand"], job["seed"], int(p["robot"].name.rpartition("_")[2]), p["mapping"])
    if p["root"] not in p["paths"]:
        mixed(p["root"], p["paths"], repo_id(cfg, p["root"]), p["weights"], p["weights_by"])
    return p


def data_cpu_s(cfg: ClosedLoopConfig, jobs_run: list[dict]) -> float:
    """CPU seconds spent making every dataset these jobs train on (recordings, conversions, mixes), each once."""
    folders: set[Path] = set()
    for job in jobs_run:
        p = plan(cfg, job)
        folders |= {*p["paths"], p["root"], *([p["robot"]] if p["robot"] else [])}
    natives = {f.with_name(f"native_{f.name.rpartition('_')[2]}") for f in folders if f.parent.name != "mixes"}
    return round(sum(_cpu_s(f) for f in folders | natives), 1)


def recordings(cfg: ClosedLoopConfig) -> dict:
    """{task/hand/seed<s>/<episodes>: what unidextok-sim-record reported} of every recording made for this run."""
    out = {}
    for path in sorted(Path(cfg.cache_dir).glob("*/seed*/*/native_*.json")):
        folder, seed, hand = path.parts[-4:-1]
        task = next((t for t in cfg.tasks if task_dir(cfg, t) == folder), None)
        if task is not None and hand in cfg.hands and int(seed[4:]) in cfg.seeds:
            out[f"{task}/{hand}/{seed}/{path.stem.rpartition('_')[2]}"] = json.loads(path.read_text())
    return out


def target_share_of(root: Path) -> float:
    """The target's (the mix's first input's) share of the sampled training frames, as the mix recorded it; its
    frame share when the mix recorded none."""
    from lerobot_unidextok.data.meta import UdhmDatasetMeta

    record = UdhmDatasetMeta(root).record
    if record.sources[0].share:
        return float(record.sources[0].share)
    frames = [(int(e.origin["mix_source"]), e.length) for e in record.episodes if e.split == "train"]
    return sum(n for k, n in frames if k == 0) / sum(n for _, n in frames)


# ---------------------------------------------------------------------------------------------
# train (LeRobot's lerobot-train code), bind, evaluate (LeRobot's lerobot-eval rollout)
# ---------------------------------------------------------------------------------------------
def train_args(cfg: ClosedLoopConfig, root: Path, out: Path, seed: int, flags: list[str], steps: int) -> list[str]:
    """lerobot-train's arguments after `--config_path=$(unidextok-config lerobot/act_udt_cpu)`: the user's flags,
    the dataset, output and seed, and the arm's own `flags`."""
    return [f"--dataset.repo_id={repo_id(cfg, root)}", f"--dataset.root={root}", *USER_FLAGS, f"--steps={steps}",
            f"--batch_size={cfg.batch_size}", f"--seed={seed}", f"--output_dir={out}", *flags]  # fmt: skip


def recipe(cfg: ClosedLoopConfig, kind: str) -> dict:
    """The policy settings an arm trains with (a run is reused only when they are unchanged): the `udt_*` defaults
    of `act_udt`, then the policy section of the recipe's file (`CONFIG`), then the user's and the arm's
    `--policy.<key>=<value>` flags, each value as YAML reads it (`true` -> True)."""
    import yaml

    from lerobot_unidextok.configs import resolve_config_path
    from lerobot_unidextok.policies.udt_config import UdtConfigMixin

    out = {f.name: f.default for f in dataclasses.fields(UdtConfigMixin)
           if f.name.startswith("udt_") and f.default is not dataclasses.MISSING}  # fmt: skip
    out.update(yaml.safe_load(Path(resolve_config_path(CONFIG)).read_text())["policy"])
    for flag in [*USER_FLAGS, *arm_flags(cfg, kind)]:
        key, _, value = flag.removeprefix("--").partition("=")
        if key.startswith("policy."):
            out[key.removeprefix("policy.")] = yaml.safe_load(value)
    return out


def train_policy(args: list[str], out: Path) -> Path:
    """lerobot-train (its own code, in this process) on act_udt_cpu.yaml with `args`; the `pretrained_model`."""
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
    train(draccus.parse(TrainPipelineConfig, config_path=resolve_config_path(CONFIG), args=args))
    return model


def fine_tune_steps(cfg: ClosedLoopConfig) -> tuple[int, int]:
    """(updates on the mix, updates on the target's own dataset) of a fine-tuned arm: `steps` in all."""
    return cfg.steps // 2, cfg.steps - cfg.steps // 2


def fine_tune_args(cfg: ClosedLoopConfig, checkpoint: Path, root: Path, out: Path, seed: int, steps: int) -> list[str]:
    """The stock fine-tune's arguments, `lerobot-train <these>` (docs/lerobot.md "One policy, several robots",
    step 6): the bound checkpoint (its config, the user's flags included, is the policy's: no `--config_path`,
    whose policy section would override it), the target's dataset, the updates, batch, seed and output;
    `--num_workers=0` is the recipe's (act_udt_cpu.yaml) in place of LeRobot's default 4."""
    return [f"--policy.path={checkpoint}", f"--dataset.repo_id={repo_id(cfg, root)}", f"--dataset.root={root}",
            f"--steps={steps}", f"--batch_size={cfg.batch_size}", f"--seed={seed}", "--num_workers=0",
            f"--output_dir={out}"]  # fmt: skip


def fine_tune_policy(args: list[str], out: Path) -> Path:
    """`lerobot-train <args>` as the stock command runs it (its `parser.wrap` reads `--policy.path` from the
    command line, so the arguments are that command line while it runs, in this process); the `pretrained_model`."""
    import sys

    from lerobot.scripts.lerobot_train import train

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies, as LeRobot's CLIs discover them)

    model = out / "checkpoints" / "last" / "pretrained_model"
    if (model / "model.safetensors").is_file():
        return model
    shutil.rmtree(out, ignore_errors=True)
    _serve_frames_from_memory()
    argv, sys.argv = sys.argv, ["lerobot-train", *args]
    try:
        train()
    finally:
        sys.argv = argv
    return model


def pool_then_fine_tune(cfg: ClosedLoopConfig, job: dict, p: dict, out: Path) -> tuple[Path, dict]:
    """A `FINE_TUNED` arm: its mix trained for the first half of `steps` (`out/pooled`), bound to the target
    (`out/bound`), trained further on the target's own dataset (`p["robot"]`, the `alone` arm's) for the rest
    (`out/fine_tuned`); (the checkpoint to score, what the run records of it)."""
    first, second = fine_tune_steps(cfg)
    pooled = train_policy(train_args(cfg, p["root"], out / "pooled", job["seed"], arm_flags(cfg, job["kind"]), first),
                          out / "pooled")  # fmt: skip
    bound = bind(pooled, p["robot"], out / "bound")
    tuned = fine_tune_policy(fine_tune_args(cfg, bound, p["robot"], out / "fine_tuned", job["seed"], second),
                             out / "fine_tuned")  # fmt: skip
    for stage in ("pooled", "fine_tuned"):
        shutil.rmtree(out / stage / "checkpoints" / "last" / "training_state", ignore_errors=True)
    return tuned, {"pool_steps": first, "fine_tune_steps": second, "fine_tune_dataset": str(p["robot"])}


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


def bind(checkpoint: Path, robot: Path, out: Path, zero_shot: bool = False, **options) -> Path:
    """`unidextok-deploy` into `out` (kept when it is there); `options`: its further flags (`BIND`)."""
    from lerobot_unidextok.policies.deploy import deploy

    if not (out / "model.safetensors").is_file():
        shutil.rmtree(out, ignore_errors=True)
        deploy(checkpoint, robot, out, zero_shot=zero_shot, **options)
    return out


def evaluate(cfg: ClosedLoopConfig, checkpoint: Path, task: str, hand: str, seed: int) -> dict:
    """What `lerobot-eval --policy.path=<checkpoint> --env.type=unidextok --seed=<eval_start>` computes, without
    videos."""
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.factory import make_env, make_env_pre_post_processors
    from lerobot.envs.utils import close_envs
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies and steps, as lerobot-eval discovers them)
    from lerobot_env_unidextok.configuration import UniDexTokEnvConfig

    env_cfg = UniDexTokEnvConfig(task=task, hand=hand, fingertips=cfg.fingertips)
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
                               max_episodes_rendered=0, start_seed=eval_start(cfg, seed))  # fmt: skip
    close_envs(envs)
    overall = info["overall"]
    n = int(overall["n_episodes"])
    return {"successes": round(float(overall["pc_success"]) * n / 100), "episodes": n}


def expert_success(cfg: ClosedLoopConfig, task: str, hand: str, seed: int) -> dict:
    """The scripted expert on seed `seed`'s evaluation episodes (its own noise)."""
    from lerobot_env_unidextok.env import UniDexTokEnv
    from lerobot_env_unidextok.record import expert_episode

    cpu = time.process_time()
    env = UniDexTokEnv(hand, task, render_mode=None)
    noise = EXPERT_NOISE_SEED + seed * SEED_STRIDE
    wins = sum(expert_episode(env, eval_start(cfg, seed) + i, noise + i, 50)[2] for i in range(cfg.eval_episodes))
    return {"successes": int(wins), "episodes": cfg.eval_episodes, "cpu_s": round(time.process_time() - cpu, 1)}


# ---------------------------------------------------------------------------------------------
# the runs
# ---------------------------------------------------------------------------------------------
def jobs(cfg: ClosedLoopConfig) -> list[dict]:
    """Every (task, target, seed, arm label, target demonstrations, pool size) to run: `<arm>_<n>` for the alone
    arms and n in demos, `<arm>_<n>_pool<k>` for the mix arms, n in mix_demos and k in pools, `<arm>_pool<k>`
    for zero-shot."""
    out = []
    for task in cfg.tasks:
        for hand in cfg.target_hands:
            for seed in cfg.seeds:
                for arm in (a for a in ARMS if a in cfg.arms):
                    if arm in PRUNED and cfg.ablation_targets and hand not in cfg.ablation_targets:
                        continue
                    if arm in FINGER_ONLY and task != "FingerPress-v0":
                        continue
                    kind = ARMS[arm][0]
                    counts = [0] if kind == "without" else cfg.demos if kind == "alone" else cfg.mix_demos
                    pools = [0] if kind == "alone" else cfg.pools
                    if arm in MECHANISMS and cfg.mechanism_pools:
                        pools = [k for k in pools if k in cfg.mechanism_pools]
                    if kind == "without" and cfg.zero_shot_pools:
                        pools = [k for k in pools if k in cfg.zero_shot_pools]
                    if arm in ("zero_shot_morph", "zero_shot_onehot"):  # one other hand: that robot alone, no
                        # identity and one head, as in `zero_shot`
                        pools = [k for k in pools if k > 2]
                    out += [{"task": task, "hand": hand, "seed": seed, "arm": arm_label(arm, n, k), "kind": arm,
                             "demos": n, "pool": k} for n in counts for k in pools]  # fmt: skip
    return sorted(out, key=lambda j: j["kind"] in MECHANISMS)  # the table's arms first, for every hand and seed


def arm_label(arm: str, demos: int, pool: int = 0) -> str:
    return "_".join([arm, *([str(demos)] if demos else []), *([f"pool{pool}"] if pool else [])])


def parse_label(label: str) -> tuple[str, int, int]:
    """(arm, target demonstrations or 0, pool size or 0) of an arm label."""
    m = re.fullmatch(r"(.+?)(?:_(\d+))?(?:_pool(\d+))?", label)
    return m.group(1), int(m.group(2) or 0), int(m.group(3) or 0)


def arm_flags(cfg: ClosedLoopConfig, arm: str) -> list[str]:
    """The arm's lerobot-train flags beyond the user's: none for the default arms (`alone`, `mix`, `mix_rule`,
    `zero_shot`); the state view, the token views, the mechanism an ablation turns off or adds, or `OWN_STATS`."""
    tokens = ["--policy.udt_hand_input=tokens", f"--policy.udt_pretrained={cfg.tokenizer}"]
    view = {"tokens_nearest": [*tokens, *encoding_flags(NEAREST_CODES)],
            "tokens_search": [*tokens, *encoding_flags(cfg.encoding)]}.get(arm, [])  # fmt: skip
    shrink = f"--policy.udt_hand_stats_prior={cfg.shrink_episodes:g}"
    return [*view, *(shrink if flag == SHRINK else flag for flag in ARMS[arm][1])]


def job_steps(cfg: ClosedLoopConfig, job: dict, root: Path) -> int:
    """The job's updates: `steps`, or for `mix_rule` the budget rule's with the share the mix recorded."""
    return budget_steps(cfg.steps, target_share_of(root)) if job["kind"] == "mix_rule" else cfg.steps


def policy_dir(cfg: ClosedLoopConfig, job: dict) -> Path:
    return Path(cfg.output_root) / NAME / "policies" / job["task"] / job["hand"] / f"seed{job['seed']}" / job["arm"]


def trained_dir(cfg: ClosedLoopConfig, job: dict) -> Path:
    """Where the job's policy is trained: its own folder, or that of the arm whose policy it binds (`SAME_POLICY`)."""
    same = SAME_POLICY.get(job["kind"])
    return policy_dir(cfg, {**job, "arm": arm_label(same, job["demos"], job["pool"])}) if same else policy_dir(cfg, job)


def run_path(cfg: ClosedLoopConfig, job: dict) -> Path:
    """Where a job's result is kept (`runs/seed<s>/<task>__<hand>__<label>.json`)."""
    return Path(cfg.output_root) / NAME / "runs" / f"seed{job['seed']}" / f"{job['task']}__{job['hand']}__{job['arm']}.json"


def cached_run(cfg: ClosedLoopConfig, job: dict) -> dict | None:
    """The job's kept result if it was trained on the dataset the job trains on and with its `recipe`, else None
    (a run on another dataset, a mix of other code, or with other settings, a changed default included, is made
    again)."""
    done = run_path(cfg, job)
    if not done.is_file():
        return None
    old = json.loads(done.read_text())
    return old if old["dataset"] == str(plan(cfg, job)["root"]) and old.get("recipe") == recipe(cfg, job["kind"]) else None


def run_one(cfg: ClosedLoopConfig, job: dict) -> dict:
    task, hand, seed, label = job["task"], job["hand"], job["seed"], job["arm"]
    cached = cached_run(cfg, job)
    if cached is not None:
        return cached
    done, settings = run_path(cfg, job), recipe(cfg, job["kind"])
    p = make(cfg, job)
    out = policy_dir(cfg, job)
    if done.is_file():
        shutil.rmtree(out, ignore_errors=True)
    steps = job_steps(cfg, job, p["root"])
    cpu0, t0 = time.process_time(), time.time()
    stages: dict = {}
    if job["kind"] in FINE_TUNED:
        bound, stages = pool_then_fine_tune(cfg, job, p, out)
    else:
        trained = trained_dir(cfg, job)
        model = train_policy(train_args(cfg, p["root"], trained, seed, arm_flags(cfg, job["kind"]), steps), trained)
        bound = model if p["robot"] is None else bind(model, p["robot"], out / "bound", zero_shot=p["zero_shot"],
                                                      **BIND.get(job["kind"], {}))  # fmt: skip
    train_cpu = time.process_time() - cpu0
    cpu1 = time.process_time()
    scores = evaluate(cfg, bound, task, hand, seed)
    share = (
        {"target_share": round(target_share_of(p["root"]), 4)}
        if p["root"] not in p["paths"] and not p["zero_shot"]
        else {}
    )
    same = {"same_policy_as": arm_label(SAME_POLICY[job["kind"]], job["demos"], job["pool"])} if job["kind"] in SAME_POLICY else {}
    result = {**job, **scores, **share, **stages, **same, "steps": steps, "dataset": str(p["root"]), "recipe": settings,
              "train_cpu_s": round(train_cpu, 1),
              "eval_cpu_s": round(time.process_time() - cpu1, 1), "wall_s": round(time.time() - t0, 1)}  # fmt: skip
    done.parent.mkdir(parents=True, exist_ok=True)
    done.write_text(json.dumps(result))
    shutil.rmtree(out / "checkpoints" / "last" / "training_state", ignore_errors=True)
    logger.info("%s/%s/%s/seed%d: %d/%d (%.0f CPU-s)", task, hand, label, seed, result["successes"], result["episodes"],
                train_cpu + result["eval_cpu_s"])  # fmt: skip
    return result


def user_commands(cfg: ClosedLoopConfig, job: dict) -> list[str]:
    """The stock command lines that reproduce `job` (record, convert, mix, train, bind, evaluate), with the flags
    this experiment passes; `mix_rule`'s steps are read from its mix, which must exist."""
    from lerobot_env_unidextok.columns import HAND_PREFIX

    task, hand, seed = job["task"], job["hand"], job["seed"]
    p, out, q = plan(cfg, job), policy_dir(cfg, job), shlex.quote
    start, noise = record_seeds(seed)
    robot = [] if p["robot"] is None or p["robot"] in p["paths"] else [(hand, int(p["robot"].name.rpartition("_")[2]))]
    lines = []
    for h, n in [*p["inputs"], *robot]:
        native, conv = native_root(cfg, task, h, seed, n), converted_root(cfg, task, h, seed, n, p["mapping"])
        lines += [f"unidextok-sim-record --hand={h} --task={task} --episodes={n} --root={q(str(native))} --seed={start} "
                  f"--noise_seed={noise} --repo_id={repo_id(cfg, native)}"
                  + (" --fingertips=true" if cfg.fingertips else ""),
                  f"unidextok-convert --source=lerobot --input={q(str(native))} --root={q(str(conv))} "
                  f"--repo_id={repo_id(cfg, conv)} --test_fraction=0 "
                  + (f"--mapping={MAPPINGS[p['mapping']]} " if p["mapping"] != "semantic" else "")
                  + q(f'--source_options={{"hands": {{"right": "{h}:{HAND_PREFIX}"}}}}')]  # fmt: skip
    if p["root"] not in p["paths"]:
        weights = [f"--weights={q(json.dumps(p['weights']))}"] if p["weights"] else []
        by = [f"--weights_by={p['weights_by']}"] if p["weights_by"] != "sampling" else []
        lines.append(" ".join([f"unidextok-mix --inputs={q(json.dumps([str(x) for x in p['paths']]))}",
                               f"--root={q(str(p['root']))}", f"--repo_id={repo_id(cfg, p['root'])}", "--keep=all",
                               *weights, *by]))  # fmt: skip
    steps = job_steps(cfg, job, p["root"]) if job["kind"] == "mix_rule" else cfg.steps
    fine_tuned = job["kind"] in FINE_TUNED
    trained = out / "pooled" if fine_tuned else trained_dir(cfg, job)
    steps = fine_tune_steps(cfg)[0] if fine_tuned else steps
    args = train_args(cfg, p["root"], trained, seed, arm_flags(cfg, job["kind"]), steps)
    lines.append(" ".join([f"lerobot-train --config_path=$(unidextok-config {CONFIG})", *map(q, args)]))
    policy = trained / "checkpoints" / "last" / "pretrained_model"
    if p["robot"] is not None:
        lines.append(f"unidextok-deploy --checkpoint={q(str(policy))} --robot={q(str(p['robot']))} "
                     f"--output={q(str(out / 'bound'))}" + (" --zero_shot=true" if p["zero_shot"] else "")
                     + "".join(f" --{k}={v}" for k, v in BIND.get(job["kind"], {}).items()))  # fmt: skip
        policy = out / "bound"
    if fine_tuned:
        args = fine_tune_args(cfg, policy, p["robot"], out / "fine_tuned", seed, fine_tune_steps(cfg)[1])
        lines.append(" ".join(["lerobot-train", *map(q, args)]))
        policy = out / "fine_tuned" / "checkpoints" / "last" / "pretrained_model"
    lines.append(f"lerobot-eval --policy.path={q(str(policy))} --env.type=unidextok --env.task={task} --env.hand={hand} "
                 f"--eval.n_episodes={cfg.eval_episodes} --eval.batch_size={min(cfg.eval_episodes, 50)} "
                 f"--eval.use_async_envs=false --policy.device=cpu --seed={eval_start(cfg, seed)} "
                 f"--output_dir={q(str(out / 'eval'))}" + (" --env.fingertips=true" if cfg.fingertips else ""))  # fmt: skip
    return lines


def paid_runs(runs: list[dict]) -> list[dict]:
    """The runs whose policy is counted in the costs: a kept run that stands for a second arm (`same_policy_as`: the
    label of the run of the same policy, e.g. zero-shot from one other hand, where a mix's statistics do not exist)
    is paid for once, when that run is among `runs`."""
    labels = {(r["task"], r["hand"], r["seed"], r["arm"]) for r in runs}
    return [r for r in runs if (r["task"], r["hand"], r["seed"], r.get("same_policy_as")) not in labels]


def run_costs(runs: list[dict]) -> dict:
    """Training and evaluation CPU seconds, wall seconds, policies and evaluations of `runs`: a policy is paid once
    (`paid_runs`); another arm's policy bound a second way (`SAME_POLICY`) is trained once but evaluated again, so
    its evaluation is paid."""
    paid = paid_runs(runs)
    scored = paid + [r for r in runs if r["kind"] in SAME_POLICY and r not in paid]
    return {"train_cpu_s": round(sum(r["train_cpu_s"] for r in paid), 1),
            "eval_cpu_s": round(sum(r["eval_cpu_s"] for r in scored), 1), "evaluations": len(scored),
            "runs_wall_s": round(sum(r["wall_s"] for r in scored), 1), "policies": len(paid)}  # fmt: skip


def run(cfg: ClosedLoopConfig) -> dict:
    from lerobot_env_unidextok.success import wilson_interval

    t0, cpu0 = time.time(), time.process_time()
    folder = Path(cfg.output_root) / NAME
    todo = jobs(cfg)
    experts = {}
    for t in cfg.tasks:
        for h in cfg.target_hands:
            per_seed = {s: expert_success(cfg, t, h, s) for s in cfg.seeds}
            k, n = sum(e["successes"] for e in per_seed.values()), sum(e["episodes"] for e in per_seed.values())
            experts[f"{t}/{h}"] = {"successes": k, "episodes": n, "interval": wilson_interval(k, n),
                                   "cpu_s": round(sum(e["cpu_s"] for e in per_seed.values()), 1),
                                   "per_seed": {str(s): e["successes"] for s, e in per_seed.items()}}  # fmt: skip
    runs = [run_one(cfg, job) for job in todo]
    summary = summarise(runs, cfg)
    result = {"experiment": NAME, "protocol": PROTOCOL, "config": dataclasses.asdict(cfg), "runs": runs, "summary": summary,
              "robustness": robustness(summary, cfg), "experts": experts, "recording": recordings(cfg),
              "costs": {"data_cpu_s": data_cpu_s(cfg, todo), **run_costs(runs),
                        "expert_cpu_s": round(sum(e["cpu_s"] for e in experts.values()), 1),
                        "this_process_cpu_s": round(time.process_time() - cpu0, 1)},
              "git_commit": git_commit(), "wall_seconds": round(time.time() - t0, 1),
              "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    # a command split over processes by task reuses finished runs: its wall time is at least theirs, summed
    result["wall_seconds"] = round(max(result["wall_seconds"], result["costs"]["runs_wall_s"]), 1)
    example = next((j for j in todo if j["kind"] == "mix"), None)
    result["user_commands"] = user_commands(cfg, example) if example else []
    tuned = next((j for j in todo if j["kind"] in FINE_TUNED), None)
    if tuned:  # its data commands are the mix's: from its first training on
        lines = user_commands(cfg, tuned)
        first = next(i for i, x in enumerate(lines) if x.startswith("lerobot-train "))
        result["fine_tune_commands"] = lines[first:]
    result["goals"] = goals(result, cfg)
    result["command"] = command_line(cfg)
    result["provenance"] = {
        "data": {"source": "sim", "synthetic_sample": False,
                 "datasets": [f"per seed, {cfg.pool} expert episodes per task and hand, and the target's own "
                              f"recording of its demonstrations (lerobot_env_unidextok)"],
                 "train_rows": f"{min(cfg.demos)}-{max(cfg.demos)} target demonstrations (+ the pool's other hands' {cfg.pool})",
                 "test_rows": f"{cfg.eval_episodes} closed-loop episodes per policy and seed", "hands": list(cfg.hands)},
        "preset": f"act_udt_cpu.yaml (lerobot-train) with {' '.join(USER_FLAGS)}", "seed": cfg.seeds,
        "git_commit": result["git_commit"], "config": {"steps": cfg.steps}, "wall_seconds": result["wall_seconds"],
        "date_utc": result["date_utc"],
    }  # fmt: skip
    folder.mkdir(parents=True, exist_ok=True)
    figures = plot(result, folder / f"{NAME}.png")
    if cfg.figure_to and "gain" in figures:
        shutil.copyfile(figures["gain"], cfg.figure_to)
    result["figures"] = {k: str(v) for k, v in figures.items()}
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


# ---------------------------------------------------------------------------------------------
# summary, robustness, goals, report
# ---------------------------------------------------------------------------------------------
def summarise(runs: list[dict], cfg: ClosedLoopConfig) -> dict:
    """{task: {hand: {arm: {"mean", "std" (over seeds, %), "successes", "episodes" (pooled), "interval"}}}}."""
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


def gain_interval(a: dict, b: dict) -> list[float]:
    """95 % interval (points) of rate(a) - rate(b) from the two Wilson intervals (Newcombe's hybrid score method)."""
    pa, pb = 100 * a["successes"] / a["episodes"], 100 * b["successes"] / b["episodes"]
    (la, ua), (lb, ub) = a["interval"], b["interval"]
    d = pa - pb
    return [d - math.hypot(pa - la, ub - pb), d + math.hypot(ua - pa, pb - lb)]


NEVER_WORSE_POINTS = 3.0  # the goal: the mix no more than 3 points below the hand alone


def robustness(summary: dict, cfg: ClosedLoopConfig) -> dict:
    """{task: {pool size: {"rows": {target: {"alone", "mix", "zero_shot" (rate %, interval), "gain", "gain_interval"}},
    "worst": [target, gain], "median", "mean", "never_worse" (targets with gain >= -3), "above_zero_shot",
    "targets"}}} at the first of `mix_demos`, the rates over the pooled seeds' episodes."""
    n, out = cfg.mix_demos[0], {}
    for task, by_hand in summary.items():
        for k in cfg.pools:
            rows = {}
            for hand, arms in by_hand.items():
                alone, mix, zero = arms.get(f"alone_{n}"), arms.get(f"mix_{n}_pool{k}"), arms.get(f"zero_shot_pool{k}")
                if not (alone and mix):
                    continue
                rate = {key: {"rate": 100 * a["successes"] / a["episodes"], "interval": a["interval"]}
                        for key, a in (("alone", alone), ("mix", mix), ("zero_shot", zero)) if a}  # fmt: skip
                rows[hand] = {**rate, "gain": rate["mix"]["rate"] - rate["alone"]["rate"],
                              "gain_interval": gain_interval(mix, alone)}  # fmt: skip
            if not rows:
                continue
            gains = {h: r["gain"] for h, r in rows.items()}
            worst = min(gains, key=gains.get)
            out.setdefault(task, {})[k] = {
                "rows": rows, "worst": [worst, gains[worst]], "median": float(np.median(list(gains.values()))),
                "mean": float(np.mean(list(gains.values()))), "targets": len(rows),
                "never_worse": sum(g >= -NEVER_WORSE_POINTS for g in gains.values()),
                "above_zero_shot": sum(r["mix"]["rate"] >= r["zero_shot"]["rate"] for r in rows.values() if "zero_shot" in r),
                "with_zero_shot": sum("zero_shot" in r for r in rows.values()),
            }  # fmt: skip
    return out


def goals(result: dict, cfg: ClosedLoopConfig) -> list[dict]:
    """The issue's goals (#57), each with the figure it is judged on, whether it is met and the figures that say
    why, from the robustness table."""
    out = []

    def goal(text: str, value: float, met: bool, why: str = "") -> None:
        out.append({"goal": text, "value": value, "met": bool(met), "why": why})

    n = cfg.mix_demos[0]
    for task, by_pool in result["robustness"].items():
        for k, t in by_pool.items():
            rows = t["rows"]
            worse = [f"{h} {r['gain']:+.0f}" for h, r in rows.items() if r["gain"] < -NEVER_WORSE_POINTS]
            goal(f"{task} pool {k}: the mix at {n} demos no more than {NEVER_WORSE_POINTS:g} points below the hand "
                 f"alone on every target", float(t["never_worse"]), not worse,
                 f"{t['never_worse']}/{t['targets']} targets" + (f"; below: {', '.join(worse)}" if worse else ""))  # fmt: skip
            below = [f"{h} {r['mix']['rate']:.0f} < {r['zero_shot']['rate']:.0f}" for h, r in rows.items()
                     if "zero_shot" in r and r["mix"]["rate"] < r["zero_shot"]["rate"]]  # fmt: skip
            if any("zero_shot" in r for r in rows.values()):  # judged only where zero-shot ran
                goal(f"{task} pool {k}: the mix never below zero-shot", float(t["above_zero_shot"]), not below,
                     "; ".join(below))  # fmt: skip
            goal(
                f"{task} pool {k}: mean gain at least +10 points",
                t["mean"],
                t["mean"] >= 10,
                f"worst {t['worst'][0]} {t['worst'][1]:+.0f}, median {t['median']:+.0f}",
            )
            zero = [(h, r) for h, r in rows.items() if "zero_shot" in r]
            if zero:
                part = 0.5 if k > 3 else 1 / 3  # from three other hands or more (five, the issue says); from one or two
                short = [h for h, r in zero if r["zero_shot"]["rate"] < part * r["alone"]["rate"]]
                goal(
                    f"{task} pool {k}: zero-shot at least {part:.2g} of the hand alone at {n} demos on every target",
                    float(len(zero) - len(short)),
                    not short,
                    f"short: {', '.join(short)}" if short else "",
                )
    more = next((d for d in cfg.demos if d > n), None)
    for task, by_pool in result["robustness"].items():
        for k, t in by_pool.items():
            both = [(r["mix"]["rate"], result["summary"][task][h][f"alone_{more}"]["mean"]) for h, r in t["rows"].items()
                    if f"alone_{more}" in result["summary"][task][h]]  # fmt: skip
            if both:
                m, a = np.mean([b[0] for b in both]), np.mean([b[1] for b in both])
                goal(f"{task} pool {k}: the mix at {n} demos reaches the hand alone at {more}, on average over "
                     f"{len(both)} targets", float(m - a), m >= a, f"mix {m:.1f} %, alone at {more} {a:.1f} %")  # fmt: skip
    for key, e in result["experts"].items():
        value = 100 * e["successes"] / e["episodes"]
        goal(f"{key.replace('/', ' ')}: expert at least 95 %", value, value >= 95, f"{e['successes']}/{e['episodes']}")
    return out


def command_line(cfg: ClosedLoopConfig) -> str:
    default = ClosedLoopConfig()
    flags = [f"--{f.name}={json.dumps(getattr(cfg, f.name)).replace(' ', '')}" for f in dataclasses.fields(cfg)
             if f.name not in WHERE_TO and getattr(cfg, f.name) != getattr(default, f.name)]  # fmt: skip
    return " ".join([f"python experiments/{NAME}.py", *flags])


ARM_TITLES = {"mix": "mix", "mix_state": "mix, state input", "mix_rule": "mix, budget rule",
              "pooled": "mix, pooled statistics (before 2026-12-05)", "no_hand_norm": "mix without per-hand statistics",
              "state_norm": "mix, per-hand statistics for the state too", "no_mask": "mix without masked slots",
              "copies": "mix with copies, not shares", "no_frame": "mix without the grasp-centre frame",
              "packed": "mix, packed native", "tokens_nearest": "mix, tokens (nearest)",
              "tokens_search": "mix, tokens (tokenizer's encoding)", "zero_shot": "zero-shot (other hands only)",
              "mix_own_stats": "mix, each hand's own statistics (the recipe before the pool's prior)",
              "zero_shot_own_stats": "zero-shot, each hand's own statistics (the recipe before the pool's prior)",
              "zero_shot_no_frame": "zero-shot without the grasp-centre frame", "alone": "alone",
              "alone_state": "alone, state input", "alone_no_frame": "alone without the grasp-centre frame",
              "zero_shot_state": "zero-shot, state input",
              "zero_shot_nearest": "zero-shot, the recipe's policy driving its nearest trained hand's slots (--zero_shot_slots=nearest; over the recipe's zero-shot)",
              "mix_heads": "mix, one-hot identity (heads, no morphology)",
              "mix_morph": "mix, no per-hand heads (morphology only)",
              "zero_shot_morph": "zero-shot, no per-hand heads (morphology only)",
              "mix_onehot": "mix, one-hot identity and no heads (the recipe before 2026-12-06)",
              "zero_shot_onehot": "zero-shot, one-hot identity and no heads (before 2026-12-06)",
              "mix_shrink": "mix, per-hand statistics shrunk toward the pool's ({shrink:g} episodes)",
              "zero_shot_shrink": "zero-shot, per-hand statistics shrunk toward the pool's ({shrink:g} episodes)",
              "state_norm_shrink": "mix, the state per hand too, shrunk toward the pool's ({shrink:g} episodes)",
              "zero_shot_state_norm_shrink": "zero-shot, the state per hand too, shrunk toward the pool's",
              "mix_ft": "mix, then fine-tuned on the target (half the updates each)",
              "mix_ft_state_norm": "mix, then fine-tuned, the state normalised per hand (kept through the fine-tune)",
              "mix_ft_default": "mix, then fine-tuned (the recipe's own mix, no flag)"}  # fmt: skip


def shrink_of(result: dict) -> float:
    """The shrunk arms' prior a result ran with (results before the field: the default)."""
    return result["config"].get("shrink_episodes", SHRINK_EPISODES)


def arm_title(label: str, shrink: float = SHRINK_EPISODES) -> str:
    """The row title of an arm's label; `shrink`: the run's `shrink_episodes` (the shrunk arms' prior)."""
    arm, demos, pool = parse_label(label)
    return ", ".join([ARM_TITLES.get(arm, arm).format(shrink=shrink), *([f"{demos} demos"] if demos else []),
                      *([f"{pool}-hand pool"] if pool else [])])  # fmt: skip


def share_words(steps: int, target_share: float | None) -> str:
    """How a run's mixes weight the target, for its table's caption (None or 0: the mix's default)."""
    if not target_share:
        return "the target's share of a mix as unidextok-mix decides it by default (no --weights)"
    return f"the target's share of a mix {target_share:g} (the budget rule's arm: {budget_steps(steps, target_share)})"


def _rate(e: dict) -> str:
    return f"{e['rate']:.0f} ({e['interval'][0]:.0f}-{e['interval'][1]:.0f})"


def robustness_lines(result: dict) -> list[str]:
    lines = []
    n = result["config"]["mix_demos"][0]
    for task, by_pool in result.get("robustness", {}).items():
        pools = list(by_pool)
        targets = list(dict.fromkeys(h for t in by_pool.values() for h in t["rows"]))
        head = ["target", f"alone {n}"] + [c for k in pools for c in (f"mix {n}, pool {k}", f"zero-shot, pool {k}",
                                                                      f"gain, pool {k}")]  # fmt: skip
        rows = []
        for h in targets:
            alone = next(t["rows"][h]["alone"] for t in by_pool.values() if h in t["rows"])
            cells = [h, _rate(alone)]
            for k in pools:
                r = by_pool[k]["rows"].get(h)
                cells += ["-"] * 3 if r is None else [
                    _rate(r["mix"]), _rate(r["zero_shot"]) if "zero_shot" in r else "-",
                    f"{r['gain']:+.0f} ({r['gain_interval'][0]:+.0f} to {r['gain_interval'][1]:+.0f})"]  # fmt: skip
            rows.append(cells)
        lines += [f"**{task}**, robustness at {n} target demonstrations (success %, 95 % interval over the pooled "
                  "seeds' episodes; gain = mix - alone, points):", "", md_table(head, rows), ""]  # fmt: skip
        for k, t in by_pool.items():
            zero = t.get("with_zero_shot", t["targets"])  # results before the field: zero-shot ran on every target
            lines.append(f"- pool {k}: worst {t['worst'][0]} {t['worst'][1]:+.0f}, median {t['median']:+.1f}, mean "
                         f"{t['mean']:+.1f}; within {NEVER_WORSE_POINTS:g} points of alone or better on "
                         f"{t['never_worse']}/{t['targets']}"
                         + (f", mix >= zero-shot on {t['above_zero_shot']}/{zero}" if zero else ""))  # fmt: skip
        for k in pools:
            shares = [r["target_share"] for r in result["runs"]
                      if r["task"] == task and r["arm"] == f"mix_{n}_pool{k}" and "target_share" in r]  # fmt: skip
            if shares:
                lines.append(f"- pool {k}: the target's share of the sampled training frames, as the mix set it: "
                             f"{min(shares):.3f}-{max(shares):.3f} (mean {np.mean(shares):.3f})")  # fmt: skip
        lines += [""]
    return lines


def mechanism_lines(result: dict) -> list[str]:
    """Per task, mechanism arm and pool size: the gain over the hand alone at the same demonstrations (points, per
    target), its mean (over the seeds, and per seed: the targets' mean gain on that seed's recordings and episodes)
    and worst, and the targets within `NEVER_WORSE_POINTS` of alone; zero-shot mechanisms against
    the zero-shot of the recipe before the pool's prior (`zero_shot_own_stats`) of the same pool. From the summary,
    so it reads what the table beside it shows."""
    lines = []
    n = result["config"]["mix_demos"][0]
    shrink = shrink_of(result)
    rate = {(r["task"], r["hand"], r["arm"], r["seed"]): 100 * r["successes"] / r["episodes"] for r in result["runs"]}
    for task, by_hand in result["summary"].items():
        rows = []
        # the zero-shot arms measured on the recipe before the pool's prior against its zero-shot, the recipe's
        # zero-shot against that too
        before = "zero_shot_own_stats"
        for arm, base in (("mix", "alone"), ("mix_own_stats", "alone"), ("mix_onehot", "alone"),
                          ("mix_heads", "alone"), ("mix_morph", "alone"), ("mix_shrink", "alone"),
                          ("state_norm_shrink", "alone"), ("mix_ft", "alone"), ("mix_ft_state_norm", "alone"),
                          ("mix_ft_default", "alone"),
                          ("zero_shot", before), ("zero_shot_onehot", before), ("zero_shot_shrink", before),
                          ("zero_shot_state_norm_shrink", before), ("zero_shot_morph", before),
                          ("zero_shot_nearest", "zero_shot")):  # fmt: skip
            for k in result["config"]["pools"]:
                label, ref = (f"{arm}_{n}_pool{k}", f"alone_{n}") if base == "alone" else (f"{arm}_pool{k}", f"{base}_pool{k}")
                pairs = {h: a[label]["mean"] - a[ref]["mean"] for h, a in by_hand.items() if label in a and ref in a}
                if len(pairs) < 2 or (arm == "mix" and f"mix_heads_{n}_pool{k}" not in next(iter(by_hand.values()))):
                    continue
                worst = min(pairs, key=pairs.get)
                # per seed, the targets' mean gain (each seed its own recordings and evaluation episodes)
                by_seed = [np.mean([rate[(task, h, label, s)] - rate[(task, h, ref, s)] for h in pairs])
                           for s in result["config"]["seeds"]
                           if all((task, h, label, s) in rate and (task, h, ref, s) in rate for h in pairs)]  # fmt: skip
                rows.append([arm_title(label, shrink), *(f"{pairs[h]:+.0f}" if h in pairs else "-" for h in by_hand),
                             f"{np.mean(list(pairs.values())):+.1f}", " / ".join(f"{g:+.1f}" for g in by_seed) or "-",
                             f"{worst} {pairs[worst]:+.0f}",
                             f"{sum(g >= -NEVER_WORSE_POINTS for g in pairs.values())}/{len(pairs)}"])  # fmt: skip
        if rows:
            lines += [f"**{task}**, each mechanism's gain (points, mean over seeds) over the hand alone at {n} "
                      "demonstrations (zero-shot arms: over the zero-shot of the recipe before the pool's prior, "
                      "each hand's own statistics, of the same pool):", "",
                      md_table(["arm", *by_hand, "mean", "mean per seed", "worst",
                                f"within {NEVER_WORSE_POINTS:g} points or better"],
                               rows), ""]  # fmt: skip
    return lines


def markdown(result: dict) -> str:
    cfg, s, costs = result["config"], result["summary"], result["costs"]
    cpu_min = sum(costs[k] for k in ("data_cpu_s", "train_cpu_s", "eval_cpu_s", "expert_cpu_s")) / 60
    runs = result["runs"]
    policies = costs.get("policies", len(runs))  # results before the field: every run its own policy
    evaluations = costs.get("evaluations", policies)  # results before the field: one evaluation per policy
    per_policy = (costs["train_cpu_s"] / policies, costs["eval_cpu_s"] / evaluations) if policies else (0, 0)
    if result.get("protocol") == PROTOCOL:
        how = (f"(each its own recording of every hand and its own {cfg['eval_episodes']} evaluation episodes), and "
               f"the 95 % Wilson interval of the pooled episodes. Every dataset holds only the demonstrations its arm "
               f"trains on. Policies: lerobot-train --config_path=$(unidextok-config {CONFIG}) {' '.join(USER_FLAGS)} "
               f"--steps={cfg['steps']} --batch_size={cfg['batch_size']} (the policy's default hand input and "
               f"tokenizer unless the arm says otherwise), {share_words(cfg['steps'], cfg['target_share'])}; mixes "
               f"bound with unidextok-deploy. Pools: the target and the hands after it in {cfg['hands']}, cyclically.")  # fmt: skip
    else:
        how = (f"({cfg['eval_episodes']} episodes each), and the 95 % Wilson interval of the pooled episodes. The "
               "protocol before issue 57: one recording per hand shared by every seed, the same evaluation episodes "
               "for every seed, the target's demonstrations a subset of its pool chosen with --dataset.episodes (so "
               "the statistics saw the whole pool), the hands as the UDHM state only (no tokenizer), mixes of every "
               "hand of the run.")  # fmt: skip
    lines = [
        f"Success rate (%) in closed loop, mean +- std over seeds {cfg['seeds']} {how} {cpu_min:.1f} CPU-minutes in all "
        f"for {policies} policies"
        f"{f' ({len(runs)} runs: a run standing for two arms is one policy)' if policies != len(runs) else ''} "
        f"({costs['data_cpu_s'] / 60:.1f} data, {costs['train_cpu_s'] / 60:.1f} training, {costs['eval_cpu_s'] / 60:.1f} "
        f"evaluation, {costs['expert_cpu_s'] / 60:.1f} experts; per policy {per_policy[0] / 60:.2f} training and "
        + (f"{per_policy[1] / 60:.2f} evaluation)" if evaluations == policies else
           f"per evaluation {per_policy[1] / 60:.2f}: {evaluations} evaluations, a policy bound a second way scored "
           "again)")
        + f"; the policies took {costs['runs_wall_s'] / 60:.0f} min of wall time "
        "summed over them (runs already done are reused, so one command may be split over processes).", ""]  # fmt: skip
    lines += robustness_lines(result)
    lines += mechanism_lines(result)
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
                cells.append(
                    f"{e['mean']:.1f} +- {e['std']:.1f} ({e['interval'][0]:.0f}-{e['interval'][1]:.0f})" if e else "-"
                )
            rows.append(["scripted expert" if arm == "expert" else arm_title(arm, shrink_of(result)), *cells])
        lines += [f"**{task}**, every arm:", "", md_table(["policy", *hands], rows), ""]
    if result.get("user_commands"):
        lines += ["The commands a user runs for one mix arm (the first of the table):", "", "```bash",
                  *result["user_commands"], "```", ""]  # fmt: skip
    if result.get("fine_tune_commands"):
        lines += ["The fine-tuned arm's commands after its mix (half the updates on the mix, bound, the other half on "
                  "the target's own dataset):", "", "```bash", *result["fine_tune_commands"], "```", ""]  # fmt: skip
    lines += ["Goals:", ""]
    lines += [f"- {'met' if g['met'] else 'NOT met'}: {g['goal']} ({g['value']:+.1f}" + (f"; {g['why']})" if g["why"] else ")")
              for g in result["goals"]]  # fmt: skip
    return "\n".join(lines).rstrip()


POOL_COLORS = ("#2ecc40", "#0074d9", "#ff851b", "#b10dc9", "#ff4136")
CURVES = (("alone", "#0074d9", "o", "alone"), ("mix", "#2ecc40", "s", "mix"), ("mix_rule", "#3d9970", "D", "mix, budget rule"),
          ("pooled", "#ff4136", "^", "mix, pooled statistics (before)"))  # fmt: skip


def plot(result: dict, out_path: Path) -> dict[str, Path]:
    """The figures: `gain` (out_path), mix - alone per target and pool size with 95 % intervals, one panel per task;
    `curves` (`<out_path stem>_curves.png`), success against the target's demonstrations at the largest pool."""
    from matplotlib.figure import Figure

    from lerobot_unidextok.viz.style import save

    out = {}
    rob = result.get("robustness", {})
    if rob:
        fig = Figure(figsize=(8, 3.2 * len(rob) + 0.4))
        for r, (task, by_pool) in enumerate(rob.items()):
            ax = fig.add_subplot(len(rob), 1, r + 1)
            targets = list(dict.fromkeys(h for t in by_pool.values() for h in t["rows"]))
            width = 0.8 / len(by_pool)
            for c, (k, t) in enumerate(by_pool.items()):
                xs = [i - 0.4 + width * (c + 0.5) for i, h in enumerate(targets) if h in t["rows"]]
                rows = [t["rows"][h] for h in targets if h in t["rows"]]
                err = [
                    [r_["gain"] - r_["gain_interval"][0] for r_ in rows],
                    [r_["gain_interval"][1] - r_["gain"] for r_ in rows],
                ]
                ax.errorbar(xs, [r_["gain"] for r_ in rows], yerr=err, color=POOL_COLORS[c % len(POOL_COLORS)], marker="o",
                            ms=5, capsize=3, ls="none", label=f"{k}-hand pool (mean {t['mean']:+.0f})")  # fmt: skip
            ax.axhline(0, color="#444444", lw=1)
            ax.axhline(-NEVER_WORSE_POINTS, color="#888888", lw=1, ls="--")
            ax.set_xticks(range(len(targets)), targets, fontsize=7)
            ax.set_ylabel("mix - alone (points)", fontsize=8)
            ax.set_title(f"{task}, {result['config']['mix_demos'][0]} target demonstrations", fontsize=9)
            ax.grid(alpha=0.3, axis="y")
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=7, frameon=False)
        fig.suptitle(f"Gain of pooling, {len(result['config']['seeds'])} seeds x {result['config']['eval_episodes']} "
                     "episodes per point (95 % intervals)", fontsize=10)  # fmt: skip
        fig.subplots_adjust(hspace=0.5)
        out["gain"] = save(fig, out_path)
    out["curves"] = plot_curves(result, out_path.with_name(f"{out_path.stem}_curves.png"))
    return out


def plot_curves(result: dict, out_path: Path) -> Path:
    """Success (%) against the target's demonstrations, one panel per task (rows) and target hand (columns), the
    mix arms at the largest pool: the hand alone, the mix (and its other recipes) as curves, zero-shot at 0
    (hollow: without the grasp-centre frame; bound with --zero_shot_slots=nearest: the diamond beside it), the expert as a dashed line; bars are 95 % Wilson intervals."""
    from matplotlib.figure import Figure

    from lerobot_unidextok.viz.style import save

    s, k_max = result["summary"], max(result["config"]["pools"])
    tasks = list(s)
    hands = list(dict.fromkeys(h for t in tasks for h in s[t]))
    fig = Figure(figsize=(3.6 * len(hands), 3.3 * len(tasks) + 0.6))
    handles, labels = [], []
    for r, task in enumerate(tasks):
        for c, hand in enumerate(hands):
            ax = fig.add_subplot(len(tasks), len(hands), r * len(hands) + c + 1)
            arms = {parse_label(a): v for a, v in s[task].get(hand, {}).items()}
            for kind, color, marker, label in CURVES:
                points = sorted((n, v) for (a, n, k), v in arms.items() if a == kind and n and k in (0, k_max))
                if points:
                    err = [[max(0.0, v["mean"] - v["interval"][0]) for _, v in points],
                           [max(0.0, v["interval"][1] - v["mean"]) for _, v in points]]  # fmt: skip
                    ax.errorbar([n for n, _ in points], [v["mean"] for _, v in points], yerr=err, color=color,
                                marker=marker, ms=5, lw=1.4, capsize=3, label=label)  # fmt: skip
            for arm, color, face, marker, x, label in (
                ("zero_shot", "#b10dc9", "#b10dc9", "o", 0.0, "zero-shot"),
                ("zero_shot_no_frame", "#b10dc9", "none", "o", 0.0, "zero-shot, robot frame"),
                ("zero_shot_nearest", "#ff851b", "#ff851b", "D", 0.6, "zero-shot, --zero_shot_slots=nearest"),
            ):
                z = arms.get((arm, 0, k_max))
                if z:
                    ax.errorbar([x], [z["mean"]], yerr=[[max(0.0, z["mean"] - z["interval"][0])],
                                                        [max(0.0, z["interval"][1] - z["mean"])]],
                                color=color, mfc=face, marker=marker, ms=7, capsize=3, ls="none", label=label)  # fmt: skip
            expert = result["experts"].get(f"{task}/{hand}")
            if expert:
                ax.axhline(
                    100 * expert["successes"] / expert["episodes"], color="#888888", ls="--", lw=1, label="expert"
                )
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
    fig.suptitle(f"Closed loop, {k_max}-hand pool, {len(result['config']['seeds'])} seeds x "
                 f"{result['config']['eval_episodes']} episodes per point (95 % intervals)", fontsize=10)  # fmt: skip
    return save(fig, out_path)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(ClosedLoopConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
