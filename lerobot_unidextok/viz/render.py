"""Frames of the episode viewer: per hand its skeleton seen from a camera, its native values and its tokens.

The figure is laid out and drawn once; every frame then moves the artists that change (bones, joints,
bars, token codes, frame number) and blits them onto the saved background, so a frame costs a few
draw calls instead of a new figure with 3D axes.

    renderer = EpisodeRenderer(view, camera="oblique")
    image = renderer.render(t)                        # (height, width, 3) uint8, even size

Camera: an orthographic view of the hand's wrist frame (`udhm/frames.py`: x palmar, y thumb side of a
right hand, z distal) from (elevation, azimuth) in degrees, matplotlib's convention (azimuth 0 looks
along -x at the palm, y to the image's right). A left hand is the mirror image of a right hand, so it is
seen by the mirrored camera (azimuth negated): its picture is the mirror image of the right hand's, the
thumb on the other side. Every hand is framed to its extent over the whole episode at one scale (mm per
pixel) for all hands and frames, so motion and sizes show, with the wrists level. Bones farther from the camera are drawn
darker; the palm (wrist and the five finger bases, fixed in the wrist frame) is a faint static polygon.
matplotlib object API only (no pyplot): headless.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
from PIL import Image

from lerobot_unidextok import hands as hand_registry
from lerobot_unidextok.constants import KEYPOINT_PARENTS, UDHM_JOINT_NAMES
from lerobot_unidextok.viz.style import DARK_BG, GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR, VIEWS

BONES = np.array([(parent, child) for child, parent in enumerate(KEYPOINT_PARENTS) if parent >= 0])  # (20, 2)
PALM = (0, 1, 5, 9, 13, 17)  # wrist, thumb CMC, index/middle/ring/pinky MCP
LAYERS = ((GROUND_TRUTH_COLOR, 2.6), (UNIDEXTOK_COLOR, 1.6))  # dataset, decoded: colour, line width (pt)

# layout, inches
_COLUMN_IN = 4.2  # one hand's column
_GAP_IN = 0.25  # between columns and at the figure's sides
_HEADER_IN = 0.45  # figure title
_TITLE_IN = 0.3  # a panel's title
_JOINT_IN = 0.19  # one bar
_TOKEN_ROW_IN = 0.24  # one row of the token grid
_BAR_AXIS_IN = 0.3  # bar axis tick labels
_MARGIN = 0.06  # free border around a hand, fraction of its extent
_LABEL_PT = 7
_FAR_DIM = 0.55  # the farthest bone is blended this far toward the background
_RANGE_COLOR = "#3d3d3d"  # a joint's range behind its bar


def camera_axes(camera: str, side: str) -> np.ndarray:
    """(3, 3) rows: the image's right and up directions and the direction toward the viewer, in the wrist
    frame of a `side` hand; the left camera is the right one mirrored in y."""
    if camera not in VIEWS:
        raise ValueError(f"unknown camera view {camera!r}; choose from {sorted(VIEWS)}")
    elev, azim = np.deg2rad(VIEWS[camera])
    if side == "left":
        azim = -azim
    ce, se, ca, sa = np.cos(elev), np.sin(elev), np.cos(azim), np.sin(azim)
    return np.array([[-sa, ca, 0.0], [-se * ca, -se * sa, ce], [ce * ca, ce * sa, se]])


def project(keypoints_m: np.ndarray, camera: str, side: str) -> np.ndarray:
    """(..., 21, 3) m -> (..., 21, 3) mm: image right, image up, toward the viewer (depth)."""
    return np.asarray(keypoints_m) @ camera_axes(camera, side).T * 1000.0


@dataclass
class HandArtists:
    """What moves in one hand's column."""

    bones: list[LineCollection]  # per layer (dataset, then decoded)
    joints: list  # per layer, PathCollection of the 21 keypoints
    bars: list  # Rectangles, one per native joint (UDHM joint for a hand given as keypoints)
    bar_base: float  # where the bars start (0 clipped into the panel's range)
    decoded_ticks: object | None  # Line2D markers at the decoded values
    token_image: object | None
    token_texts: list | None  # N * K Text, row-major


