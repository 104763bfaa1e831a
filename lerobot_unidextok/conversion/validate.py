"""Check an existing converted UDHM dataset against the converted-dataset contract.

Checks: format version, features (UDHM blocks found by name after any passthrough columns, dtypes,
shapes), frame/episode counts, hand_type names, mask consistency (zeros where masked, masks equal to the
hand specs' masks), value limits, LeRobot `splits` ranges, the recorded test episodes, the native layout,
card, and that `LeRobotDataset(repo_id, root=...)` loads it and returns a frame. Every failed or warned
check says why. Datasets edited by `lerobot-edit-dataset` (no card, no conversion record) get warnings,
not failures: they still train and evaluate (`data.splits`).
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.compute as pc
import pyarrow.parquet as pq

from lerobot_unidextok.blocks import feature_names, find_udhm_blocks, udhm_state_names
from lerobot_unidextok.constants import (
    ACTION,
    DATA_GLOB,
    EPISODES_META_GLOB,
    HAND_TYPE_KEY,
    INFO_PATH,
    OBS_STATE,
    UDHM_DIM,
    UDHM_MASK_KEY,
)
from lerobot_unidextok.conversion.mapping import ANGLE_BOUND_RAD
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.record import ConversionRecord, RecordError

LIMIT_TOL_RAD = 1e-3


@dataclass
class Check:
    name: str
    ok: bool
    detail: str = ""
    warning: bool = False  # informational: does not fail the dataset


@dataclass
class ValidationReport:
    root: Path
    checks: list[Check] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(c.ok or c.warning for c in self.checks)

    def add(self, name: str, ok: bool, detail: str = "", warning: bool = False) -> bool:
        self.checks.append(Check(name, bool(ok), detail, warning))
        return bool(ok)

    def failed(self) -> list[Check]:
        return [c for c in self.checks if not c.ok and not c.warning]

    def table(self) -> str:
        width = max(len(c.name) for c in self.checks) if self.checks else 10
        lines = [f"validate {self.root}"]
        for c in self.checks:
            status = "ok" if c.ok else ("WARN" if c.warning else "FAIL")
            lines.append(f"  {status:4s}  {c.name:<{width}}  {c.detail}")
        lines.append(f"result: {'VALID' if self.ok else 'INVALID'} ({len(self.failed())} failed)")
        return "\n".join(lines)


def _native_layout_problems(record: ConversionRecord, feats: dict) -> list[str]:
    """What in the recorded native layouts does not fit the dataset's features. (Each layout already checked
    itself when the record was read: hand columns among the native names, passthrough columns among the
    converted ones, a UDHM block for every hand.)"""
    problems = []
    for key, layout in record.native_layouts.items():
        if key not in feats:
            problems.append(f"{key}: not a feature of the dataset")
            continue
        if layout.names != feature_names(feats[key]):
            problems.append(f"{key}: the layout's converted names are not the feature's names in meta/info.json")
        native = set(layout.native_names)
        if layout.source_names and [n for n in layout.source_names if n in native] != layout.native_names:
            problems.append(f"{key}: native names are not the source_names {layout.source_names[:4]}... in source order")
    return problems


def validate_dataset(root: str | Path, repo_id: str | None = None, load: bool = True) -> ValidationReport:
    """Validate the converted dataset at `root`; never raises on a bad dataset, reports instead."""
    root = Path(root)
    rep = ValidationReport(root)
    info_path = root / INFO_PATH
    if not rep.add("meta/info.json", info_path.is_file(), str(info_path)):
        return rep
    info = json.loads(info_path.read_text())
    rep.add(
        "codebase_version",
        info.get("codebase_version") == "v3.0",
        str(info.get("codebase_version")),
    )
    feats = info.get("features", {})
    state = _check_features(rep, feats)
    if state is None or not rep.ok:
        return rep
    rows = _read_rows(rep, root, feats, state.num_hands)
    if rows is None:
        return rep
    total_eps = int(info.get("total_episodes", -1))
    _check_counts(rep, info, rows, total_eps)
    _check_values(rep, rows)
    _check_finite_columns(rep, root, feats)
    try:
        meta = UdhmDatasetMeta(root)
    except RecordError as exc:
        rep.add("conversion record", False, str(exc))
        return rep
    record = meta.record
    _check_hand_types(rep, rows, state.sides, record.mapping if record else "semantic")
    _check_splits(rep, meta)
    if record is not None and record.native_layouts:
        problems = _native_layout_problems(record, feats)
        rep.add("native layout", not problems, "; ".join(problems) or f"{sorted(record.native_layouts)}")
    _check_files(rep, root, rows.num_rows, total_eps)
    if load:
        _check_lerobot_load(rep, root, repo_id or info.get("repo_id") or f"local/{root.name}", state.dim)
    return rep


# ---------------------------------------------------------------------------------------------
# the checks, in report order
# ---------------------------------------------------------------------------------------------
@dataclass
class _StateBlocks:
    """Where the UDHM blocks sit in `observation.state`."""

    dim: int
    sides: list[str]

    @property
    def num_hands(self) -> int:
        return len(self.sides)


@dataclass
class _Rows:
    """The UDHM blocks of every frame, (n, H, 22) each, and the columns the checks read."""

    table: Any  # pyarrow.Table: state, mask, hand_type, episode_index (+ action)
    state: np.ndarray
    mask: np.ndarray
    action: np.ndarray | None  # None when the action has no UDHM blocks

    @property
    def num_rows(self) -> int:
        return self.table.num_rows


def _check_features(rep: ValidationReport, feats: dict) -> _StateBlocks | None:
    """observation.state (passthrough columns, then one or two UDHM blocks), action, udhm_mask, hand_type."""
    st = feats.get(OBS_STATE)
    if not rep.add(
        "observation.state feature",
        st is not None and st.get("dtype") == "float32",
        str(st and st.get("dtype")),
    ):
        return None
    dim = int(st["shape"][0])
    names = feature_names(st)
    try:
        blocks = find_udhm_blocks(names) if len(names) == dim else []
        why = "" if blocks else f"{len(names)} names for {dim} values; no complete '<side>_<udhm joint>' block"
    except ValueError as exc:
        blocks, why = [], str(exc)
    num_hands = len(blocks)
    sides = [b.side for b in blocks]
    udhm_names = udhm_state_names(sides)
    passthrough = [n for i, n in enumerate(names) if not any(b.start <= i < b.stop for b in blocks)]
    contiguous = bool(blocks) and all(b.start == len(passthrough) + k * UDHM_DIM for k, b in enumerate(blocks))
    rep.add(
        "state: passthrough columns then UDHM blocks",
        num_hands in (1, 2) and contiguous,
        f"{len(passthrough)} passthrough + {num_hands} block(s) {sides}"
        if num_hands in (1, 2) and contiguous
        else why or f"blocks {sides} must follow all passthrough columns, one or two hands",
    )
    for key, dtype in ((ACTION, "float32"), (UDHM_MASK_KEY, "bool")):
        ft = feats.get(key)
        if ft is None:
            rep.add(
                f"{key} feature",
                key == ACTION,
                "absent" if key == ACTION else "missing",
            )
            continue
        ft_names = feature_names(ft)
        if key == UDHM_MASK_KEY:
            ok = ft.get("dtype") == dtype and list(ft["shape"]) == [UDHM_DIM * num_hands] and ft_names == udhm_names
            rep.add(f"{key} feature", ok, f"{ft.get('dtype')} {ft['shape']}, names = the UDHM block names")
            continue
        try:
            a_blocks = find_udhm_blocks(ft_names)
        except ValueError as exc:
            rep.add(f"{key} feature", False, str(exc))
            continue
        if not a_blocks:  # an action copied unchanged (the hands have no commands)
            rep.add(f"{key} feature", True, "no UDHM block: copied from the source", warning=False)
            continue
        a_pass = len(ft_names) - UDHM_DIM * len(a_blocks)
        ok = (
            ft.get("dtype") == dtype
            and [b.side for b in a_blocks] == sides
            and all(b.start == a_pass + k * UDHM_DIM for k, b in enumerate(a_blocks))
        )
        rep.add(f"{key} feature", ok, f"{ft.get('dtype')} {ft['shape']}: {a_pass} passthrough + blocks {sides}")
    ht = feats.get(HAND_TYPE_KEY)
    rep.add(
        "hand_type feature",
        ht is not None and ht.get("dtype") == "string",
        str(ht and ht.get("dtype")),
    )
    return _StateBlocks(dim, sides)


def _read_rows(rep: ValidationReport, root: Path, feats: dict, num_hands: int) -> _Rows | None:
    """The data parquet columns the checks need, with each frame's UDHM blocks as (n, H, 22) arrays."""
    files = sorted(root.glob(DATA_GLOB))
    action_udhm = ACTION in feats and bool(find_udhm_blocks(feature_names(feats[ACTION])))
    cols = [OBS_STATE, UDHM_MASK_KEY, HAND_TYPE_KEY, "episode_index"] + ([ACTION] if action_udhm else [])
    try:
        table = pq.read_table(files, columns=cols) if files else None
    except Exception as exc:  # noqa: BLE001
        rep.add("data parquet readable", False, f"{type(exc).__name__}: {exc}")
        return None
    if not rep.add("data parquet readable", table is not None, f"{len(files)} file(s)"):
        return None
    n = table.num_rows

    def blocks(key, dtype):
        col = table.column(key).combine_chunks()
        flat = col.flatten().to_numpy(zero_copy_only=False).astype(dtype).reshape(n, -1)
        return flat[:, flat.shape[1] - UDHM_DIM * num_hands :].reshape(n, num_hands, UDHM_DIM)  # blocks come last

    action = blocks(ACTION, np.float32) if action_udhm else None
    return _Rows(table, blocks(OBS_STATE, np.float32), blocks(UDHM_MASK_KEY, bool), action)


