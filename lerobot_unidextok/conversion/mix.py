"""Mix converted datasets of different robots and people into one LeRobot v3 dataset (`unidextok-mix`).

    unidextok-mix --inputs='[data/g1_udhm, data/l10_udhm, data/human_udhm]' --root=data/mix --repo_id=lab/mix

LeRobot's own `aggregate_datasets` (and `lerobot-edit-dataset --operation.type=merge`) needs identical features,
robot type and fps (`lerobot/datasets/aggregate.py`), which datasets of different robots never have: their
state holds other blocks, their arms other columns. So the mix is written anew, episode by episode, with the
conversion's own writer (`conversion.writer`, LeRobot's file format and statistics), in one common layout:

- `observation.state` / `action`: one 22-wide UDHM block per side any input has, in order of first appearance.
  A side an input lacks is a zero block with a zero mask, never a fake hand. `--keep=hands` (the default) drops
  every other column; `--keep=all` keeps the inputs' passthrough columns (arms, grippers), aligned by name
  after `--name_map` (`{"source column": "common name"}`), zero where an input lacks one, with
  `passthrough_mask` saying which are real.
- `hand_type` (each block's hand spec; a lacking side repeats the input's first hand, as `--sides` does) and
  `udhm_mask` per frame, as in any converted dataset; and `observation.hand_ids` ((H,) int64): each block's hand
  as an index into the record's `hand_vocabulary`, -1 for a lacking side and for frames where the hand is absent. The `<type>_udt` policies read it to
  tokenise each row with its own hands and to tell the policy which embodiment it controls.
- Actions: an input's own; an input without actions (human hands: keypoint files, EgoDex) gets the action rule
  `action[t] = state[t + k]` (`--action_ahead=k`, the hand `k` frames later; the last frames hold the last
  state; zero where the hand is absent at `t`), recorded as `action_rule`.
- Every episode keeps its source: `meta/unidextok_conversion.json` lists the inputs (`sources`: dataset, robot
  type, hands, sides, test episodes, native layouts) and, per mixed episode, the input and its episode index
  there (`origin`). `test_episodes` are every input's test episodes, renumbered: splits stay whole-episode and
  per source, and the printed `--dataset.episodes` flag keeps them out of `lerobot-train`.
- `action_delta_stats` in the record: per block side and hand, the mean and std of `action - state` over the
  training episodes, with which a relative-action policy scales each hand's offsets
  (`processor/hand_action_scale.py`).
- `wrist_frame` in the record: the inputs' wrist columns (under the mix's names) and each hand's grasp centre
  (`data/wrist_frame.py`), when every input records one and `--keep=all` keeps the columns; a `<type>_udt`
  policy then learns the wrist in each hand's grasp-centre frame (`processor/wrist_frame.py`).
- Inputs that hold the same episodes are refused (`conversion/fingerprint.py`: one folder given twice, a copy,
  two conversions of one source, one hand of a recording converted beside all of it, a near copy; found by the
  content of each hand of each episode); `--allow_repeats=true` mixes them.
- Each input's `share` of the sampled training frames is chosen by a rule (`conversion/share_rule.py`), by default:
  proportional to its training frames to the power `--share_alpha` (0.43, π0's exponent): 10 target
  demonstrations beside 50 of one other hand get 0.33 of the frames, beside five hands' 50 each 0.09, near the
  0.4 and 0.1 the closed-loop runs measured best (docs/pooling.md). `--share_alpha=1` is each
  input at its frame share, 0 one equal share per input. The shares are recorded (`share` per input, `share_rule` and
  `share_alpha` beside them) and printed; `data/share_sampler.py` samples by them, and the `<type>_udt` policies
  weight each row's loss by them under `lerobot-train`, whose sampler takes every frame equally.
  `--share_rule=frames` mixes as before the rule: each input at its frame share, no share recorded. A mix of one
  input records none (all its frames are its own).
- `--weights` (training-frame share per input) override the rule (`--share_rule=frames` with `--weights` is
  refused: they contradict each other). With `--weights_by=sampling` (the default) they are recorded as the shares;
  `--weights_by=copies` writes an input's training episodes several times instead (`repeats`; test episodes
  once), for policies that are not `<type>_udt`, and records no share (without `--weights`, copies write each
  episode once: the rule is honoured by sampling only). They are checked as they enter
  (`utils/number_checks.checked_shares`): one positive number per input, divided by the largest before they are
  summed (1e308 does not overflow), and no input's share below 1e-3 (the rule's shares are held to the same floor).

Bad input (a dataset that was not converted, datasets at different fps, layouts that cannot share one vector)
is one `MixError` naming the fix; nothing is written then.
"""

