"""3D renderings of ground-truth vs reconstructed hand states through UDHM forward kinematics."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3d projection)

from lerobot_unidextok import hands, udhm
from lerobot_unidextok.constants import KEYPOINT_PARENTS, UDHM_DIM
from lerobot_unidextok.viz.style import DARK_BG, GROUND_TRUTH_COLOR, VIEWS, method_colors, save

BONES = [(child, parent) for child, parent in enumerate(KEYPOINT_PARENTS) if parent >= 0]


def _as_states(name: str, states: object, num: int | None) -> np.ndarray:
    arr = np.asarray(states, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != UDHM_DIM or (num is not None and arr.shape[0] != num):
        want = f"({num}, {UDHM_DIM})" if num is not None else f"(S, {UDHM_DIM})"
        raise ValueError(f"{name} must have shape {want} radians (one row per sampled state); got {arr.shape}")
    return arr


def _draw_hand(ax, keypoints_m: np.ndarray, color: str, width: float, alpha: float) -> None:
    kp = keypoints_m * 1000.0  # mm
    for child, parent in BONES:
        seg = kp[[parent, child]]
        ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color=color, linewidth=width, alpha=alpha, solid_capstyle="round")
    ax.scatter(kp[:, 0], kp[:, 1], kp[:, 2], color=color, s=6 * width, alpha=alpha, depthshade=False)


def plot_hand_reconstructions(
    gt_rad: object,
    recon_rad: Mapping[str, object],
    hand: str,
    out_path: str | Path,
    *,
    views: Sequence[str] = ("side", "oblique"),
    side: str = "right",
    skeleton: udhm.Skeleton | None = None,
    title: str | None = None,
) -> Path:
    """Draw `S` sampled states (columns) x `views` (rows): ground truth light grey, UniDexTok green,
    baselines red. gt_rad `(S, 22)`; recon_rad `{method: (S, 22)}`. Writes a PNG and returns its path."""
    gt = _as_states("gt_rad", gt_rad, None)
    recons = {m: _as_states(f"recon_rad[{m!r}]", r, gt.shape[0]) for m, r in recon_rad.items()}
    unknown = [v for v in views if v not in VIEWS]
    if unknown or not views:
        raise ValueError(f"unknown views {unknown}; choose from {sorted(VIEWS)}")
    skel = skeleton if skeleton is not None else hands.get(hand).skeleton()
    kp_gt = udhm.forward_kinematics(gt, skel, side=side)  # (S, 21, 3) m
    kp_rec = {m: udhm.forward_kinematics(r, skel, side=side) for m, r in recons.items()}
    colors = method_colors(list(recons))
    draw_order = sorted(kp_rec, key=lambda m: "unidextok" in m.lower())  # UniDexTok drawn last, on top
    stacked = np.stack([kp_gt, *kp_rec.values()]) * 1000.0  # (1 + M, S, 21, 3) mm
    centres = 0.5 * (stacked.min(axis=(0, 2)) + stacked.max(axis=(0, 2)))  # (S, 3) per sample
    half = float(np.abs(stacked - centres[None, :, None, :]).max()) * 1.02  # one scale for every panel

    num = gt.shape[0]
    fig = Figure(figsize=(2.6 * num + 0.4, 2.7 * len(views) + 0.9), facecolor=DARK_BG)
    for row, view in enumerate(views):
        for col in range(num):
            ax = fig.add_subplot(len(views), num, row * num + col + 1, projection="3d")
            ax.set_facecolor(DARK_BG)
            _draw_hand(ax, kp_gt[col], GROUND_TRUTH_COLOR, width=3.0, alpha=0.95)
            for m in draw_order:
                _draw_hand(ax, kp_rec[m][col], colors[m], width=1.8, alpha=0.9)
            c = centres[col]
            ax.set_xlim(c[0] - half, c[0] + half)
            ax.set_ylim(c[1] - half, c[1] + half)
            ax.set_zlim(c[2] - half, c[2] + half)
            ax.set_box_aspect((1, 1, 1), zoom=1.35)
            ax.view_init(elev=VIEWS[view][0], azim=-VIEWS[view][1] if side == "left" else VIEWS[view][1])  # mirrored
            ax.set_axis_off()
            if row == 0:
                errs = "\n".join(  # one line per method: several methods' names do not fit one panel's width
                    f"{m}: {np.linalg.norm(kp[col] - kp_gt[col], axis=-1).mean() * 1000:.1f}"
                    for m, kp in kp_rec.items()
                )
                ax.set_title(f"#{col}  MPJPE mm\n{errs}", color="white", fontsize=7)
            if col == 0:
                ax.text2D(0.0, 0.5, view, transform=ax.transAxes, color="white", fontsize=9, rotation=90, va="center")
    handles = [Line2D([], [], color=GROUND_TRUTH_COLOR, linewidth=3, label="ground truth")]
    handles += [Line2D([], [], color=colors[m], linewidth=2, label=m) for m in recons]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), frameon=False, labelcolor="white", fontsize=9)
    fig.suptitle(title or f"{hand} ({side}): ground truth vs reconstructions", color="white", fontsize=11)
    fig.subplots_adjust(left=0.02, right=0.98, top=0.86, bottom=0.08, wspace=0.0, hspace=0.05)
    return save(fig, out_path)