def _check_finite_columns(rep: ValidationReport, root: Path, feats: dict) -> None:
    """Every numeric feature, passthrough columns (arms) and copied observations included, holds no NaN/inf: one
    would make `stats.json` NaN and every training loss NaN (lerobot-train then still exits 0)."""
    keys = [k for k, ft in feats.items() if str(ft.get("dtype", "")).startswith("float")]
    bad = []
    for path in sorted(root.glob(DATA_GLOB)):
        table = pq.read_table(path, columns=[*keys, "episode_index", "frame_index"])
        for key in keys:
            col = table.column(key).combine_chunks()
            values = (col.flatten() if hasattr(col, "flatten") else col).to_numpy(zero_copy_only=False)
            values = values.reshape(table.num_rows, -1)
            rows, cols = np.nonzero(~np.isfinite(values))
            if len(rows):
                names = feature_names(feats[key]) or [f"{key}[{i}]" for i in range(values.shape[1])]
                episodes = table.column("episode_index").to_numpy()[rows]
                frames = table.column("frame_index").to_numpy()[rows]
                where = ", ".join(f"episode {e} frame {f}" for e, f in list(zip(episodes, frames, strict=True))[:3])
                bad.append(f"{key} {sorted({names[c] for c in cols})[:4]} at {where} ({len(rows)} values)")
    rep.add("every numeric column finite", not bad, "; ".join(bad) or f"{len(keys)} features")


