"""Statistics of each hand's UDHM block, from the frames where the block holds that hand (per-hand normalisation).

A UDHM block of a mix holds a different hand in different rows (an Inspire's 6 joints in one row, a Shadow's 22
in the next), and a single robot's block one hand throughout. LeRobot keeps one set of statistics per feature,
so in a mix the slots a hand lacks (zero in its rows) halve those columns' std and one hand's range sets
another's scale. Here every block side and hand gets its own, over the frames where that block holds that hand
(its `udhm_mask` block not all false; a lacking side or an untracked frame is no frame of any hand):

    {"observation.state": {side: {hand: {"mean", "std", "min", "max", "q01", "q10", "q90", "q99": [22],
                                          "frames": n}}},
     "action": {...},          # absolute actions (the action's UDHM blocks)
     "action_delta": {...}}    # action - state per block (relative actions)

Quantiles are computed from the frames of each hand, never merged from per-episode quantiles (LeRobot #4156:
merged quantiles are frame-weighted averages of the episodes' quantiles). `unidextok-mix` records them over the
mix's training episodes (`ConversionRecord.hand_stats`); a `<type>_udt` policy trained on one robot's dataset
computes them from that dataset's training episodes when `lerobot-train` builds it. Both are checked where they
are written and read (`utils/number_checks.checked_hand_stats`: 22 finite numbers per statistic, a std >= 0, every
hand of the vocabulary and no other), so a NaN std is one error naming the file, the hand and the statistic.

A hand with few demonstrations has narrow statistics of its own (a joint its 10 demonstrations barely moved gets
a tiny std, which a policy's held-out rows leave far behind). `shrunk_hand_stats` lends each hand of a mix
`prior_frames` frames of the pool's statistics (per slot, over the hands of either side that have the slot): its
statistics become those of its frames joined by that many frames drawn from the pool, so a hand with many frames
keeps nearly its own and one with few moves toward the pool's (weight n / (n + prior) on its own).
`pool_prior_episodes` sizes that prior by the pool: the more other hands a mix holds, the more its pooled
statistics are a population's and the more of them a hand is lent; with fewer than `MIN_PRIOR_HANDS` hands, none
(shrinking toward a mean estimated from the groups themselves pays only from about four groups: James and Stein,
Efron and Morris; measured in closed loop, docs/pooling.md).
"""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import ACTION, CONVERSION_PATH, HAND_TYPE_KEY, OBS_STATE, UDHM_DIM, UDHM_MASK_KEY
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.reader import data_files
from lerobot_unidextok.utils.number_checks import RANGE_PAIRS, checked_hand_stats

ACTION_DELTA = "action_delta"  # the statistics of action - state (relative actions)
QUANTILES = {"q01": 0.01, "q10": 0.10, "q90": 0.90, "q99": 0.99}
DIGITS = 8  # decimals kept in the JSON record
LOW_STATS = {low for low, _ in RANGE_PAIRS}  # min, q01, q10: the pool's is its lowest; max and the rest its highest


def _summary(values: np.ndarray) -> dict[str, Any]:
    """(n, 22) -> mean, std, min, max and quantiles per slot (rounded lists), and n."""
    out = {
        "mean": values.mean(0),
        "std": values.std(0),
        "min": values.min(0),
        "max": values.max(0),
        **{name: np.quantile(values, q, axis=0) for name, q in QUANTILES.items()},
    }
    summary: dict[str, Any] = {k: [round(float(x), DIGITS) for x in v] for k, v in out.items()}
    summary["frames"] = int(len(values))
    return summary


def _matrix(column, width: int, dtype) -> np.ndarray:
    col = column.combine_chunks()
    flat = col.values if hasattr(col, "values") else col  # a (1,)-shaped feature is stored as a plain column
    return flat.to_numpy(zero_copy_only=False).reshape(len(col), width).astype(dtype, copy=False)