class EpisodeRenderer:
    """One figure for an `EpisodeView`, drawn once; `render(t)` updates and blits frame `t`."""

    def __init__(self, view, camera: str = "oblique", dpi: int = 100):
        self.view, self.camera, self.dpi = view, camera, dpi
        layers = [view.keypoints_m] + ([view.decoded_keypoints_m] if view.decoded_keypoints_m is not None else [])
        self.points_mm = np.stack([  # (L, T, H, 21, 3) right, up, depth in mm
            np.stack([project(kp[:, k], camera, side) for k, side in enumerate(view.sides)], axis=1) for kp in layers
        ])  # fmt: skip
        depth = self.points_mm[..., 2]
        self._depth_range = depth.min(axis=(0, 1, 3)), depth.max(axis=(0, 1, 3))  # (H,) each, over the episode
        self.values = [self._bar_values(k) for k in range(len(view.hands))]
        self.figure = Figure(facecolor=DARK_BG, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.figure)
        self.hand_axes: list = []
        self.bar_axes: list = []
        self.artists: list[HandArtists] = []
        self._layout()
        self.canvas.draw()  # the static part; animated artists are left out of it
        self._background = self.canvas.copy_from_bbox(self.figure.bbox)

    # -- data -----------------------------------------------------------------------------------------
    def _bar_values(self, k: int):
        """(names, (T, J) values, (T, J) decoded or None, (J, 2) ranges) of hand k's bar panel."""
        view = self.view
        if view.native[k] is not None:
            decoded = view.decoded_native[k] if view.decoded_native else None
            ranges = hand_registry.get(view.hands[k]).raw_range(view.sides[k])  # (J, 2)
            return list(view.native_names[k]), view.native[k], decoded, ranges
        from lerobot_unidextok.udhm import JOINT_LIMITS_RAD

        deg = np.rad2deg(view.states_rad[:, k])  # (T, 22) a hand given as keypoints: its UDHM angles
        decoded = np.rad2deg(view.decoded_rad[:, k]) if view.decoded_rad is not None else None
        return list(UDHM_JOINT_NAMES), deg, decoded, np.rad2deg(JOINT_LIMITS_RAD)

    def _extents(self) -> tuple[np.ndarray, np.ndarray]:
        """(H, 2) centres and half sizes (mm) of every hand's image over the episode, both layers; the
        vertical extent is the union over hands, so every wrist (the origin) sits at the same height."""
        pts = self.points_mm[..., :2].transpose(2, 0, 1, 3, 4).reshape(len(self.view.hands), -1, 2)  # (H, P, 2)
        lo, hi = pts.min(1), pts.max(1)
        lo[:, 1], hi[:, 1] = lo[:, 1].min(), hi[:, 1].max()
        return (lo + hi) / 2, (hi - lo) / 2 * (1 + 2 * _MARGIN) + 1.0  # +1 mm: never a zero span

    # -- layout ---------------------------------------------------------------------------------------
    def _label_width_in(self) -> float:
        """Width (inches) of the longest bar label at the label font size."""
        probe = self.figure.text(0, 0, "", fontsize=_LABEL_PT)
        renderer = self.canvas.get_renderer()
        widest = 0.0
        for names, *_ in self.values:
            for name in names:
                probe.set_text(name)
                widest = max(widest, probe.get_window_extent(renderer).width / self.dpi)
        probe.remove()
        return widest

    def _layout(self) -> None:
        view, fig = self.view, self.figure
        num_hands = len(view.hands)
        centres, halves = self._extents()
        aspect = float(np.clip(np.max(halves[:, 1] / halves[:, 0]), 0.8, 1.5))  # hand panel height / width
        half_w = float(np.max(np.maximum(halves[:, 0], halves[:, 1] / aspect)))  # one scale for every hand
        hand_in = _COLUMN_IN * aspect
        bars_in = _TITLE_IN + _JOINT_IN * max(len(v[0]) for v in self.values) + _BAR_AXIS_IN
        tokens_in = 0.0 if view.tokens is None else _TITLE_IN + _TOKEN_ROW_IN * view.tokens.shape[2] + 0.1
        width_in = num_hands * _COLUMN_IN + (num_hands + 1) * _GAP_IN
        height_in = _HEADER_IN + _TITLE_IN + hand_in + bars_in + tokens_in + 0.15
        fig.set_size_inches(width_in, height_in)
        label_in = self._label_width_in() + 0.1

        def box(left_in, top_in, w_in, h_in):  # inches from the figure's top-left -> figure fraction
            return [left_in / width_in, 1 - (top_in + h_in) / height_in, w_in / width_in, h_in / height_in]

        legend = "grey: dataset" + ("   green: decoded from tokens" if view.tokens is not None else "")
        fig.text(_GAP_IN / width_in, 1 - 0.3 / height_in, f"{view.dataset}  episode {view.episode}    {legend}",
                 color="white", fontsize=9)  # fmt: skip
        self.frame_text = fig.text(1 - _GAP_IN / width_in, 1 - 0.3 / height_in, "", color="white", fontsize=9,
                                   ha="right", animated=True)  # fmt: skip
        for k, (hand, side) in enumerate(zip(view.hands, view.sides, strict=True)):
            left, top = _GAP_IN + k * (_COLUMN_IN + _GAP_IN), _HEADER_IN + _TITLE_IN
            ax = fig.add_axes(box(left, top, _COLUMN_IN, hand_in), facecolor=DARK_BG)
            (cx, cy), half_h = centres[k], half_w * aspect
            ax.set(xlim=(cx - half_w, cx + half_w), ylim=(cy - half_h, cy + half_h))
            ax.set_axis_off()
            drawn = f"  ({view.pose_source[k]})" if view.pose_source and view.pose_source[k] else ""
            ax.set_title(f"{side} {hand}{drawn}", color="white", fontsize=9)
            palm = self.points_mm[0, 0, k, PALM, :2]  # fixed in the wrist frame
            ax.add_patch(Polygon(palm, closed=True, facecolor=GROUND_TRUTH_COLOR, alpha=0.12, edgecolor="none"))
            bones, joints = [], []
            for color, width in LAYERS[: len(self.points_mm)]:
                bones.append(ax.add_collection(LineCollection([], colors=color, linewidths=width, capstyle="round",
                                                              animated=True)))  # fmt: skip
                joints.append(ax.scatter([], [], s=(width + 0.8) ** 2, color=color, linewidths=0, animated=True))
            self.hand_axes.append(ax)
            top += hand_in + _TITLE_IN
            bar_ax = fig.add_axes(box(left + label_in, top, _COLUMN_IN - label_in - 0.1,
                                      bars_in - _TITLE_IN - _BAR_AXIS_IN))  # fmt: skip
            self.bar_axes.append(bar_ax)
            bars, base, ticks = self._bar_panel(bar_ax, k)
            image = texts = None
            if view.tokens is not None:
                top += bars_in
                image, texts = self._token_panel(fig.add_axes(box(left, top, _COLUMN_IN, tokens_in - _TITLE_IN - 0.1)))
            self.artists.append(HandArtists(bones, joints, bars, base, ticks, image, texts))

    def _bar_panel(self, ax, k: int):
        names, values, decoded, ranges = self.values[k]
        num = len(names)
        ax.set_facecolor(DARK_BG)
        ax.tick_params(colors="white", labelsize=_LABEL_PT, length=2)
        for spine in ax.spines.values():
            spine.set_color("#777777")
        lo, hi = float(ranges[:, 0].min()), float(ranges[:, 1].max())
        ax.set(xlim=(lo, hi), ylim=(num - 0.5, -0.5))  # first joint on top
        y = np.arange(num)
        ax.barh(y, ranges[:, 1] - ranges[:, 0], left=ranges[:, 0], height=0.7, color=_RANGE_COLOR)
        base = float(np.clip(0.0, lo, hi))
        bars = list(ax.barh(y, np.zeros(num), left=base, height=0.7, color=GROUND_TRUTH_COLOR))
        for bar in bars:
            bar.set_animated(True)
        ax.set_yticks(y, names)
        ticks = None
        if decoded is not None:
            ticks = ax.plot([], [], "|", color=UNIDEXTOK_COLOR, markersize=9, markeredgewidth=2, animated=True)[0]
        ax.set_title("native values" if self.view.native[k] is not None else "UDHM angles (deg)", color="white",
                     fontsize=8)  # fmt: skip
        return bars, base, ticks

    def _token_panel(self, ax):
        tokens = self.view.tokens  # (T, H, N, K)
        num_tokens, groups = tokens.shape[2:]
        ax.set_axis_off()
        image = ax.imshow(np.zeros((num_tokens, groups)), cmap="viridis", vmin=0, vmax=max(1, int(tokens.max())),
                          aspect="auto", animated=True)  # fmt: skip
        texts = [ax.text(c, r, "", ha="center", va="center", color="white", fontsize=6, animated=True)
                 for r in range(num_tokens) for c in range(groups)]  # fmt: skip
        ax.set_title(f"tokens ({num_tokens} x {groups})", color="white", fontsize=8)
        return image, texts

    # -- frames ---------------------------------------------------------------------------------------
    def _shade(self, color: str, depth_mm: np.ndarray, k: int) -> np.ndarray:
        """(N, 4) RGBA: `color` blended toward the background by how far each depth is from the viewer."""
        near, far = self._depth_range[1][k], self._depth_range[0][k]
        f = np.clip((near - depth_mm) / max(near - far, 1e-6), 0.0, 1.0)[:, None] * _FAR_DIM  # (N, 1)
        return np.array(to_rgba(color)) * (1 - f) + np.array(to_rgba(DARK_BG)) * f

    def update(self, t: int) -> list:
        """Move every artist to frame `t`; returns the ones to draw."""
        view = self.view
        moved = [self.frame_text]
        self.frame_text.set_text(f"frame {int(view.frame_index[t])}")
        for k, art in enumerate(self.artists):
            for layer, (bones, joints) in enumerate(zip(art.bones, art.joints, strict=True)):
                pts = self.points_mm[layer, t, k]  # (21, 3)
                order = np.argsort(pts[BONES, 2].mean(1))  # far bones first, near ones on top
                bones.set_segments(pts[BONES[order], :2])
                bones.set_color(self._shade(LAYERS[layer][0], pts[BONES[order], 2].mean(1), k))
                joints.set_offsets(pts[:, :2])
                joints.set_facecolor(self._shade(LAYERS[layer][0], pts[:, 2], k))
                moved += [bones, joints]
            names, values, decoded, _ = self.values[k]
            for bar, v in zip(art.bars, values[t], strict=True):
                bar.set_width(float(v) - art.bar_base)
            moved += art.bars
            if art.decoded_ticks is not None:
                art.decoded_ticks.set_data(decoded[t], np.arange(len(names)))
                moved.append(art.decoded_ticks)
            if art.token_image is not None:
                codes = view.tokens[t, k]  # (N, K)
                art.token_image.set_data(codes)
                for text, code in zip(art.token_texts, codes.reshape(-1), strict=True):
                    text.set_text(str(int(code)))
                moved += [art.token_image, *art.token_texts]
        return moved

    def drawn_points_mm(self, k: int, layer: int = 0) -> np.ndarray:
        """(21, 2) the image-plane keypoints hand `k`'s joint markers are drawn at (after `render`)."""
        return np.asarray(self.artists[k].joints[layer].get_offsets())

    def render(self, t: int) -> np.ndarray:
        """(height, width, 3) uint8 image of frame `t` (even height and width, for yuv420p video)."""
        moved = self.update(t)
        self.canvas.restore_region(self._background)
        for artist in moved:
            self.figure.draw_artist(artist)
        width, height = self.canvas.get_width_height()
        rgba = Image.frombuffer("RGBA", (width, height), self.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
        return np.asarray(rgba.crop((0, 0, width // 2 * 2, height // 2 * 2)).convert("RGB"))  # Pillow: 3x numpy's


def render_frame(view, t: int, camera: str = "oblique", dpi: int = 100) -> np.ndarray:
    """(height, width, 3) uint8 image of frame `t` of `view` (one frame; use `EpisodeRenderer` for many)."""
    return EpisodeRenderer(view, camera, dpi).render(t)
