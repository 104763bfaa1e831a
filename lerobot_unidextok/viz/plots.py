"""2D evaluation plots: per-joint errors, rate-distortion, codebook usage. Each writes a PNG, returns its path."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from lerobot_unidextok.constants import UDHM_JOINT_NAMES
from lerobot_unidextok.viz.style import method_colors, save

HAND_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")


# ---------------------------------------------------------------------------------------------
# per-joint errors
# ---------------------------------------------------------------------------------------------
def plot_per_joint_errors(
    errors_deg: Mapping[str, object],
    out_path: str | Path,
    *,
    title: str = "per-joint angle error",
    joint_names: Sequence[str] = UDHM_JOINT_NAMES,
) -> Path:
    """Grouped bars per UDHM joint, one bar per method. `errors_deg[m]` is `(22,)` mean errors or
    `(N, 22)` per-state absolute errors (bars = mean, whiskers = 95% CI); NaN marks inactive slots."""
    if not errors_deg:
        raise ValueError("errors_deg is empty; pass {method: (22,) or (N, 22) errors in degrees}")
    means, cis = {}, {}
    for m, e in errors_deg.items():
        arr = np.asarray(e, dtype=np.float64)
        if arr.shape[-1] != len(joint_names) or arr.ndim not in (1, 2):
            raise ValueError(
                f"errors_deg[{m!r}] must have shape ({len(joint_names)},) or (N, {len(joint_names)}); got {arr.shape}"
            )
        if arr.ndim == 2:
            finite = np.isfinite(arr)
            count = finite.sum(0)  # (22,) states per joint; 0 = inactive slot
            safe = np.where(finite, arr, 0.0)
            mean = safe.sum(0) / np.maximum(count, 1)
            std = np.sqrt((np.where(finite, arr - mean, 0.0) ** 2).sum(0) / np.maximum(count, 1))
            means[m] = np.where(count > 0, mean, np.nan)
            cis[m] = np.where(count > 0, 1.96 * std / np.sqrt(np.maximum(count, 1)), 0.0)
        else:
            means[m], cis[m] = arr, None
    colors = method_colors(list(means))
    num_joints, num_methods = len(joint_names), len(means)
    width = 0.8 / num_methods
    fig = Figure(figsize=(max(8.0, 0.45 * num_joints * max(1, num_methods / 2)), 4.2))
    ax = fig.add_subplot()
    x = np.arange(num_joints)
    for i, (m, mean) in enumerate(means.items()):
        ax.bar(x + (i - (num_methods - 1) / 2) * width, np.nan_to_num(mean), width, yerr=cis[m], color=colors[m],
               edgecolor="#333333", linewidth=0.4, label=f"{m} (mean {np.nanmean(mean):.2f}°)",
               error_kw={"elinewidth": 0.8, "capsize": 1.5})  # fmt: skip
    ax.set_xticks(x, joint_names, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("mean absolute error (deg)")
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)
    ax.legend(fontsize=8, frameon=False)
    return save(fig, out_path)


# ---------------------------------------------------------------------------------------------
# rate-distortion
# ---------------------------------------------------------------------------------------------
def plot_rate_distortion(
    rows: Sequence[Mapping[str, object]],
    out_path: str | Path,
    *,
    error: str = "mpjae_deg",
    error_label: str | None = None,
    title: str = "rate-distortion (held-out states)",
) -> Path:
    """Bits per state (x, log2) vs `error` (y), colour = method, marker = hand. `rows` are
    dicts with method, hand, bits_per_state and the error key."""
    flat = [dict(r) for r in rows]
    if not flat:
        raise ValueError("rows is empty; pass one row per (method, hand) with bits_per_state and the error")
    missing = [r.get("method") for r in flat if error not in r]
    if missing:
        raise ValueError(f"rows of {missing} lack the error {error!r}; available keys: {sorted(flat[0])}")
    methods = list(dict.fromkeys(r["method"] for r in flat))
    hands = list(dict.fromkeys(r["hand"] for r in flat))
    colors = method_colors(methods)
    fig = Figure(figsize=(6.4, 4.4))
    ax = fig.add_subplot()
    for r in flat:
        ax.scatter(r["bits_per_state"], r[error], color=colors[r["method"]], edgecolor="#222222", linewidth=0.5,
                   marker=HAND_MARKERS[hands.index(r["hand"]) % len(HAND_MARKERS)], s=60, zorder=3)  # fmt: skip
    ax.set_xscale("log", base=2)
    ax.set_xlabel("bits per hand state (log2)")
    ax.set_ylabel(error_label or error)
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.set_axisbelow(True)
    method_handles = [ax.scatter([], [], marker="o", color=colors[m], edgecolor="#222222", label=m) for m in methods]
    hand_handles = [ax.scatter([], [], marker=HAND_MARKERS[i % len(HAND_MARKERS)], color="#888888", label=h)
                    for i, h in enumerate(hands)]  # fmt: skip
    method_legend = ax.legend(handles=method_handles, title="method", fontsize=8, title_fontsize=8, frameon=False,
                              loc="upper left", bbox_to_anchor=(1.01, 1.0))  # fmt: skip
    ax.add_artist(method_legend)
    ax.legend(handles=hand_handles, title="hand", fontsize=8, title_fontsize=8, frameon=False,
              loc="lower left", bbox_to_anchor=(1.01, 0.0))  # fmt: skip
    return save(fig, out_path)


# ---------------------------------------------------------------------------------------------
# codebook usage
# ---------------------------------------------------------------------------------------------
def codebook_usage(codes: object, vocab_size: int) -> dict[str, np.ndarray]:
    """Per group (last code axis): counts `(G, V)`, used fraction `(G,)` and perplexity `(G,)`."""
    arr = np.asarray(codes)
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"codes must be integers (token indices); got dtype {arr.dtype}")
    if arr.size == 0:
        raise ValueError("codes is empty; encode at least one state")
    if arr.min() < 0 or arr.max() >= vocab_size:
        raise ValueError(f"codes must lie in [0, {vocab_size}); got [{arr.min()}, {arr.max()}]. Is vocab_size right?")
    groups = arr.reshape(-1, arr.shape[-1]) if arr.ndim > 1 else arr[:, None]  # (M, G)
    counts = np.stack([np.bincount(groups[:, g], minlength=vocab_size) for g in range(groups.shape[1])])  # (G, V)
    probs = counts / counts.sum(1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        entropy = -np.nansum(np.where(probs > 0, probs * np.log(probs), 0.0), axis=1)
    return {"counts": counts, "used_fraction": (counts > 0).mean(1), "perplexity": np.exp(entropy)}


def plot_codebook_usage(
    codes: object,
    vocab_size: int,
    out_path: str | Path,
    *,
    title: str = "codebook usage",
    max_panels: int = 8,
) -> Path:
    """Histogram of code usage per group (last axis of `codes`, e.g. UniDexTok's K=8 groups): bars per
    code for small vocabularies, a rank-frequency curve for large ones. Titles give used % and perplexity."""
    stats = codebook_usage(codes, vocab_size)
    counts = stats["counts"][:max_panels]
    num = counts.shape[0]
    cols = min(num, 4)
    rows = int(np.ceil(num / cols))
    fig = Figure(figsize=(max(3.2 * cols, 5.5), 2.4 * rows + 0.9))
    for g in range(num):
        ax = fig.add_subplot(rows, cols, g + 1)
        freq = counts[g] / counts[g].sum() * 100.0
        if vocab_size <= 64:
            ax.bar(np.arange(vocab_size), freq, width=0.85, color="#2ecc40" if freq.any() else "#888888")
            ax.set_xlabel("code", fontsize=7)
        else:
            ax.fill_between(np.arange(vocab_size), np.sort(freq)[::-1], step="mid", color="#0074d9", alpha=0.7)
            ax.set_xlabel("code rank", fontsize=7)
        ax.axhline(100.0 / vocab_size, color="#ff4136", linewidth=0.8, linestyle="--")  # uniform usage
        ax.set_title(f"group {g}: used {stats['used_fraction'][g]:.0%}, ppl {stats['perplexity'][g]:.1f}/{vocab_size}",
                     fontsize=8)  # fmt: skip
        ax.tick_params(labelsize=7)
        if g % cols == 0:
            ax.set_ylabel("% of states", fontsize=7)
    fig.suptitle(f"{title}  (dashed = uniform)", fontsize=10)
    fig.tight_layout()
    return save(fig, out_path)