from __future__ import annotations

import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_unidextok.blocks import find_udhm_blocks, passthrough_indices, udhm_state_names
from lerobot_unidextok.constants import (
    ACTION,
    HAND_TYPE_KEY,
    OBS_HAND_IDS,
    OBS_STATE,
    PASSTHROUGH_MASK_KEY,
    UDHM_DIM,
    UDHM_MASK_KEY,
)
from lerobot_unidextok.conversion.card import write_card
from lerobot_unidextok.conversion.fingerprint import find_repeat
from lerobot_unidextok.conversion.hand_stats import hand_stats
from lerobot_unidextok.conversion.registry import resamples
from lerobot_unidextok.conversion.share_rule import (
    DEFAULT_ALPHA,
    FRAMES,
    POWER,
    SHARE_RULES,
    WEIGHTS,
    alpha_problem,
    power_shares,
    rule_text,
)
from lerobot_unidextok.conversion.writer import UdhmDatasetWriter
from lerobot_unidextok.data.destination import MIX_SOURCE, Kind, claim, move_into_place, recover, release
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.reader import data_files, dataset_folder
from lerobot_unidextok.data.record import ConversionRecord, EpisodeRecord, MixedSource, write_record
from lerobot_unidextok.data.wrist_frame import WristFrame, merge_frames
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.utils.cli import progress_bar
from lerobot_unidextok.utils.files import temp_sibling
from lerobot_unidextok.utils.number_checks import MIN_SHARE, checked_shares, weights_text

logger = logging.getLogger(__name__)

KEEP = ("hands", "all")
WEIGHTS_BY = ("sampling", "copies")
MAX_GROWTH = 20.0  # weights that would write more than this many times the inputs' frames are refused


class MixError(InvalidInputError):
    """The inputs cannot be mixed as asked; the message names the input, the problem and the fix."""


@dataclass
class MixOptions:
    """What to mix and how (`unidextok-mix` takes the same fields as flags)."""

    inputs: list[str] = field(default_factory=list)  # converted datasets: folders or repo ids (local caches)
    root: str = ""  # output folder (must not exist unless `overwrite`, and then only a mix this tool wrote)
    repo_id: str = "local/udhm_mix"  # dataset id of the mix (card, Hub)
    keep: str = "hands"  # "hands": the UDHM blocks only | "all": also the passthrough columns, aligned by name
    name_map: dict[str, str] = field(default_factory=dict)  # --keep=all: source column -> common column name
    # training-frame share per input, overriding the share rule; [] = the rule's shares (each episode written once)
    weights: list[float] = field(default_factory=list)
    # without --weights, each input's share of the sampled training frames: "power" (its training frames to the
    # power share_alpha, conversion/share_rule.py) | "frames" (each input at its frame share, no share recorded: the
    # mix before the rule)
    share_rule: str = POWER
    # the power rule's exponent in [0, 1]: 1 = each input at its frame share, 0 = one equal share per input; 0.43 is
    # π0's (arXiv 2410.24164): near the shares measured best in docs/pooling.md
    share_alpha: float = DEFAULT_ALPHA
    # inputs that hold the same episodes (one folder twice, a copy, two conversions of one source; found by
    # content, conversion/fingerprint.py) are refused; true: mix them anyway, each as often as it is given
    allow_repeats: bool = False
    # how --weights are honoured: sampling (recorded shares; <type>_udt policies) | copies (repeated episodes)
    weights_by: str = "sampling"
    action_ahead: int = 1  # inputs without actions: action[t] = state[t + action_ahead] (human hands)
    overwrite: bool = False  # replace an earlier mix at root (never anything else)
    progress: bool = True

    def __post_init__(self) -> None:
        self.inputs = [str(i) for i in self.inputs]
        if not self.inputs:
            raise MixError("no inputs: pass --inputs='[<converted dataset folder or repo id>, ...]'")
        if self.keep not in KEEP:
            raise MixError(f"keep must be one of {KEEP}, got {self.keep!r}")
        if self.weights_by not in WEIGHTS_BY:
            raise MixError(f"weights_by must be one of {WEIGHTS_BY}, got {self.weights_by!r}")
        if self.weights:  # one positive, finite number per input, and no input's share below MIN_SHARE
            checked_shares(self.weights, "--weights", count=len(self.inputs))
            self.weights = [float(w) for w in self.weights]
        if self.share_rule not in SHARE_RULES:
            raise MixError(f"share_rule must be one of {SHARE_RULES}, got {self.share_rule!r}")
        if alpha_problem(self.share_alpha):
            raise MixError(alpha_problem(self.share_alpha))
        self.share_alpha = float(self.share_alpha)
        if self.weights and self.share_rule == FRAMES:
            raise MixError("--weights and --share_rule=frames contradict each other (--weights set the shares, frames "
                           "records none): pass one of them")  # fmt: skip
        if self.action_ahead < 1:
            raise MixError(f"action_ahead must be >= 1 frame, got {self.action_ahead}")
        if not self.root:
            raise MixError("pass --root=<output folder> for the mixed dataset")


