"""Plots for evaluation and the demo: 3D hand renderings via UDHM FK, per-joint errors, rate-distortion,
codebook usage, and the episode viewer (`unidextok-view`: mp4 / gif / rerun recording). matplotlib object
API only (no pyplot), so it runs headless. Each plot function returns its PNG path."""

from lerobot_unidextok.viz.episode import EpisodeView, load_episode, view_states, write_rerun, write_video
from lerobot_unidextok.viz.hands3d import plot_hand_reconstructions
from lerobot_unidextok.viz.plots import codebook_usage, plot_codebook_usage, plot_per_joint_errors, plot_rate_distortion
from lerobot_unidextok.viz.render import EpisodeRenderer, render_frame
from lerobot_unidextok.viz.style import GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR, VIEWS, method_colors

__all__ = [
    "EpisodeRenderer",
    "EpisodeView",
    "GROUND_TRUTH_COLOR",
    "UNIDEXTOK_COLOR",
    "VIEWS",
    "codebook_usage",
    "load_episode",
    "method_colors",
    "plot_codebook_usage",
    "plot_hand_reconstructions",
    "plot_per_joint_errors",
    "plot_rate_distortion",
    "render_frame",
    "view_states",
    "write_rerun",
    "write_video",
]
