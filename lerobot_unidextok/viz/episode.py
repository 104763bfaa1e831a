"""Look at one episode of a converted dataset: each UDHM hand in 3D (forward kinematics), its native values
and, with a tokenizer, the tokens and the hand decoded from them; as an mp4 / gif, or a rerun recording.

    view = load_episode("data/g1_udhm", episode=0, tokenizer="lab/unidextok-small")
    write_video(view, "outputs/view/g1_ep0.mp4")      # or .gif
    write_rerun(view, "outputs/view/g1_ep0.rrd")      # needs rerun-sdk (pip install 'lerobot[viz]')

Frames are drawn with matplotlib's object API (headless); mp4 is encoded with PyAV (LeRobot's video
dependency, its wheels bundle the codecs), gif with Pillow. No FFmpeg binary is needed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3d projection)

from lerobot_unidextok import hands as hand_registry
from lerobot_unidextok import udhm
from lerobot_unidextok.constants import INFO_PATH, OBS_STATE, UDHM_DIM
from lerobot_unidextok.utils.imports import require_package
from lerobot_unidextok.viz.hands3d import BONES, VIEWS
from lerobot_unidextok.viz.style import DARK_BG, GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR

VIDEO_SUFFIXES = (".mp4", ".gif")


@dataclass
class EpisodeView:
    """Everything drawn for one episode, frame-major (T frames, H hands)."""

    dataset: str
    episode: int
    fps: float
    hands: list[str]
    sides: list[str]
    states_rad: np.ndarray  # (T, H, 22) UDHM radians from the dataset
    native: list[np.ndarray | None]  # per hand (T, J) native values (None: no native joints, e.g. human)
    native_names: list[list[str]]  # per hand, the native joint names
    frame_index: np.ndarray  # (T,) frame index within the episode
    tokens: np.ndarray | None = None  # (T, H, N, K) codes when a tokenizer was given
    decoded_rad: np.ndarray | None = None  # (T, H, 22) decoded UDHM state (inactive slots zero)
    decoded_native: list[np.ndarray | None] = field(default_factory=list)  # per hand (T, J) from decoded_rad
    keypoints_m: np.ndarray | None = field(default=None, repr=False)  # (T, H, 21, 3) FK of states_rad
    decoded_keypoints_m: np.ndarray | None = field(default=None, repr=False)  # (T, H, 21, 3)

    @property
    def num_frames(self) -> int:
        return int(self.states_rad.shape[0])


# ---------------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------------
def _episode_states(root: Path, episode: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, D) observation.state and (T,) frame_index of one episode, read with pyarrow."""
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    rows, frames = [], []
    for f in sorted((root / "data").rglob("*.parquet")):
        table = pq.read_table(f, columns=[OBS_STATE, "episode_index", "frame_index"])
        table = table.filter(pc.equal(table["episode_index"], episode))
        if table.num_rows:
            rows.append(np.stack(table[OBS_STATE].to_numpy(zero_copy_only=False)).astype(np.float64))
            frames.append(table["frame_index"].to_numpy())
    if not rows:
        raise ValueError(f"episode {episode} is not in {root}; see meta/info.json total_episodes")
    order = np.argsort(np.concatenate(frames), kind="stable")
    return np.concatenate(rows)[order], np.concatenate(frames)[order]


def load_episode(
    dataset: str | Path,
    episode: int = 0,
    tokenizer: str | None = None,
    stride: int = 1,
    max_frames: int | None = None,
) -> EpisodeView:
    """Read episode `episode` of a converted dataset (folder or repo id on this machine); with `tokenizer`
    (folder or repo id) also its tokens and the decoded hands. Every `stride`-th frame, at most `max_frames`."""
    import json

    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep, hand_layout_from_dataset
    from lerobot_unidextok.utils.hf_cache import dataset_root

    root = Path(dataset)
    if not (root / INFO_PATH).is_file():
        if root.exists() or str(dataset).count("/") != 1:
            raise FileNotFoundError(f"{dataset} is not a LeRobotDataset folder (meta/info.json missing) nor a repo id")
        root = dataset_root(str(dataset))
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    info = json.loads((root / INFO_PATH).read_text())
    layout = hand_layout_from_dataset(root)
    states, frame_index = _episode_states(root, episode)
    take = np.arange(0, len(states), stride)[:max_frames]
    states, frame_index = states[take], frame_index[take]
    blocks = states[:, layout.block_columns].reshape(len(states), layout.num_hands, UDHM_DIM)  # (T, H, 22)

    specs = [hand_registry.get(h) for h in layout.hands]
    native = [s.from_udhm(blocks[:, k], side) if s.kind == "joints" else None
              for k, (s, side) in enumerate(zip(specs, layout.sides, strict=True))]  # fmt: skip
    view = EpisodeView(
        dataset=str(dataset), episode=episode, fps=float(info["fps"]) / stride, hands=layout.hands,
        sides=layout.sides, states_rad=blocks, native=native,
        native_names=[list(s.joint_names) if s.kind == "joints" else [] for s in specs], frame_index=frame_index,
    )  # fmt: skip
    if tokenizer is not None:
        import torch

        step = UniDexTokStateTokenizerStep(hand_layout=layout.hands, state_names=layout.state_names,
                                           pretrained=str(tokenizer), allow_unknown=True, range_check="warn")  # fmt: skip
        tokens, decoded = step.tokenize(torch.as_tensor(states, dtype=torch.float32))  # (T, H*N*K), (T, H*22)
        cfg = step.tokenizer.config
        view.tokens = tokens.numpy().reshape(len(states), layout.num_hands, cfg.num_tokens, cfg.num_groups)
        view.decoded_rad = decoded.numpy().astype(np.float64).reshape(len(states), layout.num_hands, UDHM_DIM)
        view.decoded_native = [
            s.from_udhm(view.decoded_rad[:, k], side) if s.kind == "joints" else None
            for k, (s, side) in enumerate(zip(specs, layout.sides, strict=True))
        ]
    view.keypoints_m = _fk(view.states_rad, specs, layout.sides)
    if view.decoded_rad is not None:
        view.decoded_keypoints_m = _fk(view.decoded_rad, specs, layout.sides)
    return view