@dataclass
class _Input:
    """One input, read once: where its hands and columns sit and where they go in the mix."""

    name: str  # as given
    meta: UdhmDatasetMeta
    sides: list[str]
    state_pass: list[str]  # its passthrough state columns, after the name map
    action_pass: list[str]
    has_action: bool
    test: set[int]

    @property
    def record(self) -> ConversionRecord:
        return self.meta.record


@dataclass
class MixReport:
    root: Path
    num_episodes: int
    num_frames: int
    test_episodes: list[int]
    sources: list[MixedSource]
    train_shares: list[float]  # the training-frame share each input gets (sampled, or written)
    seconds: float
    share_rule: str = FRAMES  # how the shares were chosen (the record's share_rule)
    share_alpha: float | None = None  # the power rule's exponent


# ---------------------------------------------------------------------------------------------
# planning: read every input's metadata, check they fit one layout
# ---------------------------------------------------------------------------------------------
def _open_input(name: str, opts: MixOptions) -> _Input:
    try:
        root = dataset_folder(name)
    except FileNotFoundError as err:
        raise MixError(f"input {name}: {err}") from err
    meta = UdhmDatasetMeta(root)
    record = meta.record
    if record is None:
        raise MixError(
            f"input {name} was not converted by unidextok-convert (no meta/unidextok_conversion.json): convert it "
            "first (unidextok-convert --source=lerobot --input=... for a LeRobot dataset)"
        )
    if record.hand_vocabulary:
        raise MixError(f"input {name} is itself a mix: mix the datasets it was made of instead")
    if meta.record_problem:
        raise MixError(f"input {name}: {meta.record_problem}; convert it again")
    names = meta.names(OBS_STATE)
    blocks = find_udhm_blocks(names)
    if not blocks:
        raise MixError(f"input {name}: {OBS_STATE} holds no UDHM block; convert it with unidextok-convert")
    rename = opts.name_map.get
    state_pass = [rename(names[i], names[i]) for i in passthrough_indices(names)]
    action_names = meta.names(ACTION)
    action_pass = [rename(action_names[i], action_names[i]) for i in passthrough_indices(action_names)]
    if action_names and [b.side for b in find_udhm_blocks(action_names)] != [b.side for b in blocks]:
        raise MixError(f"input {name}: its action blocks are not its state blocks; convert it again")
    return _Input(name, meta, [b.side for b in blocks], state_pass, action_pass, bool(action_names),
                  set(meta.split("recorded").test))  # fmt: skip


def _refuse_repeats(inputs: list[_Input], opts: MixOptions) -> None:
    """Inputs that hold the same episodes (conversion/fingerprint.py) are one error, unless `allow_repeats`."""
    if opts.allow_repeats:
        return
    repeat = find_repeat([(i.name, i.meta.root) for i in inputs])
    if repeat is not None:
        raise MixError(
            f"{repeat.describe()}: the mix would hold them twice. Pass each dataset once (--weights gives an input "
            "a larger share of the training frames), or --allow_repeats=true to mix them anyway"
        )


