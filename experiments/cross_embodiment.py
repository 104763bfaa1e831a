"""What a mix of embodiments buys a policy on one robot: the same small ACT trained on a few episodes of the
target robot alone, or with other hands' data, scored open loop on the target's held-out episodes.

    python experiments/cross_embodiment.py                               # CPU-sized: 3 target sizes x 4 arms x 3 seeds
    python experiments/cross_embodiment.py --act.chunk_size=30 --target_episodes='[4]'   # the longer horizon

Target: the real Unitree G1 + Inspire recording (`g1-inspire`, both hands, converted), its recorded test
episodes held out, `target_episodes` of its training episodes trained on (the same episodes in every arm).
Other embodiments, each labelled by what it is:
- `human_clip` (real): the dex-retargeting MediaPipe clip of one right hand through UDHM IK, in 6 segments;
- `l10_presets` (real poses, synthetic motion): a right LinkerHand L10 moving between the real L10 vendor
  presets (`linkerhand-ros2-sdk/L10_positions.yaml`), minimum-jerk moves (`samples.motion.key_pose_motion`);
- `xhand_gestures` (synthetic): XHand1 right hand, the sample gesture motion on its active slots.
Action rule for sources without recorded actions: the hand state one frame ahead.

Arms (same ACT, steps, seeds, batches): `target_only`; `udhm_mix` (every source in one UDHM layout, a left and
a right block, a side a source lacks zero: semantic insertion); `udhm_mix_old` (`udhm_mix` with the recipe
before 2026-12-05, below); `native_packed` (each source's own joints packed at the front of one vector and
zero-padded, pi0's way; the human hand's joints are its 22 UDHM angles); `tokens_dequantized` (`udhm_mix` with
the hand input through the shipped tokenizer's codes and back). Every arm gets the embodiment as a one-hot
`observation.state`. Targets: relative actions (the action chunk minus the current state, as
`act_udt_cpu.yaml`). Metric: open-loop MAE on the target's held-out frames, first action and over the chunk,
hands in UDHM degrees and in the Inspire's native units; `copy_state` (every future action = the current
state) as reference.

The recipe (the `<type>_udt` defaults, docs/pooling.md), each part one flag:
- `normalise=per_source`: the relative actions z-scored with each source's own mean / std (a source holds one
  hand per block, so per source is per hand), the target's predictions un-scaled with the target's;
- `hand_norm=actions`: the per-source actions not z-scored again, the hand input z-scored pooled over every
  training row (`udt_hand_norm_state=false`: a target of 2-4 episodes has narrow statistics of its own, which its
  held-out states leave far behind); `per_source`: the hand input too with each source's own statistics
  (`train_act`'s own z-score of the hand input and of the per-source actions is then the identity, as LeRobot's
  normaliser is under `unidextok.hand_normalizer`); `state`: only the hand input per source;
- `mask_slots=true`: no loss on the action slots a source's hand lacks (the hand spec's active mask through
  `unidextok.slot_mask`; a side a source lacks entirely lacks every slot; packed: the zero padding), and the
  target's prediction there set to 0, as `unidextok.hand_normalizer` does;
- `share_by=sampling`: the target's `target_share` of the batches drawn by `ShareSampler`, not by copies.
`udhm_mix_old` always runs the old one: `hand_norm=pooled` (one mean / std over the training rows for the hand
input, and one for the per-source actions on top),
`mask_slots=false`, `share_by=copies` (the target's rows repeated up to its share).
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
from experiments.common import WHERE_TO, git_commit, md_table, shown_command
from experiments.policy_training import SmallACT, Standardiser
from lerobot_unidextok.constants import ACTION, OBS_STATE, UDHM_DIM
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL

logger = logging.getLogger(__name__)
NAME = "cross_embodiment"
ARMS = ("target_only", "udhm_mix", "udhm_mix_old", "native_packed", "tokens_dequantized")
HAND_NORMS = ("per_source", "state", "actions", "pooled")  # which of hand input and actions are z-scored per source
OLD_ARM = "udhm_mix_old"  # udhm_mix with the recipe before 2026-12-05 (module docstring)
OTHERS = {"human_clip": "real", "l10_presets": "real poses, synthetic motion", "xhand_gestures": "synthetic"}
SIDES = ("left", "right")  # the mixed UDHM layout: a left block, then a right block
PACKED_WIDTH = UDHM_DIM  # the widest source's joints (the human hand's 22 angles)
COPY = "copy_state"
METRICS = ("hands_udhm_deg_first", "hands_udhm_deg_chunk", "hands_native_first", "hands_native_chunk")


@dataclass
class CrossEmbodimentACT(SmallACT):
    """act_udt_cpu.yaml's sizes, the steps cut to fit the CPU budget (a class default, so `--act.<field>=...`
    keeps it: draccus builds a nested config from its class)."""

    steps: int = 600


@dataclass
class CrossEmbodimentConfig:
    target_episodes: list[int] = field(default_factory=lambda: [2, 4, 8])  # target training episodes per run
    arms: list[str] = field(default_factory=lambda: list(ARMS))
    others: list[str] = field(default_factory=lambda: list(OTHERS))
    other_episodes: int = 12  # episodes of each synthetic-motion source (l10_presets, xhand_gestures)
    other_frames: int = 300  # frames per such episode (30 fps)
    # How the relative actions are z-scored: "per_source" (each source with its own mean / std, the target's
    # predictions un-scaled with the target's: a hand's small moves are not drowned by another's large ones) or
    # "pooled" (one mean / std over every training row)
    normalise: str = "per_source"
    # How the hand input is z-scored: "per_source" (each source with its own mean / std, and the per-source actions
    # not z-scored again) or "pooled" (one mean / std over every training row, for the hand input and on top of the
    # actions: the recipe before 2026-12-05); "actions" (the default, as udt_hand_norm_state=false) / "state": only
    # that half per source, the other pooled
    hand_norm: str = "actions"
    # Each source's own statistics (the per-source ones above) shrunk toward the pool's by this many episodes of
    # the pool's frames, as `--policy.udt_hand_stats_prior` does (`conversion.hand_stats.shrunk_hand_stats`); 0 =
    # `hand_prior_per_hand` decides
    hand_prior: float = 0.0
    # When hand_prior is 0: this many episodes per other hand of the training rows' sources, as the ACT recipes'
    # `udt_hand_stats_prior_per_hand: 2` (`conversion.hand_stats.pool_prior_episodes`); 0 = each source's own
    hand_prior_per_hand: float = 2.0
    mask_slots: bool = True  # no loss on the action slots a source's hand lacks (false: trained as zeros)
    target_share: float = 0.5  # share of the training batches' rows that are the target's; 0 = as they come
    share_by: str = "sampling"  # "sampling" (ShareSampler draws the batches) or "copies" (the target's rows repeated)
    seeds: list[int] = field(default_factory=lambda: [0, 1, 2])
    act: CrossEmbodimentACT = field(default_factory=CrossEmbodimentACT)
    target: str = ""  # a converted robot dataset with recorded test episodes; empty = the real G1 + Inspire recording
    tokenizer: str = UNIVERSAL_SMALL  # the tokenizer of `tokens_dequantized` (never trained on these episodes)
    output_root: str = "outputs/experiments"
    cache_dir: str = "outputs/experiments/_data"  # where the real G1 recording is converted once

    def __post_init__(self) -> None:
        if isinstance(self.act, dict):
            self.act = CrossEmbodimentACT(**self.act)
        for name, given, allowed in (("arms", self.arms, ARMS), ("others", self.others, OTHERS)):
            unknown = sorted(set(given) - set(allowed))
            if unknown:
                raise ValueError(f"unknown {name} {unknown}; choose from {list(allowed)}")
        if self.normalise not in ("per_source", "pooled"):
            raise ValueError(f"normalise must be per_source or pooled, got {self.normalise!r}")
        if self.hand_norm not in HAND_NORMS:
            raise ValueError(f"hand_norm must be one of {HAND_NORMS}, got {self.hand_norm!r}")
        if not self.hand_prior >= 0 or not self.hand_prior_per_hand >= 0:
            raise ValueError(f"hand_prior and hand_prior_per_hand must be >= 0 episodes, got {self.hand_prior} and "
                             f"{self.hand_prior_per_hand}")  # fmt: skip
        if self.share_by not in ("sampling", "copies"):
            raise ValueError(f"share_by must be sampling or copies, got {self.share_by!r}")
        if not 0.0 <= self.target_share < 1.0:
            raise ValueError(f"target_share must be in [0, 1), got {self.target_share}")
        if not self.seeds or not self.target_episodes:
            raise ValueError("give at least one seed and one target size, e.g. --seeds='[0]' --target_episodes='[4]'")


# ---------------------------------------------------------------------------------------------
# sources: each as UDHM blocks (left, right), its own packed joints, episodes, relative-action targets
# ---------------------------------------------------------------------------------------------
@dataclass
class Source:
    name: str
    label: str
    udhm: np.ndarray  # (N, 44) state, [left block, right block], radians; a missing side is 0
    udhm_next: np.ndarray  # (N, 44) the action in the same layout
    packed: np.ndarray  # (N, 22) the source's own joints at the front, zero-padded
    packed_next: np.ndarray  # (N, 22)
    episode: np.ndarray  # (N,)
    hands: list[str | None]  # the hand spec of each UDHM block (SIDES order); None = a side the source lacks
    joints: int  # how many of `packed`'s columns are the source's own (the rest is padding)


def _blocks(states: dict[str, np.ndarray], n: int) -> np.ndarray:
    out = np.zeros((n, 2 * UDHM_DIM))
    for i, side in enumerate(SIDES):
        if side in states:
            out[:, i * UDHM_DIM : (i + 1) * UDHM_DIM] = states[side]
    return out


def _pad(x: np.ndarray) -> np.ndarray:
    return np.pad(x, ((0, 0), (0, PACKED_WIDTH - x.shape[1])))


def _next_in_episode(x: np.ndarray, episode: np.ndarray) -> np.ndarray:
    """x one frame ahead within each episode (the last frame repeats): the action rule of unrecorded actions."""
    nxt = np.roll(x, -1, axis=0)
    last = np.append(episode[1:] != episode[:-1], True)
    nxt[last] = x[last]
    return nxt


def target_source(frames) -> Source:
    """The target robot from its converted frames: recorded actions, its hands' native values (both sides:
    a side it lacks is zero in the UDHM layout)."""
    state_native = frames.native_layout(OBS_STATE).to_native(frames.state)
    action_native = frames.native_layout(ACTION).to_native(frames.action)
    cols = frames.native_hand_columns(ACTION)
    by_side = {s: frames.block_columns[i * UDHM_DIM : (i + 1) * UDHM_DIM] for i, s in enumerate(frames.sides)}
    n = len(frames.state)
    hand_of = dict(zip(frames.sides, frames.hands, strict=True))
    return Source("target", "the target robot", _blocks({s: frames.state[:, c] for s, c in by_side.items()}, n),
                  _blocks({s: frames.action[:, c] for s, c in by_side.items()}, n), _pad(state_native[:, cols]),
                  _pad(action_native[:, cols]), frames.episode, [hand_of.get(s) for s in SIDES], len(cols))  # fmt: skip


def human_source(real: Path) -> Source:
    from lerobot_unidextok import hands

    q = np.asarray(hands.get("human").to_udhm(np.load(real / "dex-retargeting" / "human_joint_right.npy"), "right"))
    episode = np.minimum(np.arange(len(q)) * 6 // len(q), 5)
    nxt = _next_in_episode(q, episode)
    return Source("human_clip", OTHERS["human_clip"], _blocks({"right": q}, len(q)), _blocks({"right": nxt}, len(q)),
                  _pad(q), _pad(nxt), episode, [None, "human"], q.shape[1])  # fmt: skip


def l10_source(real: Path, episodes: int, frames: int) -> Source:
    import yaml

    from lerobot_unidextok import hands
    from lerobot_unidextok.samples.motion import key_pose_motion

    data = yaml.safe_load((real / "linkerhand-ros2-sdk" / "L10_positions.yaml").read_text())
    presets = np.array([p["POSITION"] for p in data.get("RIGHT_HAND") or []], dtype=np.float64)
    native = np.concatenate([key_pose_motion(presets, frames, seed=e) for e in range(episodes)])
    episode = np.repeat(np.arange(episodes), frames)
    nxt = _next_in_episode(native, episode)
    spec = hands.get("linkerhand_l10")
    q, q_next = spec.to_udhm(native, "right"), spec.to_udhm(nxt, "right")
    return Source("l10_presets", OTHERS["l10_presets"], _blocks({"right": q}, len(q)),
                  _blocks({"right": q_next}, len(q)), _pad(native), _pad(nxt), episode, [None, "linkerhand_l10"],
                  native.shape[1])  # fmt: skip


def xhand_source(episodes: int, frames: int) -> Source:
    from lerobot_unidextok import hands
    from lerobot_unidextok.samples.motion import gesture_track

    spec = hands.get("xhand1")
    rng = np.random.default_rng(123)
    udhm = np.concatenate([gesture_track(rng, frames, 30.0).angles_rad for _ in range(episodes)])
    native = np.clip(spec.from_udhm(udhm, "right"), *spec.raw_range("right").T)  # the hand's own joints, in range
    q = spec.to_udhm(native, "right")
    episode = np.repeat(np.arange(episodes), frames)
    nxt = _next_in_episode(native, episode)
    return Source("xhand_gestures", OTHERS["xhand_gestures"], _blocks({"right": q}, len(q)),
                  _blocks({"right": spec.to_udhm(nxt, "right")}, len(q)), _pad(native), _pad(nxt), episode,
                  [None, "xhand1"], native.shape[1])  # fmt: skip


# ---------------------------------------------------------------------------------------------
# one run
# ---------------------------------------------------------------------------------------------
def dequantized(x: np.ndarray, block_hands: list[str | None], tokenizer) -> np.ndarray:
    """(N, 44) UDHM blocks through the tokenizer's codes and back, per block (a missing side stays 0)."""
    import torch

    out = np.zeros_like(x)
    for i, hand in enumerate(block_hands):
        if hand is None:
            continue
        block = torch.from_numpy(x[:, i * UDHM_DIM : (i + 1) * UDHM_DIM].astype(np.float32))
        with torch.no_grad():
            out[:, i * UDHM_DIM : (i + 1) * UDHM_DIM] = tokenizer.decode(tokenizer.encode(block, hand=hand), hand=hand).numpy()
    return out