def _check_counts(rep: ValidationReport, info: dict, rows: _Rows, total_eps: int) -> None:
    """Frame count as info.json says; episodes numbered 0..N-1."""
    n = rows.num_rows
    rep.add(
        "total_frames",
        n == info.get("total_frames"),
        f"{n} rows, info says {info.get('total_frames')}",
    )
    eps = np.unique(rows.table.column("episode_index").to_numpy())
    rep.add(
        "episodes 0..N-1",
        len(eps) == total_eps and (len(eps) == 0 or (eps[0] == 0 and eps[-1] == total_eps - 1)),
        f"{len(eps)} episodes",
    )


def _check_values(rep: ValidationReport, rows: _Rows) -> None:
    """State (and action) blocks: finite, |angle| <= 2 pi, exactly zero where the mask is False."""
    for key, values in ((OBS_STATE, rows.state), (ACTION, rows.action)):
        if values is None:
            continue
        finite = np.isfinite(values).all()
        rep.add(
            f"{key} finite",
            finite,
            "" if finite else f"{int((~np.isfinite(values)).sum())} NaN/inf values",
        )
        peak = float(np.abs(np.nan_to_num(values)).max(initial=0.0))
        rep.add(
            f"{key} |angle| <= 2 pi",
            peak <= ANGLE_BOUND_RAD,
            f"max |angle| {peak:.3f} rad",
        )
        leak = int((values[~rows.mask] != 0).sum())
        rep.add(f"{key} zero where masked", leak == 0, f"{leak} non-zero masked values")


