"""RawEpisode (native units) -> UDHM arrays for the writer, with per-episode validation.

Every hand stream goes through `hands.get(hand).to_udhm(native, side, mapping)`: robot joint values by
semantic insertion (or append_pad), human MANO-21 keypoints through the UDHM inverse kinematics.
Frames where a hand is not present (`HandStream.valid` False) get zeros and a False mask in that block;
leading/trailing frames where no hand is present are trimmed. Anything that would write garbage
(NaN, out-of-range raw values, wrong shapes, unknown hands/sides) raises `EpisodeError`.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION, MAPPINGS, OBS_STATE, SIDES, UDHM_DIM
from lerobot_unidextok.conversion.episode import HandStream, Passthrough, RawEpisode, VideoSegment
from lerobot_unidextok.errors import InvalidInputError

ANGLE_BOUND_RAD = 2 * np.pi  # no UDHM joint angle is beyond this: larger values are unit errors


class EpisodeError(InvalidInputError):
    """One episode cannot be converted; `source_file` and `reason` go into the error report."""

    def __init__(self, source_file: str, reason: str):
        super().__init__(f"{source_file}: {reason}")
        self.source_file = source_file
        self.reason = reason


@dataclass
class UdhmEpisode:
    """One episode in UDHM, ready for the writer (H hands, T frames)."""

    source_file: str
    fps: float
    task: str
    sides: tuple[str, ...]  # (H,)
    hands: tuple[str, ...]  # (H,) hand spec names
    state_rad: np.ndarray  # (T, 22 * H) float32
    mask: np.ndarray  # (T, 22 * H) bool
    action_rad: np.ndarray | None = None  # (T, 22 * H) float32
    trimmed_frames: int = 0
    absent_hand_frames: int = 0  # hand-frames zero-filled because the hand was not present
    zero_hand_sides: tuple[str, ...] = ()  # hands whose state was 0 throughout: converted as absent
    synthetic: bool = False
    extra: dict = field(default_factory=dict)
    # -- whole robot (see RawEpisode): trimmed like the hand arrays ------------------------------------
    passthrough: dict[str, Passthrough] = field(default_factory=dict)
    native_names: dict[str, list[str]] = field(default_factory=dict)
    native_keys: dict[str, str] = field(default_factory=dict)
    dropped: dict[str, list[str]] = field(default_factory=dict)  # source columns left out (see RawEpisode)
    # every source column name where `native_names` lists only the kept (hand) columns (`--keep=hands`)
    source_names: dict[str, list[str]] = field(default_factory=dict)
    hand_columns: tuple[tuple[tuple[str, ...] | None, tuple[str, ...] | None], ...] = ()  # (H,) (state, action)
    copied: dict[str, Any] = field(default_factory=dict)
    copied_features: dict[str, dict] = field(default_factory=dict)
    copied_stats: dict[str, dict] = field(default_factory=dict)
    videos: dict[str, VideoSegment] = field(default_factory=dict)
    video_features: dict[str, dict] = field(default_factory=dict)
    source_episode: dict = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return int(self.state_rad.shape[0])

    @property
    def hand_type(self) -> str:
        return ",".join(self.hands)

    @property
    def signature(self) -> tuple:
        """What must match across a dataset's episodes: block sides, actions, passthrough columns, copied
        features and videos (the dataset's features are set by its first episode)."""
        return (
            self.sides,
            self.action_rad is not None,
            tuple((k, p.names) for k, p in sorted(self.passthrough.items())),
            tuple(sorted(self.copied_features)),
            tuple(sorted(self.videos)),
        )

    def without_robot(self) -> UdhmEpisode:
        """The hands-only episode (`--keep=hands`): no passthrough columns, copied features or videos.

        The native vectors shrink to the hand columns (source order), so a hands-only dataset decodes to
        the hands' own commands; `source_names` keeps every source column name to place them in the
        robot's full vector.
        """
        native_names, source_names = {}, {}
        for key, which in ((OBS_STATE, 0), (ACTION, 1)):
            hand_cols = [c for pair in self.hand_columns for c in (pair[which] or ())]
            if not hand_cols:
                continue
            p = self.passthrough.get(key)
            full = list(self.native_names.get(key) or [*(p.names if p is not None else ()), *hand_cols])
            native_names[key] = [n for n in full if n in set(hand_cols)]
            if native_names[key] != full:
                source_names[key] = full
        return replace(
            self,
            passthrough={},
            copied={},
            copied_features={},
            copied_stats={},
            videos={},
            video_features={},
            native_names=native_names,
            source_names=source_names,
            dropped={},  # the native vectors are the hand columns only
        )


def state_names(sides: tuple[str, ...] | list[str]) -> list[str]:
    """`<side>_<udhm joint>` names of a (22 * H,) state, blocks in `sides` order."""
    return udhm_state_names(list(sides))


def _frames(idx: np.ndarray, limit: int = 8) -> str:
    shown = ", ".join(str(i) for i in idx[:limit])
    return f"[{shown}{', ...' if len(idx) > limit else ''}] ({len(idx)} frames)"


def _map_values(
    spec,
    values: np.ndarray,
    side: str,
    mapping: str,
    what: str,
    src: str,
    present: np.ndarray,
    first: int = 0,
) -> np.ndarray:
    """(T, ...) native -> (T, 22) float32 rad; absent frames are zero. `first`: the source frame number of
    frame 0 (leading frames without a hand are trimmed), for the messages."""
    from lerobot_unidextok.hands import check_units
    from lerobot_unidextok.udhm.ik import KeypointFramesError

    num = values.shape[0]
    out = np.zeros((num, UDHM_DIM), dtype=np.float32)
    sel = values[present]
    if sel.size and not np.isfinite(sel).all():
        bad = ~np.isfinite(sel.reshape(sel.shape[0], -1)).all(axis=1)
        raise EpisodeError(
            src,
            f"NaN/inf in {what} of the {side} hand at frames {_frames(first + np.flatnonzero(present)[bad])}",
        )
    if not present.any():
        return out
    try:
        check_units(spec, sel, side)  # wrong units (a tiny corner of the range, or beyond it): likely fix
        udhm = np.asarray(spec.to_udhm(sel, side=side, mapping=mapping), dtype=np.float64)
    except EpisodeError:
        raise
    except KeypointFramesError as exc:  # its frames count the present frames only: name the episode's
        frames = first + np.flatnonzero(present)[exc.frames.reshape(-1)]
        raise EpisodeError(src, f"{what} of the {side} hand: {exc.problem} in frames {_frames(frames)}{exc.hint}") from exc
    except (ValueError, KeyError) as exc:
        raise EpisodeError(src, f"{what} of the {side} {spec.name} hand: {exc}") from exc
    if not np.isfinite(udhm).all():
        raise EpisodeError(src, f"UDHM mapping of the {side} {spec.name} {what} produced NaN/inf")
    if np.abs(udhm).max(initial=0.0) > ANGLE_BOUND_RAD:
        raise EpisodeError(
            src,
            f"UDHM {what} of the {side} {spec.name} hand reaches {np.abs(udhm).max():.3g} rad: wrong units?",
        )
    out[present] = udhm.astype(np.float32)
    return out


def _check_stream(stream: HandStream, spec, num: int, src: str) -> np.ndarray:
    if stream.side not in SIDES:
        raise EpisodeError(src, f"hand side {stream.side!r} is not one of {SIDES}")
    state = np.asarray(stream.state_native)
    expected = "(T, 21, 3) keypoints_m" if spec.kind == "keypoints" else f"(T, {spec.num_native}) native joints"
    ok = state.shape == (num, 21, 3) if spec.kind == "keypoints" else state.shape == (num, spec.num_native)
    if not ok:
        raise EpisodeError(
            src,
            f"{stream.side} {spec.name} state has shape {state.shape}, expected {expected} with T={num}",
        )
    if stream.action_native is not None and np.asarray(stream.action_native).shape != state.shape:
        raise EpisodeError(
            src,
            f"{stream.side} action shape {np.asarray(stream.action_native).shape} != state shape {state.shape}",
        )
    if stream.valid is None:
        return np.ones(num, dtype=bool)
    valid = np.asarray(stream.valid)
    if valid.shape != (num,) or valid.dtype != bool:
        raise EpisodeError(
            src,
            f"{stream.side} valid must be a bool array of shape ({num},), got {valid.dtype} {valid.shape}",
        )
    return valid


ZERO_HANDS = ("absent", "keep")


def map_episode(raw: RawEpisode, mapping: str = "semantic", zero_hands: str = "absent") -> UdhmEpisode:
    """Validate one raw episode and map every hand to UDHM; raises EpisodeError with the reason.

    `zero_hands="absent"`: a robot hand whose state is 0 in every joint of every frame of the episode was not
    recorded (a two-hand layout with one hand's columns left at zero): it is converted as absent (zero block,
    zero mask) and listed in `zero_hand_sides`, never as a closed fist. "keep": converted as values."""
    from lerobot_unidextok import hands as hand_registry

    src = raw.source_file
    if mapping not in MAPPINGS:
        raise ValueError(f"mapping must be one of {MAPPINGS}, got {mapping!r}")
    if not raw.hands:
        raise EpisodeError(src, "episode has no hand streams")
    if not (np.isfinite(raw.fps) and raw.fps > 0):
        raise EpisodeError(src, f"fps must be positive, got {raw.fps!r}")
    sides = tuple(s.side for s in raw.hands)
    if len(set(sides)) != len(sides):
        raise EpisodeError(src, f"two hand streams share a side: {sides}")
    has_action = [s.action_native is not None for s in raw.hands]
    if any(has_action) and not all(has_action):
        raise EpisodeError(
            src,
            "some hands have actions and others do not; give actions for all hands or none",
        )
    num = int(np.asarray(raw.hands[0].state_native).shape[0])
    if num == 0:
        raise EpisodeError(src, "episode has 0 frames")

    if zero_hands not in ZERO_HANDS:
        raise ValueError(f"zero_hands must be one of {ZERO_HANDS}, got {zero_hands!r}")
    specs, valids, zero_sides = [], [], []
    for stream in raw.hands:
        try:
            spec = hand_registry.get(stream.hand)
        except (KeyError, ValueError) as exc:
            raise EpisodeError(src, f"unknown hand {stream.hand!r}: {exc}") from exc
        specs.append(spec)
        valid = _check_stream(stream, spec, num, src)
        if zero_hands == "absent" and spec.kind == "joints" and not np.any(np.asarray(stream.state_native)):
            valid = np.zeros(num, dtype=bool)
            zero_sides.append(stream.side)
        valids.append(valid)
    present = np.stack(valids)  # (H, T)
    any_present = present.any(axis=0)
    if not any_present.any():
        raise EpisodeError(
            src,
            "no frame has a present hand"
            + (f" (every hand's state is 0 throughout: {zero_sides}; --zero_hands=keep converts zeros as values)"
               if zero_sides else " (all valid flags False)"),
        )  # fmt: skip
    first, last = int(np.argmax(any_present)), num - int(np.argmax(any_present[::-1]))

    states, masks, actions = [], [], []
    for stream, spec, valid in zip(raw.hands, specs, valids, strict=True):
        keep = valid[first:last]
        native = np.asarray(stream.state_native)[first:last]
        states.append(_map_values(spec, native, stream.side, mapping, "state", src, keep, first))
        masks.append(np.where(keep[:, None], spec.mask(mapping)[None, :], False))
        if stream.action_native is not None:
            act = np.asarray(stream.action_native)[first:last]
            actions.append(_map_values(spec, act, stream.side, mapping, "action", src, keep, first))

    passthrough = _check_passthrough(raw, num, src, has_action=any(has_action))
    trimmed = (first, last) != (0, num)
    return UdhmEpisode(
        source_file=src,
        fps=float(raw.fps),
        task=str(raw.task or ""),
        sides=sides,
        hands=tuple(spec.name for spec in specs),
        state_rad=np.concatenate(states, axis=1),
        mask=np.concatenate(masks, axis=1),
        action_rad=np.concatenate(actions, axis=1) if actions else None,
        trimmed_frames=num - (last - first),
        absent_hand_frames=int((~present[:, first:last]).sum()),
        zero_hand_sides=tuple(zero_sides),
        synthetic=bool(raw.extra.get("synthetic", False)),
        extra=dict(raw.extra),
        passthrough={k: Passthrough(p.names, p.values[first:last]) for k, p in passthrough.items()},
        native_names={k: list(v) for k, v in raw.native_names.items()},
        native_keys=dict(raw.native_keys),
        dropped={k: list(v) for k, v in raw.dropped.items()},
        hand_columns=tuple((s.state_columns, s.action_columns) for s in raw.hands),
        copied={k: _slice_column(v, first, last, num, src, k) for k, v in raw.copied.items()},
        copied_features=dict(raw.copied_features),
        copied_stats=dict(raw.copied_stats),
        videos={k: _trim_video(v, first, last, raw.fps) for k, v in raw.videos.items()}
        if trimmed
        else dict(raw.videos),
        video_features=dict(raw.video_features),
        source_episode=dict(raw.source_episode),
    )


def _check_passthrough(raw: RawEpisode, num: int, src: str, has_action: bool) -> dict[str, Passthrough]:
    """The non-hand columns must be finite-shaped (T, P) blocks of the episode's length."""
    for key, p in raw.passthrough.items():
        if p.values.shape[0] != num:
            raise EpisodeError(src, f"{key} passthrough columns have {p.values.shape[0]} frames, the hands {num}")
        if key == "action" and not has_action:
            raise EpisodeError(src, "action passthrough columns given but the hands have no actions")
        values = np.asarray(p.values)
        if values.dtype.kind == "f" and not np.isfinite(values).all():
            bad = ~np.isfinite(values)
            columns = [p.names[i] for i in np.flatnonzero(bad.any(axis=0))]
            raise EpisodeError(
                src,
                f"NaN/inf in {key} columns {columns[:6]}{' ...' if len(columns) > 6 else ''} at frames "
                f"{_frames(np.flatnonzero(bad.any(axis=1)))}: these frames would make the dataset's statistics NaN "
                "and every training loss NaN; fix or drop them in the source (--on_error=skip skips the episode)",
            )
    missing = set(raw.copied_features) ^ set(raw.copied)
    if missing:
        raise EpisodeError(src, f"copied features and columns disagree: {sorted(missing)}")
    for key, column in raw.copied.items():
        bad = nonfinite_rows(column)
        if bad is not None and len(bad):
            raise EpisodeError(
                src,
                f"NaN/inf in the copied feature {key} at frames {_frames(bad)}: the dataset's statistics and every "
                "training loss that reads it would be NaN; fix or drop those frames in the source, convert with "
                "--keep=hands to leave the feature out, or --on_error=skip to skip the episode",
            )
    return raw.passthrough


def nonfinite_rows(column) -> np.ndarray | None:
    """Frame indices of a (T,) Arrow column (numbers, or lists of them) holding NaN or inf; None when the
    column does not hold floating-point numbers (strings, images, integers)."""
    import pyarrow as pa  # the copied columns are Arrow arrays already: pyarrow is loaded
    import pyarrow.compute as pc

    arr = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    rows = np.arange(len(arr))
    while pa.types.is_list(arr.type) or pa.types.is_large_list(arr.type) or pa.types.is_fixed_size_list(arr.type):
        rows = rows[pc.list_parent_indices(arr).to_numpy()]
        arr = arr.flatten()
    if not pa.types.is_floating(arr.type):
        return None
    values = arr.to_numpy(zero_copy_only=False)
    return np.unique(rows[~np.isfinite(values)])


def _slice_column(column, first: int, last: int, num: int, src: str, key: str):
    if len(column) != num:
        raise EpisodeError(src, f"copied feature {key!r} has {len(column)} frames, the hands {num}")
    return column if (first, last) == (0, num) else column.slice(first, last - first)


def _trim_video(video: VideoSegment, first: int, last: int, fps: float) -> VideoSegment:
    """The segment of the kept frames [first, last) (leading/trailing frames without a hand trimmed)."""
    return VideoSegment(video.path, video.from_s + first / fps, min(video.to_s, video.from_s + last / fps))


def to_sides(ep: UdhmEpisode, sides: tuple[str, ...]) -> UdhmEpisode:
    """Reorder `ep`'s blocks to `sides`; sides the episode lacks get zeros, a False mask and the
    spec name of its first hand in `hand_type` (a single-hand source whose sequences are left or right)."""
    if ep.sides == tuple(sides):
        return ep
    extra = [s for s in ep.sides if s not in sides]
    if extra:
        raise EpisodeError(
            ep.source_file,
            f"episode has hand side(s) {extra} outside the dataset layout {tuple(sides)}",
        )
    num = ep.num_frames
    blocks = {s: i for i, s in enumerate(ep.sides)}

    def arrange(values: np.ndarray | None, fill) -> np.ndarray | None:
        if values is None:
            return None
        parts = [
            values[:, blocks[s] * UDHM_DIM : (blocks[s] + 1) * UDHM_DIM]
            if s in blocks
            else np.full((num, UDHM_DIM), fill, values.dtype)
            for s in sides
        ]
        return np.concatenate(parts, axis=1)

    hands = tuple(ep.hands[blocks[s]] if s in blocks else ep.hands[0] for s in sides)
    absent = num * (len(sides) - len(ep.sides))
    columns = {s: ep.hand_columns[blocks[s]] if s in blocks and ep.hand_columns else (None, None) for s in sides}
    return replace(
        ep,
        sides=tuple(sides),
        hands=hands,
        state_rad=arrange(ep.state_rad, 0.0),
        mask=arrange(ep.mask, False),
        action_rad=arrange(ep.action_rad, 0.0),
        absent_hand_frames=ep.absent_hand_frames + absent,
        hand_columns=tuple(columns[s] for s in sides),
    )
