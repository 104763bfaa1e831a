"""Plots for evaluation and the demo: 3D hand renderings via UDHM FK, per-joint errors, rate-distortion,
codebook usage. matplotlib object API only (no pyplot), so it runs headless. Each function returns its PNG path."""

from lerobot_unidextok.viz.hands3d import VIEWS, plot_hand_reconstructions
from lerobot_unidextok.viz.plots import codebook_usage, plot_codebook_usage, plot_per_joint_errors, plot_rate_distortion
from lerobot_unidextok.viz.style import GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR, method_colors

__all__ = [
    "GROUND_TRUTH_COLOR",
    "UNIDEXTOK_COLOR",
    "VIEWS",
    "codebook_usage",
    "method_colors",
    "plot_codebook_usage",
    "plot_hand_reconstructions",
    "plot_per_joint_errors",
    "plot_rate_distortion",
]