def _check_compatible(inputs: list[_Input], opts: MixOptions) -> None:
    fps = {i.name: i.meta.fps for i in inputs}
    if len(set(fps.values())) > 1:
        again = [f"{i.name} ({i.record.source})" for i in inputs if _resamples(i.record.source)]
        fixed = [f"{i.name} ({i.record.source})" for i in inputs if not _resamples(i.record.source)]
        raise MixError(
            f"the inputs have different frame rates {fps}, and a mix has one. "
            + (f"Convert {', '.join(again)} again with --fps=<the others' rate> (their source resamples "
               "time-stamped streams onto that grid). " if again else "")
            + (f"{', '.join(fixed)} keep the rate they were recorded at (their source has fixed-rate files): mix "
               "them only with inputs at that rate." if fixed else "")
        )
    mappings = {i.name: i.record.mapping for i in inputs}
    if len(set(mappings.values())) > 1:
        raise MixError(
            f"the inputs were converted with different UDHM mappings {mappings}: a block means one thing in a mix; "
            "convert them with the same --mapping (semantic)"
        )
    if opts.keep == "all":
        udhm_like = set(udhm_state_names(["right", "left"]))
        clash = sorted({n for i in inputs for n in i.state_pass + i.action_pass if n in udhm_like})
        if clash:
            raise MixError(f"--name_map maps passthrough columns onto UDHM block names {clash[:4]}; choose other names")


def _resamples(source: str) -> bool:
    try:
        return resamples(source)
    except ValueError:  # a source not registered here (another package's reader): say nothing about it
        return False


def _ordered_union(lists: list[list[str]]) -> list[str]:
    return list(dict.fromkeys(n for names in lists for n in names))


def repeat_factors(train_frames: list[int], weights: list[float]) -> list[int]:
    """Whole repeats of each input's training episodes so their frame shares come near `weights` (the input
    wanted least per frame is written once)."""
    if not weights:
        return [1] * len(train_frames)
    shares = checked_shares(weights, "--weights")  # divided by the largest first: 1e308 does not overflow
    per_frame = [s / max(f, 1) for s, f in zip(shares, train_frames, strict=True)]
    base = min(per_frame)
    return [max(1, round(p / base)) for p in per_frame]


def chosen_shares(train_frames: list[int], opts: MixOptions) -> tuple[list[float], str, float | None]:
    """(each input's recorded share, or [] when none is; the rule that chose them; its exponent) for inputs with
    `train_frames` training frames: `--weights` by sampling (rule "weights"), else the share rule ("power") for a
    mix of several inputs by sampling, else none ("weights" by copies; "frames": --share_rule=frames, one input,
    or copies without --weights)."""
    if opts.weights:
        by_sampling = opts.weights_by == "sampling"
        return (checked_shares(opts.weights, "--weights") if by_sampling else []), WEIGHTS, None
    if opts.share_rule == FRAMES or len(train_frames) < 2 or opts.weights_by != "sampling":
        return [], FRAMES, None
    shares = power_shares(train_frames, opts.share_alpha)
    low = min(range(len(shares)), key=shares.__getitem__)
    if shares[low] < MIN_SHARE:  # the floor --weights are held to (utils/number_checks.checked_shares)
        raise MixError(
            f"the share rule {rule_text(POWER, opts.share_alpha)} gives input {low} ({train_frames[low]} training "
            f"frames) a share of {shares[low]:.3g}, below the {MIN_SHARE:g} an input needs to count in the mix: "
            "lower --share_alpha, pass --weights, or leave that input out"
        )
    return shares, POWER, opts.share_alpha


# ---------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------
def _read_input(inp: _Input):
    """(table of every row, tasks by index) of an input."""
    import pyarrow as pa  # ~0.2 s; only when mixing
    import pyarrow.parquet as pq

    columns = [OBS_STATE, HAND_TYPE_KEY, UDHM_MASK_KEY, "episode_index", "task_index"]
    columns += [ACTION] if inp.has_action else []
    table = pa.concat_tables(pq.read_table(f, columns=columns) for f in data_files(inp.meta.root))
    tasks = pq.read_table(inp.meta.root / "meta" / "tasks.parquet").to_pydict()
    return table, dict(zip(tasks["task_index"], tasks["task"], strict=True))


def _matrix(column, width: int, dtype) -> np.ndarray:
    col = column.combine_chunks()
    flat = col.values if hasattr(col, "values") else col  # a (1,)-shaped feature is stored as a plain column
    return flat.to_numpy(zero_copy_only=False).reshape(len(col), width).astype(dtype, copy=False)