def _fk(states_rad: np.ndarray, specs, sides: list[str]) -> np.ndarray:
    """(T, H, 22) -> (T, H, 21, 3) keypoints in metres, each hand with its own skeleton and side."""
    return np.stack(
        [udhm.forward_kinematics(states_rad[:, k], s.skeleton(), side=side) for k, (s, side) in
         enumerate(zip(specs, sides, strict=True))], axis=1)  # fmt: skip


# ---------------------------------------------------------------------------------------------
# drawing
# ---------------------------------------------------------------------------------------------
def _draw_skeleton(ax, kp_mm: np.ndarray, color: str, width: float) -> None:
    for child, parent in BONES:
        seg = kp_mm[[parent, child]]
        ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color=color, linewidth=width, solid_capstyle="round")
    ax.scatter(kp_mm[:, 0], kp_mm[:, 1], kp_mm[:, 2], color=color, s=4 * width, depthshade=False)


def render_frame(view: EpisodeView, t: int, camera: str = "oblique", dpi: int = 80) -> np.ndarray:
    """(height, width, 3) uint8 image of frame `t`: per hand a 3D view (dataset grey, decoded green), its
    native values (bars: dataset, ticks: decoded) and its token grid."""
    h = len(view.hands)
    fig = Figure(figsize=(4.2 * h, 7.0), facecolor=DARK_BG, dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    rows = fig.add_gridspec(3, h, height_ratios=[3.2, 1.0, 1.0], hspace=0.55, wspace=0.15)
    kp_all = view.keypoints_m * 1000.0  # (T, H, 21, 3) mm
    centre = 0.5 * (kp_all.min(axis=(0, 2)) + kp_all.max(axis=(0, 2)))  # (H, 3) fixed per hand
    half = float(np.abs(kp_all - centre[None, :, None]).max()) * 1.05
    for k, (hand, side) in enumerate(zip(view.hands, view.sides, strict=True)):
        ax = fig.add_subplot(rows[0, k], projection="3d")
        ax.set_facecolor(DARK_BG)
        _draw_skeleton(ax, kp_all[t, k], GROUND_TRUTH_COLOR, 2.6)
        if view.decoded_keypoints_m is not None:
            _draw_skeleton(ax, view.decoded_keypoints_m[t, k] * 1000.0, UNIDEXTOK_COLOR, 1.6)
        for axis, c in zip("xyz", centre[k], strict=True):
            getattr(ax, f"set_{axis}lim")(c - half, c + half)
        ax.set_box_aspect((1, 1, 1), zoom=1.5)
        ax.view_init(elev=VIEWS[camera][0], azim=VIEWS[camera][1])
        ax.set_axis_off()
        ax.set_title(f"{side} {hand}", color="white", fontsize=9)
        panel = fig.add_subplot(rows[1, k])
        panel.set_facecolor(DARK_BG)
        panel.tick_params(colors="white", labelsize=6)
        if view.native[k] is not None:
            values, names = view.native[k][t], view.native_names[k]
            panel.bar(range(len(values)), values, color=GROUND_TRUTH_COLOR)
            if view.decoded_native and view.decoded_native[k] is not None:
                panel.scatter(range(len(values)), view.decoded_native[k][t], color=UNIDEXTOK_COLOR, marker="_", s=120)
            lo, hi = hand_registry.get(hand).raw_range(side).T
            panel.set_ylim(float(lo.min()), float(hi.max()))
            panel.set_xticks(range(len(values)), [n[:8] for n in names], rotation=60)
            panel.set_title("native values", color="white", fontsize=8)
        else:
            deg = np.rad2deg(view.states_rad[t, k])
            panel.bar(range(UDHM_DIM), deg, color=GROUND_TRUTH_COLOR)
            panel.set_title("UDHM angles (deg)", color="white", fontsize=8)
        grid = fig.add_subplot(rows[2, k])
        grid.set_axis_off()
        if view.tokens is not None:
            codes = view.tokens[t, k]  # (N, K)
            grid.imshow(codes, cmap="viridis", vmin=0, vmax=max(1, int(view.tokens.max())), aspect="auto")
            for (r, c), code in np.ndenumerate(codes):
                grid.text(c, r, str(int(code)), ha="center", va="center", color="white", fontsize=6)
            grid.set_title(f"tokens ({codes.shape[0]} x {codes.shape[1]})", color="white", fontsize=8)
    legend = "grey: dataset" + ("   green: decoded from tokens" if view.tokens is not None else "")
    fig.suptitle(f"{view.dataset}  episode {view.episode}  frame {int(view.frame_index[t])}    {legend}",
                 color="white", fontsize=9)  # fmt: skip
    fig.subplots_adjust(left=0.05, right=0.98, top=0.93, bottom=0.03)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return image[: image.shape[0] // 2 * 2, : image.shape[1] // 2 * 2]  # even size for yuv420p video


def write_video(view: EpisodeView, path: str | Path, camera: str = "oblique", progress: bool = True) -> Path:
    """Render every frame of `view` into an .mp4 (PyAV, H.264 or MPEG-4) or a .gif (Pillow); returns the path."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"write a video as one of {VIDEO_SUFFIXES}, got {str(path)!r} (.rrd: write_rerun)")
    if camera not in VIEWS:
        raise ValueError(f"unknown camera view {camera!r}; choose from {sorted(VIEWS)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    from lerobot_unidextok.utils.cli import progress_bar

    frames = (render_frame(view, t, camera) for t in range(view.num_frames))
    frames = progress_bar(frames, total=view.num_frames, desc=f"render {path.name}", unit="frame", disable=not progress)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        images = [Image.fromarray(f) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / view.fps), loop=0)
        return path
    _write_mp4(frames, path, view.fps)
    return path


def _write_mp4(frames, path: Path, fps: float) -> None:
    from fractions import Fraction

    import av

    codec = "libx264" if "libx264" in av.codecs_available else "mpeg4"
    with av.open(str(path), mode="w") as container:
        stream = None
        for image in frames:
            if stream is None:
                stream = container.add_stream(codec, rate=Fraction(fps).limit_denominator(1000))
                stream.height, stream.width = image.shape[:2]
                stream.pix_fmt = "yuv420p"
            container.mux(stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")))
        if stream is not None:
            container.mux(stream.encode(None))


def write_rerun(view: EpisodeView, path: str | Path) -> Path:
    """A rerun recording (.rrd): per hand 3D keypoints + bones (dataset and decoded), native values and
    tokens as time series on the episode's frame timeline. Needs rerun-sdk (`pip install 'lerobot[viz]'`)."""
    rr = require_package(
        "rerun-sdk", "viz", purpose="writing a rerun recording", import_name="rerun",
        hint=" (or 'lerobot[viz]'); an .mp4 or .gif needs nothing extra",
    )  # fmt: skip
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(f"unidextok/{Path(view.dataset).name}/episode_{view.episode}")
    rec.save(path)
    bones = np.array(BONES)  # (20, 2) child, parent
    rgb = {c: [int(c[i : i + 2], 16) for i in (1, 3, 5)] for c in (GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR)}
    for t in range(view.num_frames):
        rec.set_time("frame_index", sequence=int(view.frame_index[t]))
        for k, (hand, side) in enumerate(zip(view.hands, view.sides, strict=True)):
            base = f"{side}_{hand}"
            layers = [("dataset", view.keypoints_m, GROUND_TRUTH_COLOR)]
            if view.decoded_keypoints_m is not None:
                layers.append(("decoded", view.decoded_keypoints_m, UNIDEXTOK_COLOR))
            for name, kp_all, color in layers:
                kp = kp_all[t, k]  # (21, 3) m
                segments = np.stack([kp[bones[:, 1]], kp[bones[:, 0]]], axis=1)  # (20, 2, 3) parent -> child
                rec.log(f"{base}/{name}/keypoints", rr.Points3D(kp, colors=rgb[color], radii=0.003))
                rec.log(f"{base}/{name}/bones", rr.LineStrips3D(segments, colors=rgb[color]))
            if view.native[k] is not None:
                for j, joint in enumerate(view.native_names[k]):
                    rec.log(f"{base}/native/{joint}", rr.Scalars(float(view.native[k][t, j])))
            if view.tokens is not None:
                rec.log(f"{base}/tokens", rr.Tensor(view.tokens[t, k], dim_names=["token", "group"]))
    rec.flush()
    return path