def hand_stats(root: str | Path, episodes: list[int] | None = None) -> dict[str, dict[str, dict[str, dict]]]:
    """Per key (`observation.state`, `action`, `action_delta`), block side and hand, the statistics of that hand's
    frames in `episodes` (None: every episode) of the converted or mixed dataset at `root` (module docstring).
    `action` and `action_delta` are there when the action has the state's UDHM blocks."""
    import pyarrow as pa  # ~0.2 s; only when statistics are computed
    import pyarrow.parquet as pq

    meta = UdhmDatasetMeta(Path(root))
    state_names, action_names = meta.names(OBS_STATE), meta.names(ACTION)
    state_blocks = find_udhm_blocks(state_names)
    action_blocks = {b.side: b for b in find_udhm_blocks(action_names)} if action_names else {}
    with_action = bool(state_blocks) and all(b.side in action_blocks for b in state_blocks)
    columns = [OBS_STATE, HAND_TYPE_KEY, UDHM_MASK_KEY, "episode_index"] + ([ACTION] if with_action else [])
    table = pa.concat_tables(pq.read_table(f, columns=columns) for f in data_files(meta.root))
    rows = np.ones(table.num_rows, bool)
    if episodes is not None:
        rows = np.isin(table.column("episode_index").to_numpy(), list(episodes))
    state = _matrix(table.column(OBS_STATE), len(state_names), np.float64)[rows]
    mask = _matrix(table.column(UDHM_MASK_KEY), UDHM_DIM * len(state_blocks), bool)[rows]
    hand_type = np.asarray(table.column(HAND_TYPE_KEY).to_pylist(), dtype=object)[rows]
    action = _matrix(table.column(ACTION), len(action_names), np.float64)[rows] if with_action else None
    out: dict[str, dict[str, dict[str, dict]]] = {OBS_STATE: {}}
    if with_action:
        out[ACTION], out[ACTION_DELTA] = {}, {}
    per_row_hands = np.array([t.split(",") for t in hand_type], dtype=object).reshape(len(hand_type), -1)
    for k, block in enumerate(state_blocks):
        present = mask[:, UDHM_DIM * k : UDHM_DIM * (k + 1)].any(axis=1)
        hands = per_row_hands[:, k] if per_row_hands.shape[1] > k else per_row_hands[:, 0]
        for hand in sorted(set(hands[present])):
            pick = present & (hands == hand)
            s = state[pick][:, block.slice]
            out[OBS_STATE].setdefault(block.side, {})[hand] = _summary(s)
            if with_action:
                a = action[pick][:, action_blocks[block.side].slice]
                out[ACTION].setdefault(block.side, {})[hand] = _summary(a)
                out[ACTION_DELTA].setdefault(block.side, {})[hand] = _summary(a - s)
    return checked_hand_stats(out, f"the per-hand statistics of {meta.root}", sides=[b.side for b in state_blocks],
                              fix="a converted dataset holds finite UDHM radians: validate it (unidextok-convert "
                              "--validate=true) and convert it again")  # fmt: skip


MIN_PRIOR_HANDS = 4  # `pool_prior_episodes`: no prior in a mix of fewer hands (module docstring)