class _Mixer:
    """Places each input's columns into the common layout."""

    def __init__(self, inputs: list[_Input], opts: MixOptions):
        self.sides = _ordered_union([i.sides for i in inputs])
        self.state_pass = _ordered_union([i.state_pass for i in inputs]) if opts.keep == "all" else []
        self.action_pass = _ordered_union([i.action_pass for i in inputs]) if opts.keep == "all" else []
        self.vocabulary = sorted({h for i in inputs for t in i.meta.hand_types for h in t.split(",")})
        self.udhm = udhm_state_names(self.sides)
        self.opts = opts
        self.features = self._features()

    @property
    def num_hands(self) -> int:
        return len(self.sides)

    def _features(self) -> dict[str, dict]:
        state, action = [*self.state_pass, *self.udhm], [*self.action_pass, *self.udhm]
        features = {
            OBS_STATE: {"dtype": "float32", "shape": (len(state),), "names": state},
            ACTION: {"dtype": "float32", "shape": (len(action),), "names": action},
            HAND_TYPE_KEY: {"dtype": "string", "shape": (1,), "names": None},
            UDHM_MASK_KEY: {"dtype": "bool", "shape": (len(self.udhm),), "names": self.udhm},
            OBS_HAND_IDS: {"dtype": "int64", "shape": (self.num_hands,), "names": [f"{s}_hand" for s in self.sides]},
        }
        if self.state_pass or self.action_pass:
            common = _ordered_union([self.state_pass, self.action_pass])
            features[PASSTHROUGH_MASK_KEY] = {"dtype": "bool", "shape": (len(common),), "names": common}
        return features

    def episode(self, inp: _Input, rows, tasks: dict[int, str]) -> tuple[dict[str, np.ndarray], str]:
        """The mixed frames of one input episode (its rows of the input table)."""
        n = rows.num_rows
        names = inp.meta.names(OBS_STATE)
        state_in = _matrix(rows.column(OBS_STATE), len(names), np.float32)
        mask_in = _matrix(rows.column(UDHM_MASK_KEY), UDHM_DIM * len(inp.sides), bool)
        hand_types = rows.column(HAND_TYPE_KEY).to_pylist()
        if len(set(hand_types)) != 1:
            raise MixError(f"input {inp.name} changes hands inside an episode ({sorted(set(hand_types))[:3]})")
        own_hands = hand_types[0].split(",")
        block_of = {b.side: b for b in find_udhm_blocks(names)}
        state = np.zeros((n, len(self.state_pass) + UDHM_DIM * self.num_hands), np.float32)
        mask = np.zeros((n, UDHM_DIM * self.num_hands), bool)
        hand_ids = np.full((n, self.num_hands), -1, np.int64)
        block_hands = []
        for k, side in enumerate(self.sides):
            out = slice(len(self.state_pass) + UDHM_DIM * k, len(self.state_pass) + UDHM_DIM * (k + 1))
            if side in block_of:
                j = inp.sides.index(side)
                state[:, out] = state_in[:, block_of[side].slice]
                block_mask = mask_in[:, UDHM_DIM * j : UDHM_DIM * (j + 1)]
                mask[:, UDHM_DIM * k : UDHM_DIM * (k + 1)] = block_mask
                # the hand where it is there (a frame where it was not tracked: no hand, as a lacking side)
                hand_ids[:, k] = np.where(block_mask.any(axis=1), self.vocabulary.index(own_hands[j]), -1)
                block_hands.append(own_hands[j])
            else:  # a side this input lacks: zero block, zero mask, id -1 (hand_type names its first hand)
                block_hands.append(own_hands[0])
        frames = {OBS_STATE: state, UDHM_MASK_KEY: mask, OBS_HAND_IDS: hand_ids, HAND_TYPE_KEY: ",".join(block_hands)}
        self._passthrough(frames, inp, state_in, names, OBS_STATE, self.state_pass, inp.state_pass)
        frames[ACTION] = self._action(inp, rows, state, mask)
        if PASSTHROUGH_MASK_KEY in self.features:
            common = self.features[PASSTHROUGH_MASK_KEY]["names"]
            real = set(inp.state_pass) | set(inp.action_pass)
            frames[PASSTHROUGH_MASK_KEY] = np.tile(np.array([c in real for c in common]), (n, 1))
        task_index = rows.column("task_index").to_numpy()
        return frames, tasks[int(task_index[0])]

    def _passthrough(self, frames, inp, values, names, key, common, own) -> None:
        if not common:
            return
        for col, name in zip(passthrough_indices(names), own, strict=True):
            frames[key][:, common.index(name)] = values[:, col]

    def _action(self, inp: _Input, rows, state: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The input's actions in the common layout, or the action rule's for an input without actions."""
        n = rows.num_rows
        width = len(self.action_pass) + UDHM_DIM * self.num_hands
        if not inp.has_action:
            ahead = np.minimum(np.arange(n) + self.opts.action_ahead, n - 1)
            action = np.zeros((n, width), np.float32)
            # the hand k frames later, where the hand is there now (an absent hand commands nothing)
            action[:, len(self.action_pass) :] = state[ahead, len(self.state_pass) :] * mask
            return action
        action_names = inp.meta.names(ACTION)
        values = _matrix(rows.column(ACTION), len(action_names), np.float32)
        action = np.zeros((n, width), np.float32)
        block_of = {b.side: b for b in find_udhm_blocks(action_names)}
        for k, side in enumerate(self.sides):
            if side in block_of:
                at = len(self.action_pass) + UDHM_DIM * k
                action[:, at : at + UDHM_DIM] = values[:, block_of[side].slice]
        frames = {ACTION: action}
        self._passthrough(frames, inp, values, action_names, ACTION, self.action_pass, inp.action_pass)
        return action


def action_delta_stats(root: str | Path, episodes: list[int]) -> dict[str, dict[str, dict]]:
    """Per UDHM block side and hand, the mean and std of the relative action (`action - state`, 22 each) over
    the frames of `episodes` of the mixed dataset at `root` where the block holds that hand: the scale
    `unidextok.hand_action_scale` gives each hand's relative actions (`processor/hand_action_scale.py`).
    `unidextok-mix` records it over the training episodes; to train on fewer of them, recompute it over those
    and rewrite the record's `action_delta_stats`."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    meta = UdhmDatasetMeta(Path(root))
    state_names, action_names = meta.names(OBS_STATE), meta.names(ACTION)
    vocabulary = meta.record.hand_vocabulary if meta.record else []
    if not vocabulary or OBS_HAND_IDS not in meta.features:
        raise MixError(
            f"{root} is not a mixed dataset (no hand_vocabulary / {OBS_HAND_IDS}); write it with unidextok-mix"
        )
    columns = [OBS_STATE, ACTION, OBS_HAND_IDS, "episode_index"]
    table = pa.concat_tables(pq.read_table(f, columns=columns) for f in data_files(meta.root))
    rows = np.isin(table.column("episode_index").to_numpy(), list(episodes))
    state = _matrix(table.column(OBS_STATE), len(state_names), np.float64)[rows]
    action = _matrix(table.column(ACTION), len(action_names), np.float64)[rows]
    ids = _matrix(table.column(OBS_HAND_IDS), len(meta.names(OBS_HAND_IDS)), np.int64)[rows]
    in_state = {b.side: b.slice for b in find_udhm_blocks(state_names)}
    out: dict[str, dict[str, dict]] = {}
    for k, block in enumerate(find_udhm_blocks(action_names)):
        delta = action[:, block.slice] - state[:, in_state[block.side]]  # (N, 22)
        for v in np.unique(ids[:, k]):
            if v < 0:
                continue
            d = delta[ids[:, k] == v]
            out.setdefault(block.side, {})[vocabulary[v]] = {
                "mean": [round(float(x), 8) for x in d.mean(0)],
                "std": [round(float(x), 8) for x in d.std(0)],
                "frames": len(d),
            }
    return out


def mixed_wrist_frame(inputs: list[_Input], opts: MixOptions, mixer: _Mixer) -> dict:
    """The mix's `wrist_frame`: every input's grasp centre per hand, its columns under the mix's names
    (`data/wrist_frame.py`); {} when an input records none or the mix drops the columns (`--keep=hands`), so a
    policy on it keeps the wrist as recorded."""
    frames = [i.record.wrist_frame for i in inputs]
    if not any(frames):
        return {}
    if not all(frames):
        logger.warning("inputs %s record no wrist frame: the mix has none (grasp-centre frame off)",
                       [i.name for i in inputs if not i.record.wrist_frame])  # fmt: skip
        return {}
    merged = merge_frames([WristFrame.from_dict(f, f"{i.name}: its record's wrist_frame").renamed(opts.name_map)
                           for f, i in zip(frames, inputs, strict=True)], "unidextok-mix")  # fmt: skip
    if merged.missing_columns(mixer.state_pass, mixer.action_pass):
        logger.warning("the inputs record each hand's grasp centre, but --keep=%s drops their wrist columns %s: the mix "
                       "has no wrist frame (a policy on it learns the wrist as recorded); --keep=all keeps it",
                       opts.keep, merged.columns)  # fmt: skip
        return {}
    return merged.to_dict()


def mix(opts: MixOptions) -> MixReport:
    """Mix `opts.inputs` into one dataset at `opts.root` (module docstring)."""
    t0 = time.perf_counter()
    target = recover(opts.root)  # before anything can fail: a dead run's half-replaced mix is put back
    inputs = [_open_input(name, opts) for name in opts.inputs]
    claim(target, Kind.MIX, inputs=[i.meta.root for i in inputs], overwrite=opts.overwrite)
    try:
        return _mix_into(target, inputs, opts, t0)
    finally:
        release(target)  # the destination's lock (data/destination.py), however the mix ended


def _mix_into(target: Path, inputs: list[_Input], opts: MixOptions, t0: float) -> MixReport:
    """The mix of the opened `inputs` into the claimed `target`."""
    _check_compatible(inputs, opts)
    _refuse_repeats(inputs, opts)  # after the metadata checks: it reads every input's states
    mixer = _Mixer(inputs, opts)
    train_frames = [
        sum(length for e, length in (i.meta.episode_lengths or {}).items() if e not in i.test) for i in inputs
    ]
    for i, frames in zip(inputs, train_frames, strict=True):  # its hands would have no per-hand statistics
        if not frames:
            raise MixError(f"input {i.meta.root} has no training episodes: all {i.meta.total_episodes} are in its "
                           "recorded test split, so the mix could neither train on its hands nor normalise them; "
                           "convert it again with a smaller --test_fraction (or more episodes), or leave it out")  # fmt: skip
    repeats = repeat_factors(train_frames, opts.weights if opts.weights_by == "copies" else [])
    asked, share_rule, share_alpha = chosen_shares(train_frames, opts)
    written = sum(r * f for r, f in zip(repeats, train_frames, strict=True))
    if written > MAX_GROWTH * max(sum(train_frames), 1):
        raise MixError(
            f"--weights {weights_text(opts.weights)} would write the training episodes {repeats} times ({written} "
            f"frames, more than {MAX_GROWTH:g}x the inputs' {sum(train_frames)}): choose weights closer to the inputs' "
            "sizes"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(target)
    writer = UdhmDatasetWriter(tmp, opts.repo_id, int(inputs[0].meta.fps), mixer.features)
    episodes: list[EpisodeRecord] = []
    test: list[int] = []
    total = sum(i.meta.total_episodes + (repeats[k] - 1) * (i.meta.total_episodes - len(i.test))
                for k, i in enumerate(inputs))  # fmt: skip
    bar = progress_bar(total=total, desc="mix", unit="ep", disable=not opts.progress)
    try:
        for k, inp in enumerate(inputs):
            table, tasks = _read_input(inp)
            index = table.column("episode_index").to_numpy()
            for e in range(inp.meta.total_episodes):
                rows = table.filter(index == e)
                if rows.num_rows == 0:
                    continue
                frames, task = mixer.episode(inp, rows, tasks)
                split = "test" if e in inp.test else "train"
                for r in range(repeats[k] if split == "train" else 1):
                    at = writer.add_episode(frames, task=task)
                    origin = {"mix_source": k, "source_episode_index": e, **({"repeat": r} if r else {})}
                    episodes.append(EpisodeRecord(at, f"{inp.name}#{e}", split, rows.num_rows,
                                                  frames[HAND_TYPE_KEY], origin))  # fmt: skip
                    if split == "test":
                        test.append(at)
                    bar.update(1)
        bar.close()
        writer.finalize(splits={"train": f"0:{writer.num_episodes}"})
        sources = [
            MixedSource(
                dataset=i.name, robot_type=i.meta.robot_type, source=i.record.source, sides=i.sides,
                hands=list(i.record.hands), num_episodes=i.meta.total_episodes, test_episodes=sorted(i.test),
                weight=opts.weights[k] if opts.weights else 1.0, repeats=repeats[k], has_action=i.has_action,
                share=round(asked[k], 8) if asked else 0.0,
                native_layouts=i.record.native_layouts,
            )
            for k, i in enumerate(inputs)
        ]  # fmt: skip
        record = ConversionRecord(
            source=MIX_SOURCE,
            license="; ".join(dict.fromkeys(f"{i.record.source}: {i.record.license}" for i in inputs)),
            description=f"mix of {len(inputs)} converted datasets: " + ", ".join(opts.inputs),
            synthetic=any(i.record.synthetic for i in inputs),
            mapping=inputs[0].record.mapping,
            keep=opts.keep,
            fps=int(inputs[0].meta.fps),
            split_method="each input's own test episodes, renumbered",
            sides=mixer.sides,
            hands=mixer.vocabulary,
            has_action=True,
            passthrough={OBS_STATE: mixer.state_pass, ACTION: mixer.action_pass},
            listed_episodes=sum(i.meta.total_episodes for i in inputs),
            num_episodes=writer.num_episodes,
            test_episodes=test,
            episodes=episodes,
            hand_vocabulary=mixer.vocabulary,
            sources=sources,
            name_map=dict(opts.name_map),
            wrist_frame=mixed_wrist_frame(inputs, opts, mixer),
            share_rule=share_rule,
            share_alpha=share_alpha,
            action_rule=(
                f"inputs without actions: action[t] = state[t + {opts.action_ahead}] (the last frames hold the last state)"
                if not all(i.has_action for i in inputs)
                else ""
            ),
        )
        write_record(tmp, record)  # (the statistics below read the record's vocabulary)
        train = [e.episode_index for e in episodes if e.split == "train"]
        record.action_delta_stats = action_delta_stats(tmp, train)
        record.hand_stats = hand_stats(tmp, train)  # per-hand normalisation (conversion/hand_stats.py)
        write_record(tmp, record)
        write_card(tmp, repo_id=opts.repo_id, record=record, num_frames=writer.num_frames, features=writer.features)
        move_into_place(tmp, target, Kind.MIX, opts.overwrite)
    except BaseException:
        bar.close()
        writer.abort()
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shares = [r * f for r, f in zip(repeats, train_frames, strict=True)]
    return MixReport(target, writer.num_episodes, writer.num_frames, test, sources,
                     asked or [s / max(sum(shares), 1) for s in shares], time.perf_counter() - t0,
                     share_rule, share_alpha)  # fmt: skip


def budget_steps(alone_steps: int, share: float) -> int:
    """The budget rule for a mix: the updates in which an input with `share` of the sampled training frames sees
    its frames as often as in `alone_steps` updates on it alone (`alone_steps / share`; docs/pooling.md
    measures it against matched compute)."""
    if not 0 < share <= 1:
        raise MixError(f"a share of the training frames must be in (0, 1], got {share}")
    return max(1, round(alone_steps / share))


def format_report(report: MixReport) -> str:
    """The summary `unidextok-mix` prints: how the shares were chosen, then per input its episodes, repeats,
    training-frame share and the budget rule's factor (`budget_steps`)."""
    lines = [
        f"wrote {report.root}: {report.num_episodes} episodes, {report.num_frames} frames, "
        f"{len(report.test_episodes)} test episodes ({report.seconds:.1f} s)"
    ]
    if len(report.sources) > 1:
        lines.append(_shares_line(report))
    for s, share in zip(report.sources, report.train_shares, strict=True):
        lines.append(
            f"  {s.dataset}: {s.robot_type or s.source}, hands {', '.join(s.hands)} ({', '.join(s.sides)}), "
            f"{s.num_episodes} episodes ({len(s.test_episodes)} test), training episodes x{s.repeats}: "
            + (f"{share * 100:.3g}% of the sampled training frames (share recorded)" if s.share else
               f"{share * 100:.3g}% of the training frames")
            + ("" if s.has_action else "; actions by the action rule")
            + (f"; budget rule: {1 / share:.1f}x the updates it would train alone" if share > 0 else "")
        )
    return "\n".join(lines)


def _shares_line(report: MixReport) -> str:
    """'shares by the rule frames^0.43 (override with --weights): input 0 33.3 %, input 1 66.7 %' and the like."""
    each = ", ".join(f"input {k} {share * 100:.1f} %" for k, share in enumerate(report.train_shares))
    if report.share_rule == POWER:
        return f"shares by the rule {rule_text(POWER, report.share_alpha)} (override with --weights): {each}"
    if report.share_rule == WEIGHTS:
        recorded = any(s.share for s in report.sources)
        return f"shares by --weights ({'recorded' if recorded else 'as copies, none recorded'}): {each}"
    return f"shares: each input at its frame share (no share recorded): {each}"


__all__ = [
    "MixError",
    "MixOptions",
    "MixReport",
    "budget_steps",
    "chosen_shares",
    "format_report",
    "mix",
    "repeat_factors",
]
