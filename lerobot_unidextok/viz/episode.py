"""Look at one episode of a converted dataset: each hand drawn in 3D (the robot with its coupled joints, or
its URDF), its native values and, with a tokenizer, the tokens and the hand decoded from them; as an mp4 /
gif, or a rerun recording.

    view = load_episode("data/g1_udhm", episode=0, tokenizer="lab/unidextok-small")
    write_video(view, "outputs/view/g1_ep0.mp4")      # or .gif
    write_rerun(view, "outputs/view/g1_ep0.rrd")      # needs rerun-sdk (pip install 'lerobot[viz]')

Frames come from `viz/render.py` (matplotlib object API, headless); mp4 is encoded with PyAV (LeRobot's
video dependency, its wheels bundle the codecs), gif with Pillow. No FFmpeg binary is needed.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_unidextok import hands as hand_registry
from lerobot_unidextok.constants import INFO_PATH, OBS_STATE, UDHM_DIM
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.utils.files import temp_file_sibling
from lerobot_unidextok.utils.imports import require_package
from lerobot_unidextok.viz.pose import find_urdf, spec_keypoints_m, urdf_keypoints_m
from lerobot_unidextok.viz.render import BONES, VIEWS, EpisodeRenderer
from lerobot_unidextok.viz.style import GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR

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
    keypoints_m: np.ndarray | None = field(default=None, repr=False)  # (T, H, 21, 3) the drawn hand (viz/pose.py)
    decoded_keypoints_m: np.ndarray | None = field(default=None, repr=False)  # (T, H, 21, 3)
    pose_source: list[str] = field(default_factory=list)  # per hand: what the keypoints come from

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
        raise InvalidInputError(f"episode {episode} is not in {root}; see meta/info.json total_episodes")
    order = np.argsort(np.concatenate(frames), kind="stable")
    return np.concatenate(rows)[order], np.concatenate(frames)[order]


def load_episode(
    dataset: str | Path,
    episode: int = 0,
    tokenizer: str | None = None,
    stride: int = 1,
    max_frames: int | None = None,
    urdf: str | Path | None = None,
) -> EpisodeView:
    """Read episode `episode` of a converted dataset (folder or repo id on this machine); with `tokenizer`
    (folder or repo id) also its tokens and the decoded hands. Every `stride`-th frame, at most `max_frames`.
    Robot hands are drawn from their spec (skeleton and coupled joints), or with `urdf` (a URDF file, or a
    folder holding each hand's `urdf.file`) by the URDF's own kinematics."""

    from lerobot_unidextok.data import UdhmDatasetMeta
    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep
    from lerobot_unidextok.utils.hf_cache import dataset_root

    root = Path(dataset)
    if not (root / INFO_PATH).is_file():
        if root.exists() or str(dataset).count("/") != 1:
            raise MissingInputError(f"{dataset} is not a LeRobotDataset folder (meta/info.json missing) nor a repo id")
        root = dataset_root(str(dataset))
    if stride < 1:
        raise InvalidInputError(f"stride must be >= 1, got {stride}")
    meta = UdhmDatasetMeta(root)
    info, layout = meta.info, meta.hand_layout()
    states, frame_index = _episode_states(root, episode)
    take = np.arange(0, len(states), stride)[:max_frames]
    states, frame_index = states[take], frame_index[take]
    blocks = states[:, layout.block_columns].reshape(len(states), layout.num_hands, UDHM_DIM)  # (T, H, 22)

    tokens = decoded_rad = None
    if tokenizer is not None:
        import torch

        step = UniDexTokStateTokenizerStep(hand_layout=layout.hands, state_names=layout.state_names,
                                           pretrained=str(tokenizer), allow_unknown=True, range_check="warn")  # fmt: skip
        codes, decoded = step.tokenize(torch.as_tensor(states, dtype=torch.float32))  # (T, H*N*K), (T, H*22)
        cfg = step.tokenizer.config
        tokens = codes.numpy().reshape(len(states), layout.num_hands, cfg.num_tokens, cfg.num_groups)
        decoded_rad = decoded.numpy().astype(np.float64).reshape(len(states), layout.num_hands, UDHM_DIM)
    return view_states(blocks, layout.hands, layout.sides, fps=float(info["fps"]) / stride, frame_index=frame_index,
                       tokens=tokens, decoded_rad=decoded_rad, urdf=urdf, dataset=str(dataset), episode=episode)  # fmt: skip


def view_states(
    states_rad: np.ndarray,
    hands: list[str],
    sides: list[str],
    *,
    fps: float = 30.0,
    frame_index: np.ndarray | None = None,
    tokens: np.ndarray | None = None,
    decoded_rad: np.ndarray | None = None,
    urdf: str | Path | None = None,
    dataset: str = "",
    episode: int = 0,
) -> EpisodeView:
    """The view of UDHM states `(T, H, 22)` of `hands` on `sides` (e.g. a model's output): native values and
    the keypoints drawn, from each hand's spec (skeleton, coupled joints) or, with `urdf`, its URDF.
    `tokens` (T, H, N, K) and `decoded_rad` (T, H, 22) add the token grid and the decoded hand."""
    states_rad = np.asarray(states_rad, dtype=np.float64)
    if states_rad.ndim != 3 or states_rad.shape[1:] != (len(hands), UDHM_DIM) or len(sides) != len(hands):
        raise ValueError(f"states_rad must be (T, {len(hands)}, {UDHM_DIM}) for hands {hands} on sides {sides}, "
                         f"got {states_rad.shape}")  # fmt: skip
    specs = [hand_registry.get(h) for h in hands]
    urdfs = [find_urdf(urdf, s, side) if urdf is not None and s.kind == "joints" else None
             for s, side in zip(specs, sides, strict=True)]  # fmt: skip

    def native_of(states):  # per hand (T, J) native values, None for a hand given as keypoints
        return [s.from_udhm(states[:, k], side) if s.kind == "joints" else None
                for k, (s, side) in enumerate(zip(specs, sides, strict=True))]  # fmt: skip

    view = EpisodeView(
        dataset=dataset, episode=episode, fps=fps, hands=list(hands), sides=list(sides), states_rad=states_rad,
        native=native_of(states_rad), native_names=[list(s.joint_names) if s.kind == "joints" else [] for s in specs],
        frame_index=np.arange(len(states_rad)) if frame_index is None else np.asarray(frame_index), tokens=tokens,
        pose_source=[f"URDF {p.name}" if p is not None else "coupled joints" if any(c.slot for c in s.coupled)
                     else "" for s, p in zip(specs, urdfs, strict=True)],
    )  # fmt: skip
    view.keypoints_m = _keypoints(states_rad, view.native, specs, sides, urdfs)
    if decoded_rad is not None:
        view.decoded_rad = np.asarray(decoded_rad, dtype=np.float64)
        view.decoded_native = native_of(view.decoded_rad)
        view.decoded_keypoints_m = _keypoints(view.decoded_rad, view.decoded_native, specs, sides, urdfs)
    return view


def _keypoints(states_rad: np.ndarray, native: list, specs, sides: list[str], urdfs: list) -> np.ndarray:
    """(T, H, 22) -> (T, H, 21, 3) keypoints in metres: each hand from its URDF when it has one, else
    from its spec (skeleton, side and coupled joints)."""
    return np.stack(
        [urdf_keypoints_m(s, native[k], side, u) if u is not None else spec_keypoints_m(s, states_rad[:, k], side)
         for k, (s, side, u) in enumerate(zip(specs, sides, urdfs, strict=True))], axis=1)  # fmt: skip


# ---------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------
def write_video(view: EpisodeView, path: str | Path, camera: str = "oblique", progress: bool = True) -> Path:
    """Render every frame of `view` into an .mp4 (PyAV, H.264 or MPEG-4) or a .gif (Pillow); returns the path.
    The file appears only when complete (written beside it, then renamed)."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"write a video as one of {VIDEO_SUFFIXES}, got {str(path)!r} (.rrd: write_rerun)")
    if camera not in VIEWS:
        raise ValueError(f"unknown camera view {camera!r}; choose from {sorted(VIEWS)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    from lerobot_unidextok.utils.cli import progress_bar

    renderer = EpisodeRenderer(view, camera)
    frames = (renderer.render(t) for t in range(view.num_frames))
    frames = progress_bar(frames, total=view.num_frames, desc=f"render {path.name}", unit="frame", disable=not progress)
    partial = temp_file_sibling(path)  # named per run: two renders of one path never share it
    try:
        if path.suffix.lower() == ".gif":
            _write_gif(frames, partial, view.fps, [renderer.render(t) for t in _palette_frames(view.num_frames)])
        else:
            _write_mp4(frames, partial, view.fps)
        partial.replace(path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def _palette_frames(num_frames: int) -> list[int]:
    """Frames whose colours make the GIF's palette: first, middle, last."""
    return sorted({0, num_frames // 2, num_frames - 1})


def _write_gif(frames, path: Path, fps: float, samples: list[np.ndarray]) -> None:
    """One 256-colour palette from `samples` for every frame (no per-frame colour search, no dithering)."""
    from PIL import Image

    palette = Image.fromarray(np.concatenate(samples)).quantize(256, method=Image.Quantize.FASTOCTREE)
    images = (Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames)
    first = next(images)
    first.save(
        path, format="GIF", save_all=True, append_images=images, duration=round(1000 / fps), loop=0, optimize=False
    )  # Pillow's palette optimisation re-reads every pixel in Python


def _write_mp4(frames, path: Path, fps: float) -> None:
    from fractions import Fraction

    import av

    codec = "libx264" if "libx264" in av.codecs_available else "mpeg4"
    with av.open(str(path), mode="w", format="mp4") as container:
        stream = None
        for image in frames:
            if stream is None:
                stream = container.add_stream(codec, rate=Fraction(fps).limit_denominator(1000))
                stream.height, stream.width = image.shape[:2]
                stream.pix_fmt = "yuv420p"
                if codec == "libx264":
                    stream.options = {"preset": "veryfast"}  # faster than the default preset (benchmarks/bench_view.py)
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
                segments = kp[BONES]  # (20, 2, 3) parent -> child
                rec.log(f"{base}/{name}/keypoints", rr.Points3D(kp, colors=rgb[color], radii=0.003))
                rec.log(f"{base}/{name}/bones", rr.LineStrips3D(segments, colors=rgb[color]))
            if view.native[k] is not None:
                for j, joint in enumerate(view.native_names[k]):
                    rec.log(f"{base}/native/{joint}", rr.Scalars(float(view.native[k][t, j])))
            if view.tokens is not None:
                rec.log(f"{base}/tokens", rr.Tensor(view.tokens[t, k], dim_names=["token", "group"]))
    rec.flush()
    return path