def shrunk_hand_stats(stats: dict[str, dict[str, dict[str, dict]]], prior_frames: float
                      ) -> dict[str, dict[str, dict[str, dict]]]:  # fmt: skip
    """`stats` (as `hand_stats` gives them) with each hand's statistics per slot moved toward the pool's: the
    mixture of its `frames` frames and `prior_frames` frames of the pool (module docstring). The pool spans both
    sides (a UDHM slot means the same joint on a left and a right hand, so a side that holds one hand, such as a
    two-handed robot's left in a mix of right hands, is shrunk toward the others too). Its mean and std are the
    frame-weighted mixture's over the hands that have the slot (`HandSpec.active_mask`); the range statistics (min,
    max, quantiles) are blended with the pool's lowest low and highest high by the same weight. A slot the hand
    lacks, a key with one hand on one side and `prior_frames <= 0` are left as they are; `frames` stays the hand's
    own count."""
    from lerobot_unidextok import hands as hand_specs

    if prior_frames <= 0:
        return stats
    out: dict[str, dict[str, dict[str, dict]]] = {}
    for key, per_side in stats.items():
        members = [(side, h) for side in sorted(per_side) for h in sorted(per_side[side])]  # every (side, hand)
        if len(members) < 2:
            out[key] = per_side
            continue
        has = np.stack([hand_specs.get(h).active_mask for _, h in members])  # (V, 22)
        frames = np.array([float(per_side[side][h]["frames"]) for side, h in members])  # (V,)
        weight = frames[:, None] * has  # (V, 22)
        total = np.maximum(weight.sum(0), 1e-12)
        entries = [{k: np.asarray(v, np.float64) for k, v in per_side[side][h].items() if k != "frames"}
                   for side, h in members]  # fmt: skip
        stat_names = set.intersection(*(set(e) for e in entries))
        pooled: dict[str, np.ndarray] = {}
        if {"mean", "std"} <= stat_names:
            mean = np.stack([e["mean"] for e in entries])
            second = np.stack([e["std"] ** 2 for e in entries]) + mean**2
            pooled["mean"] = (weight * mean).sum(0) / total
            pooled["second"] = (weight * second).sum(0) / total
        for name in stat_names - {"mean", "std"}:
            values = np.stack([e[name] for e in entries])  # (V, 22)
            low = name in LOW_STATS
            masked = np.where(has, values, np.inf if low else -np.inf)
            pooled[name] = masked.min(0) if low else masked.max(0)
        out[key] = {side: {} for side in per_side}
        for v, ((side, h), own) in enumerate(zip(members, entries, strict=True)):
            w = np.where(has[v], frames[v] / (frames[v] + prior_frames), 1.0)  # (22,): 1 = its own
            new: dict[str, Any] = {}
            if "mean" in pooled:
                mean = w * own["mean"] + (1 - w) * pooled["mean"]
                second = w * (own["std"] ** 2 + own["mean"] ** 2) + (1 - w) * pooled["second"]
                new["mean"], new["std"] = mean, np.sqrt(np.maximum(second - mean**2, 0.0))
            for name in stat_names - {"mean", "std"}:
                new[name] = w * own[name] + (1 - w) * np.where(np.isfinite(pooled[name]), pooled[name], own[name])
            rounded: dict[str, Any] = {k: [round(float(x), DIGITS) for x in new.get(k, own[k])] for k in own}
            rounded["frames"] = per_side[side][h]["frames"]
            out[key][side][h] = rounded
    return out


def prior_episodes_for(hands: Collection[str], per_other_hand: float) -> float:
    """The prior, in episodes, that lends each of the distinct `hands` `per_other_hand` episodes of the pool's
    statistics for every other one when there are at least `MIN_PRIOR_HANDS`: 3x `per_other_hand` among four, 5x
    among six; 0 with fewer (one hand's dataset, a mix of two or three)."""
    n = len(set(hands))
    return per_other_hand * (n - 1) if n >= MIN_PRIOR_HANDS else 0.0


def pool_prior_episodes(stats: dict[str, dict[str, dict[str, dict]]], per_other_hand: float) -> float:
    """`prior_episodes_for` the hands of `stats` (as `hand_stats` gives them; a hand is counted once whichever sides
    hold it, as the pool spans both)."""
    return prior_episodes_for({h for per_side in stats.values() for per_hand in per_side.values() for h in per_hand},
                              per_other_hand)  # fmt: skip


def recorded_hand_stats(meta: UdhmDatasetMeta) -> dict[str, dict[str, dict[str, dict]]] | None:
    """The per-hand statistics a mix records (`ConversionRecord.hand_stats`), checked against its hand vocabulary
    and blocks; None when the record has none (one robot's dataset: `hand_stats` computes them)."""
    record = meta.record
    if record is None or not record.hand_stats:
        return None
    sides = [b.side for b in find_udhm_blocks(meta.names(OBS_STATE))]
    return checked_hand_stats(record.hand_stats, f"{meta.root / CONVERSION_PATH} hand_stats",
                              hands=list(record.hand_vocabulary) or None, sides=sides,
                              fix="the file was edited or damaged: mix the datasets again (unidextok-mix "
                              "--overwrite=true) to recompute it")  # fmt: skip


def training_episodes(meta: UdhmDatasetMeta) -> list[int] | None:
    """The dataset's training episodes: all but its recorded test episodes (None: every episode)."""
    record = meta.record
    if record is None or not record.test_episodes:
        return None
    test = set(record.test_episodes)
    return [e for e in range(meta.total_episodes) if e not in test]


__all__ = ["ACTION_DELTA", "MIN_PRIOR_HANDS", "QUANTILES", "hand_stats", "pool_prior_episodes", "prior_episodes_for",
           "recorded_hand_stats", "shrunk_hand_stats", "training_episodes"]
