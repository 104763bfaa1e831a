"""Coverage training: batches that mix recorded rows with states synthesised inside each hand's joint ranges.

A tokenizer trained only on the few poses of its recordings memorises them: on unseen episodes of the same
robot it is many times worse than per-joint binning (docs/tokenizer.md). Coverage samples fill the joint
space the recordings leave empty.

Mixing semantics of `MixtureSampler.sample` (one batch):

1. each row picks a hand with the hand shares (`hand_weights`, relative; balanced by default);
2. then a source with that hand kind's source weights (`CoverageConfig.robot` or `.human`, relative);
3. then the source makes the row:

   - `recorded`: a recorded row of that hand, as is;
   - `uniform`: every active DoF uniform inside the hand's joint range (robot hands: the registered range of
     one of its sides, from `hands.get(name).udhm_limits_rad(side)`; human: the UDHM joint limits);
     inactive slots stay 0;
   - `recombine`: each finger (thumb, index, middle, ring, pinky joint groups) from a different recorded row;
   - `noise`: a recorded row plus uniform noise of at most `noise_deg` per active DoF, clipped to the range;
   - `interpolate`: a random point on the segment between two recorded rows.

Every synthesised row keeps the active-DoF mask of the recorded rows it came from (`uniform`: the hand's
mask), so padded slots are never targets. Hands without a registered spec use the range of their recorded
rows (logged once).

Range-only hands (`range_hands`, `TrainConfig.range_hands`): registered hands without recorded rows, trained on
`uniform` states of their registered ranges (both sides, the `semantic` mask) only, so one model covers every
registered hand, recorded or not.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from lerobot_unidextok.constants import UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.data.rowstore import HandRowStore
from lerobot_unidextok.training.arrays import HandStates

if TYPE_CHECKING:
    from lerobot_unidextok.hands import HandSpec

logger = logging.getLogger(__name__)

PROFILE_ROWS = 100_000  # rows read to find a hand's common mask (and an unregistered hand's range)
SOURCES: tuple[str, ...] = ("recorded", "uniform", "recombine", "noise", "interpolate")
# UDHM joint -> finger group (0 thumb, 1 index, 2 middle, 3 ring, 4 pinky) for per-finger recombination
FINGER_OF_JOINT: np.ndarray = np.array(
    [("thumb", "index", "middle", "ring", "pinky").index(n.split("_", 1)[0]) for n in UDHM_JOINT_NAMES]
)


@dataclass
class CoverageConfig:
    """Source weights of the training mixture per hand kind (relative; a hand's rows follow them)."""

    # Robot hands: recorded rows and uniform samples inside the registered joint ranges.
    robot: dict[str, float] = field(default_factory=lambda: {"recorded": 0.5, "uniform": 0.5})
    # The human hand: 22 independent uniform DoFs are implausible poses, so mostly plausible augmentations
    # of the recorded poses plus a share of uniform samples.
    human: dict[str, float] = field(
        default_factory=lambda: {"recorded": 0.3, "recombine": 0.2, "noise": 0.2, "interpolate": 0.1, "uniform": 0.2}
    )
    noise_deg: float = 5.0  # bound of the uniform per-DoF noise of the `noise` source

    def __post_init__(self) -> None:
        for kind in ("robot", "human"):
            weights = getattr(self, kind)
            unknown = sorted(set(weights) - set(SOURCES))
            if unknown:
                raise ValueError(f"coverage.{kind}: unknown sources {unknown}; choose from {list(SOURCES)}")
            if any(w < 0 for w in weights.values()) or sum(weights.values()) <= 0:
                raise ValueError(f"coverage.{kind} weights must be >= 0 with a positive sum, got {weights}")
        if self.noise_deg < 0:
            raise ValueError(f"coverage.noise_deg must be >= 0, got {self.noise_deg}")

    @classmethod
    def recorded_only(cls) -> CoverageConfig:
        """No coverage: recorded rows only (the behaviour before coverage training)."""
        return cls(robot={"recorded": 1.0}, human={"recorded": 1.0})


# ---------------------------------------------------------------------------------------------
# per-hand tables
# ---------------------------------------------------------------------------------------------
def is_human(hand: str) -> bool:
    """True for hands whose native data are keypoints (the human hand)."""
    from lerobot_unidextok import hands

    try:
        return hands.get(hand).kind == "keypoints"
    except KeyError:
        return False


def hand_ranges_rad(hand: str, mask: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """(S, 22) lower and upper bounds (one row per side) of `hand` whose rows use active-DoF `mask`, and
    where they came from: "registry", "udhm_limits" (human) or "recorded" (unregistered hand or a layout
    the registry does not describe)."""
    from lerobot_unidextok import hands, udhm

    try:
        spec = hands.get(hand)
    except KeyError:
        spec = None
    if spec is not None and spec.kind == "keypoints":
        lo, hi = udhm.JOINT_LIMITS_RAD[:, 0], udhm.JOINT_LIMITS_RAD[:, 1]
        return lo[None] * mask, hi[None] * mask, "udhm_limits"
    if spec is not None:
        for mapping in ("semantic", "append_pad"):
            if np.array_equal(spec.mask(mapping), mask):
                los, his = [], []
                for side in spec.sides:
                    lo, hi = spec.udhm_limits_rad(side)
                    if mapping == "append_pad":  # same values packed at the front in native order
                        order = spec.slot_indices(spec.sides[0])
                        lo = np.concatenate([lo[order], np.zeros(UDHM_DIM - len(order))])
                        hi = np.concatenate([hi[order], np.zeros(UDHM_DIM - len(order))])
                    los.append(lo)
                    his.append(hi)
                return np.stack(los), np.stack(his), "registry"
    logger.warning(
        "coverage: hand %r has no registered joint ranges for its mask; sampling inside its recorded range", hand
    )
    return rows.min(0, keepdims=True) * mask, rows.max(0, keepdims=True) * mask, "recorded"


@dataclass
class _Hand:
    """Recorded rows of one hand and what the sources need."""

    name: str
    rows: np.ndarray  # (n, 22) float32, in memory or memory-mapped
    masks: np.ndarray  # (n, 22) bool
    take: np.ndarray | None  # (k,) the rows that may be drawn (a view of a store), or None for all n
    mask: np.ndarray  # (22,) bool, the most common row mask
    lo: np.ndarray  # (S, 22) per-side lower bounds
    hi: np.ndarray  # (S, 22) per-side upper bounds
    ranges_from: str
    source_p: np.ndarray  # (len(SOURCES),) source probabilities

    @property
    def count(self) -> int:
        return len(self.rows) if self.take is None else len(self.take)

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """(22,) union of the per-side ranges."""
        return self.lo.min(0), self.hi.max(0)


def resolve_range_hands(names: list[str], exclude: list[str] | None = None) -> list[str]:
    """The hands `names` asks for (`all` = every registered hand), registered, in order, minus `exclude`."""
    from lerobot_unidextok import hands

    registered = list(hands.names())
    wanted = registered if "all" in names else list(dict.fromkeys(names))
    unknown = sorted(set(wanted) - set(registered))
    if unknown:
        raise ValueError(f"range_hands {unknown} are not registered hands; choose from {registered} or 'all'")
    return [h for h in wanted if h not in set(exclude or ())]


def range_only_table(hand: str | HandSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mask (22,), lo (S, 22), hi (S, 22)) of a hand from its spec alone (`semantic` mapping): a registered
    name, or a `HandSpec` (e.g. a YAML loaded with `hands.load_spec`, registered or not). Robot hands: one row
    per side (`spec.udhm_limits_rad`); the human hand: the UDHM joint limits."""
    from lerobot_unidextok import hands, udhm

    spec = hand if isinstance(hand, hands.HandSpec) else hands.get(hand)
    mask = spec.mask("semantic")
    if spec.kind == "keypoints":
        lo, hi = udhm.JOINT_LIMITS_RAD[None, :, 0] * mask, udhm.JOINT_LIMITS_RAD[None, :, 1] * mask
        return mask, lo, hi
    lo, hi = zip(*(spec.udhm_limits_rad(side) for side in spec.sides), strict=True)
    return mask, np.stack(lo), np.stack(hi)


def range_states(hand: str | HandSpec, n: int, seed: int) -> HandStates:
    """`n` states of `hand` (a registered name or a `HandSpec`) uniform inside its joint ranges, each on a
    random side (the `uniform` source of a range-only hand), labelled with the hand's name: the per-hand
    in-range evaluation set."""
    mask, lo, hi = range_only_table(hand)
    name = hand if isinstance(hand, str) else hand.name
    rng = np.random.default_rng(seed)
    side = rng.integers(len(lo), size=n)
    x = lo[side] + (hi[side] - lo[side]) * rng.random((n, UDHM_DIM))
    masks = np.broadcast_to(mask, x.shape)
    return HandStates(np.where(masks, x, 0.0), np.full(n, name), masks)


def recorded_tables(data: HandStates | HandRowStore):
    """(hand, rows, masks, take) per hand: in-memory copies, or a store's memory maps and its view's rows."""
    if isinstance(data, HandRowStore):
        for name in data.hand_names():
            yield name, data.hands[name].states_rad, data.hands[name].masks, data.rows_of(name)
        return
    for name in data.hand_names():
        sel = data.hands == name
        yield name, data.states_rad[sel], data.masks[sel], None


@dataclass
class Batch:
    states_rad: np.ndarray  # (B, 22) float32
    masks: np.ndarray  # (B, 22) bool
    hands: np.ndarray  # (B,) int64, index into `MixtureSampler.hand_names`
    sources: np.ndarray  # (B,) int64, index into SOURCES


# ---------------------------------------------------------------------------------------------
# main class
# ---------------------------------------------------------------------------------------------
class MixtureSampler:
    """Draws training batches: hand by hand share, then source by the hand kind's source weights."""

    def __init__(
        self,
        data: HandStates | HandRowStore,
        hand_weights: dict[str, float] | None = None,
        default_weight: float = 1.0,
        coverage: CoverageConfig | None = None,
        seed: int = 0,
        range_hands: list[str] | tuple[str, ...] = (),
    ) -> None:
        if len(data) == 0:
            raise ValueError("no training rows: the sampler needs at least one recorded row per hand")
        coverage = coverage or CoverageConfig()
        self.coverage = coverage
        recorded = data.hand_names()
        extra = [h for h in range_hands if h not in recorded]  # registered hands without recordings
        self.hand_names = [*recorded, *extra]
        w = np.array([(hand_weights or {}).get(h, default_weight) for h in self.hand_names], dtype=np.float64)
        if w.sum() <= 0:
            raise ValueError(f"all hand weights are zero for hands {self.hand_names}; give at least one a weight > 0")
        self.hand_p = w / w.sum()
        self.rng = np.random.default_rng(seed)
        self.hands: list[_Hand] = []
        for name, rows, masks, take in recorded_tables(data):
            # the common mask and (unregistered hands) the recorded range, from at most PROFILE_ROWS rows
            n = len(rows) if take is None else len(take)
            if n == 0:
                raise ValueError(f"hand {name!r} has no training rows; drop it or give it recorded rows")
            profile = np.sort(self.rng.choice(n, PROFILE_ROWS, replace=False)) if n > PROFILE_ROWS else np.arange(n)
            profile = profile if take is None else take[profile]
            uniq, counts = np.unique(np.asarray(masks[profile]), axis=0, return_counts=True)
            mask = uniq[counts.argmax()]
            lo, hi, ranges_from = hand_ranges_rad(name, mask, np.asarray(rows[profile]))
            weights = coverage.human if is_human(name) else coverage.robot
            p = np.array([weights.get(s, 0.0) for s in SOURCES], dtype=np.float64)
            self.hands.append(_Hand(name, rows, masks, take, mask, lo.astype(np.float32), hi.astype(np.float32),
                                    ranges_from, p / p.sum()))  # fmt: skip
        only_uniform = np.array([s == "uniform" for s in SOURCES], dtype=np.float64)
        for name in extra:
            mask, lo, hi = range_only_table(name)
            self.hands.append(_Hand(name, np.zeros((0, UDHM_DIM), np.float32), np.zeros((0, UDHM_DIM), bool), None,
                                    mask, lo.astype(np.float32), hi.astype(np.float32), "registry", only_uniform))  # fmt: skip
        self.noise_rad = np.float32(np.radians(coverage.noise_deg))

    # -----------------------------------------------------------------------------------------
    # what the mixture is (training state, model card)
    # -----------------------------------------------------------------------------------------
    def describe(self) -> dict:
        """Per hand: its share of a batch, its kind, where its ranges come from and its source shares."""
        return {
            "noise_deg": self.coverage.noise_deg,
            "hands": {
                h.name: {
                    "share": float(p),
                    "kind": "human" if is_human(h.name) else "robot",
                    "recorded_rows": h.count,
                    "range_only": h.count == 0,
                    "ranges_from": h.ranges_from,
                    "sources": {s: float(q) for s, q in zip(SOURCES, h.source_p, strict=True) if q > 0},
                }
                for h, p in zip(self.hands, self.hand_p, strict=True)
            },
        }

    # -----------------------------------------------------------------------------------------
    # sampling
    # -----------------------------------------------------------------------------------------
    def sample(self, batch_size: int) -> Batch:
        rng = self.rng
        hand_of_row = rng.choice(len(self.hands), size=batch_size, p=self.hand_p)  # (B,)
        x = np.zeros((batch_size, UDHM_DIM), dtype=np.float32)
        m = np.zeros((batch_size, UDHM_DIM), dtype=bool)
        src = np.zeros(batch_size, dtype=np.int64)
        for k, hand in enumerate(self.hands):
            rows_k = np.flatnonzero(hand_of_row == k)
            if rows_k.size == 0:
                continue
            src_k = rng.choice(len(SOURCES), size=rows_k.size, p=hand.source_p)
            src[rows_k] = src_k
            for s, name in enumerate(SOURCES):
                out = rows_k[src_k == s]
                if out.size:
                    x[out], m[out] = getattr(self, f"_{name}")(hand, out.size)
        return Batch(x, m, hand_of_row.astype(np.int64), src)

    def _pick(self, hand: _Hand, size) -> np.ndarray:
        """Uniform row indices into `hand.rows` (its view's rows where it has one)."""
        i = self.rng.integers(hand.count, size=size)
        return i if hand.take is None else hand.take[i]

    def _recorded(self, hand: _Hand, n: int) -> tuple[np.ndarray, np.ndarray]:
        i = self._pick(hand, n)
        return np.asarray(hand.rows[i]), np.asarray(hand.masks[i])

    def _uniform(self, hand: _Hand, n: int) -> tuple[np.ndarray, np.ndarray]:
        side = self.rng.integers(len(hand.lo), size=n)
        lo, hi = hand.lo[side], hand.hi[side]  # (n, 22)
        x = lo + (hi - lo) * self.rng.random((n, UDHM_DIM), dtype=np.float32)
        mask = np.broadcast_to(hand.mask, x.shape).copy()
        return np.where(mask, x, 0.0).astype(np.float32), mask

    def _recombine(self, hand: _Hand, n: int) -> tuple[np.ndarray, np.ndarray]:
        donors = self._pick(hand, (n, int(FINGER_OF_JOINT.max()) + 1))  # (n, 5)
        i = donors[:, FINGER_OF_JOINT]  # (n, 22): the row each joint comes from
        j = np.arange(UDHM_DIM)
        return np.asarray(hand.rows[i, j]), np.asarray(hand.masks[i, j])

    def _noise(self, hand: _Hand, n: int) -> tuple[np.ndarray, np.ndarray]:
        x, mask = self._recorded(hand, n)
        lo, hi = hand.box
        noisy = x + self.rng.uniform(-self.noise_rad, self.noise_rad, size=x.shape).astype(np.float32)
        noisy = np.clip(noisy, np.minimum(lo, x), np.maximum(hi, x))  # recorded rows may sit on a bound
        return np.where(mask, noisy, x).astype(np.float32), mask

    def _interpolate(self, hand: _Hand, n: int) -> tuple[np.ndarray, np.ndarray]:
        a, b = self._pick(hand, n), self._pick(hand, n)
        t = self.rng.random((n, 1), dtype=np.float32)
        ra, rb = np.asarray(hand.rows[a]), np.asarray(hand.rows[b])
        x = ra + t * (rb - ra)
        mask = np.asarray(hand.masks[a]) & np.asarray(hand.masks[b])
        return np.where(mask, x, 0.0).astype(np.float32), mask