def chunks(current: np.ndarray, future: np.ndarray, episode: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """((N, chunk, D) relative action chunks: the action k steps ahead minus the current state, (N, chunk) pad)."""
    from experiments.policy_data import chunk_index

    index, pad = chunk_index(episode, chunk)
    return future[index] - current[:, None, :], pad


def lacking(src: Source, packed: bool) -> np.ndarray:
    """(D,) bool: the action slots the source lacks, in the arm's layout: UDHM (44), the slots its hands' specs
    lack and every slot of a side it lacks (`unidextok.slot_mask`'s mask); packed (22), its zero padding."""
    if packed:
        return np.arange(PACKED_WIDTH) >= src.joints
    import torch

    from lerobot_unidextok.blocks import udhm_block_names
    from lerobot_unidextok.processor.slot_mask import SlotMaskStep

    names = [name for side in SIDES for name in udhm_block_names(side)]
    vocabulary = sorted({h for h in src.hands if h is not None})
    step = SlotMaskStep(state_names=names, action_names=names, hand_vocabulary=vocabulary)
    ids = torch.tensor([[-1 if h is None else vocabulary.index(h) for h in src.hands]])
    return step.pad_mask(ids, 1)[0].numpy()


@dataclass
class TrainingSet:
    """An arm's training arrays (rows of every source, the target's first) and the target's own scales."""

    identity: np.ndarray  # (N, sources) one-hot embodiment
    hands: np.ndarray  # (N, D) the hand input (z-scored per source with hand_norm=per_source or state)
    actions: np.ndarray  # (N, chunk, D) relative action chunks (z-scored per source with normalise=per_source)
    is_pad: np.ndarray  # (N, chunk)
    slot_pad: np.ndarray | None  # (N, D) no loss there (mask_slots), else None
    order: np.ndarray | None  # the batches' rows drawn by ShareSampler (share_by=sampling), else None
    target_rows: int  # how many of the N rows are the target's (its copies included)
    state_scale: Standardiser | None  # the target's hand-input z-score (hand_norm=per_source or state)
    action_scale: Standardiser | None  # the target's action z-score (normalise=per_source)
    target_lacks: np.ndarray | None  # (D,) the target's lacked slots (mask_slots)
    actions_prescaled: bool = False  # the actions are z-scored per source and not again (hand_norm=per_source, actions)


def training_set(cfg: CrossEmbodimentConfig, arm: str, sources: list[Source], target_train: np.ndarray,
                 views: dict, seed: int) -> TrainingSet:  # fmt: skip
    """The arm's rows under its recipe (`udhm_mix_old`: the old one whatever the flags; module docstring)."""
    from lerobot_unidextok.data.share_sampler import ShareSampler

    old = arm == OLD_ARM
    hand_norm, mask, share_by = ("pooled", False, "copies") if old else (cfg.hand_norm, cfg.mask_slots, cfg.share_by)
    used = sources[:1] if arm == "target_only" else sources
    packed = arm == "native_packed"
    others = sum(len(src.episode) for src in used[1:])
    share = cfg.target_share if others else 0.0
    picked = []  # per source: its rows, hand input and action chunks
    for k, src in enumerate(used):
        rows = target_train if k == 0 else np.arange(len(src.episode))
        cur, nxt = (src.packed, src.packed_next) if packed else (src.udhm, src.udhm_next)
        y, pad = chunks(cur, nxt, src.episode, cfg.act.chunk_size)
        picked.append((rows, (views[src.name] if arm == "tokens_dequantized" else cur)[rows], y[rows], pad[rows]))
    x_scales = y_scales = [None] * len(used)
    episodes = sum(len(np.unique(src.episode[rows])) for src, (rows, *_) in zip(used, picked, strict=True))
    prior = 0.0 if old else cfg.hand_prior or prior_episodes(used, cfg.hand_prior_per_hand)
    prior_frames = prior * sum(len(rows) for rows, *_ in picked) / episodes  # at the mean episode length
    if hand_norm in ("per_source", "state"):
        x_scales = source_scales(used, [x for _, x, _, _ in picked], prior_frames, packed)
    if cfg.normalise == "per_source":
        y_scales = source_scales(used, [y[:, 0] for _, _, y, _ in picked], prior_frames, packed)
    parts, scales = [], []
    for k, (src, (rows, x, y, pad)) in enumerate(zip(used, picked, strict=True)):
        if k == 0 and share and share_by == "copies":  # repeat the target's rows up to its share
            copies = max(1, round(share / (1 - share) * others / len(rows)))
            rows, x, y, pad = (np.tile(a, (copies,) + (1,) * (a.ndim - 1)) for a in (rows, x, y, pad))
        x_scale, y_scale = x_scales[k], y_scales[k]
        lacks = lacking(src, packed) if mask else None
        scales.append((x_scale, y_scale, lacks))
        parts.append((x if x_scale is None else x_scale(x), y if y_scale is None else y_scale(y),
                      pad, np.full(len(rows), k), None if lacks is None else np.tile(lacks, (len(rows), 1))))  # fmt: skip
    xs, ys, pads, ids, slot_pads = (list(p) for p in zip(*parts, strict=True))
    n0, total = len(ids[0]), sum(len(i) for i in ids)
    order = None
    if share and share_by == "sampling":  # group 0 the target's rows, group 1 the others' (uniform within each)
        sampler = ShareSampler([0, n0], [n0, total], [0, 1], [share, 1 - share],
                               num_samples=cfg.act.steps * cfg.act.batch_size, seed=seed)  # fmt: skip
        order = np.fromiter(iter(sampler), np.int64, count=len(sampler))
    return TrainingSet(np.eye(len(sources))[np.concatenate(ids)], np.concatenate(xs), np.concatenate(ys),
                       np.concatenate(pads), None if not mask else np.concatenate(slot_pads), order, n0, *scales[0],
                       actions_prescaled=hand_norm in ("per_source", "actions") and cfg.normalise == "per_source")  # fmt: skip


def prior_episodes(sources: list[Source], per_other_hand: float) -> float:
    """The prior the recipe's rule gives these sources (`conversion.hand_stats.prior_episodes_for` their hands,
    whichever side holds them)."""
    from lerobot_unidextok.conversion.hand_stats import prior_episodes_for

    return prior_episodes_for({h for src in sources for h in src.hands if h is not None}, per_other_hand)


def source_scales(sources: list[Source], values: list[np.ndarray], prior_frames: float,
                  packed: bool) -> list[Standardiser]:  # fmt: skip
    """Each source's z-score of its (n, D) `values` rows: its own mean / std, or with `prior_frames` > 0 (UDHM
    layout only) those shrunk toward the pool's by `conversion.hand_stats.shrunk_hand_stats`, each side a block,
    each source's hand there one entry."""
    own = [Standardiser.fit(v) for v in values]
    if prior_frames <= 0 or packed:
        return own
    from lerobot_unidextok.conversion.hand_stats import shrunk_hand_stats

    block = {side: slice(i * UDHM_DIM, (i + 1) * UDHM_DIM) for i, side in enumerate(SIDES)}
    stats = {"x": {side: {src.hands[i]: {"mean": v[:, block[side]].mean(0), "std": v[:, block[side]].std(0),
                                         "frames": len(v)}
                          for src, v in zip(sources, values, strict=True) if src.hands[i] is not None}
                   for i, side in enumerate(SIDES)}}  # fmt: skip
    shrunk = shrunk_hand_stats(stats, prior_frames)["x"]
    out = []
    for src, scale in zip(sources, own, strict=True):
        mean, std = scale.mean.copy(), scale.std.copy()  # a side the source lacks keeps its own (0 and 1)
        for i, side in enumerate(SIDES):
            if src.hands[i] is not None:
                entry = shrunk[side][src.hands[i]]
                mean[block[side]], std[block[side]] = entry["mean"], entry["std"]
        out.append(Standardiser.of(mean, std))
    return out


def run_one(cfg: CrossEmbodimentConfig, arm: str, sources: list[Source], target_train: np.ndarray,
            test_rows: np.ndarray, views: dict, seed: int) -> tuple[np.ndarray, dict]:  # fmt: skip
    """(predicted absolute hand chunks of the target's test rows in the arm's space, facts)."""
    from experiments.policy_training import train_act

    data = training_set(cfg, arm, sources, target_train, views, seed)
    model = train_act(cfg.act, data.identity, data.hands, data.actions, data.is_pad, seed, slot_pad=data.slot_pad,
                      order=data.order, hands_prescaled=data.state_scale is not None,
                      actions_prescaled=data.actions_prescaled)  # fmt: skip
    target = sources[0]
    cur = target.packed if arm == "native_packed" else target.udhm
    x = (views[target.name] if arm == "tokens_dequantized" else cur)[test_rows]
    delta = model.predict(np.eye(len(sources))[np.zeros(len(test_rows), int)],
                          x if data.state_scale is None else data.state_scale(x))  # fmt: skip
    if data.action_scale is not None:
        delta = data.action_scale.inverse(delta)
    if data.target_lacks is not None:  # never trained there: hold the state (a lacked slot is 0)
        delta[..., data.target_lacks] = 0.0
    drawn = data.order[: cfg.act.steps * cfg.act.batch_size] if data.order is not None else None
    target_share = float(np.mean(drawn < data.target_rows)) if drawn is not None else data.target_rows / len(data.hands)
    return cur[test_rows][:, None, :] + delta, {"train_rows": int(len(data.hands)), "train_cpu_s": round(model.cpu_s, 1),
                                                  "target_share": round(target_share, 3)}  # fmt: skip


def held_out_spread(cfg: CrossEmbodimentConfig, sources: list[Source], target_train: np.ndarray,
                    test_rows: np.ndarray) -> dict[str, float]:  # fmt: skip
    """The 99th percentile of |z| of the target's held-out hand states (the slots its hands have), z-scored with
    the statistics of its own training rows (`hand_norm=per_source`) and with those pooled over every source's
    rows (the old recipe's, `train_act`'s z-score of `udhm_mix_old`'s input): how far outside its statistics the
    states the policy is scored on lie."""
    target = sources[0]
    active = ~lacking(target, packed=False)
    pooled = training_set(cfg, OLD_ARM, sources, target_train, {}, seed=0).hands
    out = {}
    for name, rows in (("per_source", target.udhm[target_train]), ("pooled", pooled)):
        z = Standardiser.fit(rows)(target.udhm[test_rows])[:, active]
        out[name] = round(float(np.percentile(np.abs(z), 99)), 2)
    return out


def to_target_layout(pred: np.ndarray, arm: str, frames, test_rows: np.ndarray) -> np.ndarray:
    """(R, chunk, D) the prediction in the target's converted layout (its hand block columns filled)."""
    out = np.repeat(frames.action[test_rows][:, None, :], pred.shape[1], axis=1)
    if arm == "native_packed":  # the Inspire values back through the hand specs
        layout = frames.native_layout(ACTION)
        cols = frames.native_hand_columns(ACTION)
        native = layout.to_native(out)
        native[..., cols] = pred[..., : len(cols)]
        return np.asarray(layout.to_converted(native, on_out_of_range="clip"))
    for i, side in enumerate(frames.sides):
        out[..., frames.block_columns[i * UDHM_DIM : (i + 1) * UDHM_DIM]] = pred[..., SIDES.index(side) * UDHM_DIM :][..., :UDHM_DIM]
    return out


# ---------------------------------------------------------------------------------------------
# the experiment
# ---------------------------------------------------------------------------------------------
def run(cfg: CrossEmbodimentConfig) -> dict:
    from experiments.policy_data import copy_state_prediction, load_frames, open_loop_errors, recorded_test_episodes
    from experiments.unseen_data import converted_g1, real_data_dir

    t0 = time.time()
    real = real_data_dir() if {"human_clip", "l10_presets"} & set(cfg.others) else None
    frames = load_frames(cfg.target or converted_g1(cfg.cache_dir))
    test_eps = recorded_test_episodes(frames.root)
    train_eps = np.random.default_rng(0).permutation(np.setdiff1d(np.unique(frames.episode), test_eps))
    if max(cfg.target_episodes) > len(train_eps):
        raise ValueError(f"the target has {len(train_eps)} training episodes; --target_episodes={cfg.target_episodes}")
    build = {"human_clip": lambda: human_source(real),
             "l10_presets": lambda: l10_source(real, cfg.other_episodes, cfg.other_frames),
             "xhand_gestures": lambda: xhand_source(cfg.other_episodes, cfg.other_frames)}  # fmt: skip
    sources = [target_source(frames), *(build[name]() for name in cfg.others)]
    views = {}
    if "tokens_dequantized" in cfg.arms:
        from lerobot_unidextok.tokenizer import UniDexTok

        tok = UniDexTok.from_pretrained(cfg.tokenizer)
        views = {s.name: dequantized(s.udhm, s.hands, tok) for s in sources}
    test_rows = np.flatnonzero(np.isin(frames.episode, test_eps))
    covered = np.zeros(frames.action.shape[1], bool)
    covered[frames.block_columns] = True
    chunk = cfg.act.chunk_size
    runs = [{"arm": COPY, "target_episodes": None, "seed": None,
             "errors": open_loop_errors(copy_state_prediction(frames, test_rows, chunk), frames, test_rows, chunk,
                                        predicted=covered)}]  # fmt: skip
    folder = Path(cfg.output_root) / NAME
    folder.mkdir(parents=True, exist_ok=True)
    spread = {}
    for n in cfg.target_episodes:
        target_train = np.flatnonzero(np.isin(frames.episode, train_eps[:n]))
        spread[str(n)] = held_out_spread(cfg, sources, target_train, test_rows)
        for arm in cfg.arms:
            for seed in cfg.seeds:
                logger.info("%d target episodes, %s, seed %d: training ACT (%d steps)", n, arm, seed, cfg.act.steps)
                pred, facts = run_one(cfg, arm, sources, target_train, test_rows, views, seed)
                full = to_target_layout(pred, arm, frames, test_rows)
                errors = open_loop_errors(full, frames, test_rows, chunk, predicted=covered)
                runs.append({"arm": arm, "target_episodes": n, "seed": seed, "errors": errors, **facts})
    result = {"experiment": NAME, "config": dataclasses.asdict(cfg), "test_episodes": list(map(int, test_eps)),
              "target": "real G1 + Inspire (g1-inspire, converted)" if not cfg.target else str(cfg.target),
              "train_episode_order": train_eps.tolist(),
              "sources": [{"name": s.name, "label": s.label, "frames": len(s.episode),
                           "episodes": int(len(np.unique(s.episode)))} for s in sources],
              "summary": summarise(runs, cfg), "runs": runs, "git_commit": git_commit(),
              "held_out_state_z_p99": spread,
              "wall_seconds": round(time.time() - t0, 1), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    result["command"] = command_line(cfg)
    result["provenance"] = {
        "data": {"source": "datasets" if cfg.target else "real", "synthetic_sample": False,
                 "datasets": [f"{x['name']} ({x['label']})" for x in result["sources"]],
                 "train_rows": f"target {min(cfg.target_episodes)}-{max(cfg.target_episodes)} episodes + the others",
                 "test_rows": int(len(test_rows)), "hands": sorted(set(frames.hands))},
        "preset": "ACT, act_udt_cpu.yaml's sizes", "seed": cfg.seeds, "git_commit": result["git_commit"],
        "config": {"steps": cfg.act.steps}, "wall_seconds": result["wall_seconds"], "date_utc": result["date_utc"],
    }  # fmt: skip
    (folder / f"{NAME}.json").write_text(json.dumps(result, indent=2))
    (folder / f"{NAME}.md").write_text(markdown(result) + "\n")
    return result


def command_line(cfg: CrossEmbodimentConfig) -> str:
    """`python experiments/cross_embodiment.py` with the flags of the settings that differ from the defaults
    (but `WHERE_TO`)."""
    default, flags = CrossEmbodimentConfig(), []
    for f in dataclasses.fields(cfg):
        if f.name in WHERE_TO:
            continue
        value, base = getattr(cfg, f.name), getattr(default, f.name)
        if dataclasses.is_dataclass(value):
            flags += [f"--{f.name}.{g.name}={getattr(value, g.name)}" for g in dataclasses.fields(value)
                      if getattr(value, g.name) != getattr(base, g.name)]  # fmt: skip
        elif value != base:
            flags.append(f"--{f.name}='{json.dumps(value)}'" if isinstance(value, list) else f"--{f.name}={value}")
    return " ".join(["python experiments/cross_embodiment.py", *flags])


def summarise(runs: list[dict], cfg: CrossEmbodimentConfig) -> dict:
    """Per (target size, arm) and metric: mean and std over seeds; copy_state once."""
    out = {COPY: {m: {"mean": runs[0]["errors"][m], "std": 0.0} for m in METRICS}}
    for n in cfg.target_episodes:
        for arm in cfg.arms:
            rs = [r for r in runs if r["arm"] == arm and r["target_episodes"] == n]
            out[f"{n}/{arm}"] = {m: {"mean": float(np.mean([r["errors"][m] for r in rs])),
                                     "std": float(np.std([r["errors"][m] for r in rs], ddof=1)) if len(rs) > 1 else 0.0}
                                 for m in METRICS}  # fmt: skip
            out[f"{n}/{arm}"]["train_cpu_s"] = float(np.mean([r["train_cpu_s"] for r in rs]))
    return out


def prior_words(cfg: dict) -> str:
    """How a result's per-source statistics were shrunk toward the pool's (results before the fields: not)."""
    if cfg.get("hand_prior"):
        return f"each source's statistics shrunk toward the pool's by {cfg['hand_prior']:g} episodes"
    if cfg.get("hand_prior_per_hand"):
        return (f"each source's statistics shrunk toward the pool's by {cfg['hand_prior_per_hand']:g} episodes per "
                "other hand")
    return "each source's own statistics"


def markdown(result: dict) -> str:
    cfg, s = result["config"], result["summary"]
    act = cfg["act"]
    header = ["target episodes", "arm", "hands UDHM deg, first", "hands UDHM deg, chunk", "hands native, first",
              "hands native, chunk", "chunk vs target only", "ACT CPU s/run"]  # fmt: skip

    def cell(v, m, d):
        return f"{v[m]['mean']:.{d}f} +- {v[m]['std']:.{d}f}"

    rows = [["-", COPY, *(f"{s[COPY][m]['mean']:.{2 if 'udhm' in m else 4}f}" for m in METRICS), "", ""]]
    for n in cfg["target_episodes"]:
        base = s.get(f"{n}/target_only")
        for arm in cfg["arms"]:
            v = s[f"{n}/{arm}"]
            rel = "" if base is None or arm == "target_only" else \
                f"{100 * (v['hands_udhm_deg_chunk']['mean'] / base['hands_udhm_deg_chunk']['mean'] - 1):+.1f} %"
            rows.append([str(n), arm, cell(v, "hands_udhm_deg_first", 2), cell(v, "hands_udhm_deg_chunk", 2),
                         cell(v, "hands_native_first", 4), cell(v, "hands_native_chunk", 4), rel,
                         f"{v['train_cpu_s']:.0f}"])  # fmt: skip
    srcs = "; ".join(f"`{x['name']}` ({x['label']}, {x['episodes']} episodes, {x['frames']} frames)" for x in result["sources"])
    return "\n".join([
        f"# {NAME}", "",
        f"LeRobot's ACT (stock model, act_udt_cpu.yaml's sizes, chunk {act['chunk_size']}, {act['steps']} steps at "
        f"batch {act['batch_size']}, one CPU thread), relative actions z-scored {cfg['normalise'].replace('_', ' ')}, "
        f"the hand input z-scored {cfg.get('hand_norm', 'pooled').replace('_', ' ')}, {prior_words(cfg)}, "
        f"{'no loss on the slots a source lacks' if cfg.get('mask_slots') else 'every slot trained'}, the target "
        f"{cfg['target_share']:.0%} of the mixed training rows ({cfg.get('share_by', 'copies')}); `{OLD_ARM}`: the "
        f"recipe before 2026-12-05 (hand input pooled, every slot trained, copies); seeds {cfg['seeds']}. Target: "
        f"{result['target']}, test episodes {result['test_episodes']}, its first N training episodes of the order "
        f"{result['train_episode_order']}. Sources: {srcs}. Open-loop MAE on the target's test frames (hands: UDHM "
        "degrees over the slots its hands have, and native units), mean +- std over seeds.", "",
        md_table(header, rows), "",
        "`chunk vs target only`: hands UDHM MAE over the chunk against `target_only` at the same size (-5 % = 5 % better).",
        *([("The target's held-out hand states z-scored with its own training rows' statistics "
            "(`hand_norm=per_source`) / with those pooled over every source (the old recipe): 99th percentile of "
            "|z| " + ", ".join(f"{v['per_source']:.2f} / {v['pooled']:.2f} at {n} episodes" for n, v in spread.items())
            + ".")] if (spread := result.get("held_out_state_z_p99")) else []),
        f"Wall time {result['wall_seconds']:.0f} s; command: `{shown_command(result.get('command', f'python experiments/{NAME}.py'))}`.",
    ])  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    runtime.cli(CrossEmbodimentConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