def _check_hand_types(rep: ValidationReport, rows: _Rows, sides: list[str], mapping: str) -> None:
    """hand_type: known specs, masks equal to the spec masks (or all False for an absent hand), values
    within each hand's UDHM limits (a warning: IK fits may exceed them slightly)."""
    from lerobot_unidextok import hands as hand_registry

    num_hands = len(sides)
    ht_col = rows.table.column(HAND_TYPE_KEY).combine_chunks().dictionary_encode()
    codes = ht_col.indices.to_numpy(zero_copy_only=False)
    bad_names, bad_masks, out_of_limits, checked = [], 0, 0, 0
    for code, value in enumerate(ht_col.dictionary.to_pylist()):
        parts = value.split(",")
        frames = codes == code
        if len(parts) != num_hands:
            bad_names.append(value)
            continue
        for b, name in enumerate(parts):
            try:
                spec = hand_registry.get(name)
            except (KeyError, ValueError):
                bad_names.append(name)
                continue
            m = rows.mask[frames, b]
            spec_mask = spec.mask(mapping)
            ok_rows = (m == spec_mask).all(axis=1) | ~m.any(axis=1)
            bad_masks += int((~ok_rows).sum())
            present = m.any(axis=1)
            if spec.kind == "keypoints":
                from lerobot_unidextok.udhm import JOINT_LIMITS_RAD

                lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
            else:
                lo, hi = spec.udhm_limits_rad(sides[b])
            vals = rows.state[frames, b][present]
            out_of_limits += int(((vals < lo - LIMIT_TOL_RAD) | (vals > hi + LIMIT_TOL_RAD)).sum())
            checked += vals.size
    rep.add(
        "hand_type names known",
        not bad_names,
        f"unknown/mis-sized: {sorted(set(bad_names))[:5]}" if bad_names else f"{ht_col.dictionary.to_pylist()[:4]}",
    )
    rep.add(
        "udhm_mask matches hand specs",
        bad_masks == 0,
        f"{bad_masks} inconsistent hand-frames (mapping={mapping})",
    )
    rep.add(
        "state within hand limits",
        out_of_limits == 0,
        f"{out_of_limits} of {checked} values beyond limits + {LIMIT_TOL_RAD} rad (IK fits may exceed slightly)",
        warning=True,
    )


def _check_splits(rep: ValidationReport, meta: UdhmDatasetMeta) -> None:
    """LeRobot's `splits` ranges in info.json, and the recorded test episodes (warned when missing)."""
    total_eps = meta.total_episodes
    splits = meta.info.get("splits", {})
    bad = []
    for name, value in (splits or {}).items():
        try:
            a, b = (int(x) for x in str(value).split(":"))
            if not 0 <= a <= b <= total_eps:
                bad.append(f"{name}={value} outside 0:{total_eps}")
        except ValueError:
            bad.append(f"{name}={value!r} is not 'a:b'")
    rep.add(
        "meta/info.json splits (LeRobot ranges)",
        bool(splits) and not bad,
        "; ".join(bad) if bad else (f"{splits}" if splits else "no splits"),
    )
    recorded, why = meta.recorded_split()
    rep.add(
        "recorded test episodes",
        recorded is not None,
        f"{len(recorded.test)} of {total_eps} ({recorded.origin})"
        if recorded is not None
        else f"{why}; train/eval fall back to --holdout=hash (a deterministic 20 % by episode hash)",
        warning=recorded is None,
    )


def _check_files(rep: ValidationReport, root: Path, num_rows: int, total_eps: int) -> None:
    """Dataset card (warned when missing), stats, tasks, and the episodes metadata lengths."""
    has_card = (root / "README.md").is_file()
    rep.add(
        "dataset card README.md",
        has_card,
        ""
        if has_card
        else "missing (lerobot-edit-dataset drops it): the source, license and settings are not documented",
        warning=not has_card,
    )
    for rel in ("meta/stats.json", "meta/tasks.parquet"):
        rep.add(rel, (root / rel).is_file(), "")
    ep_files = sorted(root.glob(EPISODES_META_GLOB))
    if ep_files:
        ep_tab = pq.read_table(ep_files, columns=["episode_index", "length"])
        rep.add(
            "meta/episodes lengths",
            int(pc.sum(ep_tab.column("length")).as_py() or 0) == num_rows and ep_tab.num_rows == total_eps,
            f"{ep_tab.num_rows} rows",
        )
    else:
        rep.add("meta/episodes lengths", False, "no meta/episodes parquet")


def _check_lerobot_load(rep: ValidationReport, root: Path, repo_id: str, dim: int) -> None:
    """`LeRobotDataset(repo_id, root=root)` opens the dataset and returns a frame of the state's width."""
    try:
        from lerobot.datasets import LeRobotDataset

        ds = LeRobotDataset(repo_id, root=root, video_backend="pyav")  # state-only: skip the video decoder probe
        item = ds[0]
        rep.add(
            "LeRobotDataset loads",
            tuple(item[OBS_STATE].shape) == (dim,),
            f"{ds.num_episodes} episodes, {ds.num_frames} frames",
        )
    except Exception as exc:  # noqa: BLE001
        rep.add("LeRobotDataset loads", False, f"{type(exc).__name__}: {exc}")
