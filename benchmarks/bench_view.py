"""Episode viewer speed: frames/s of `unidextok-view`'s renderer next to references measured in the same run.

    .venv/bin/python benchmarks/bench_view.py [--frames 120] [--reference_frames 20]

Data: episode 0 of the real G1 + Inspire fixture (../shared/data/real/g1-inspire, or $UNIDEXTOK_REAL_DATA)
converted with `--source=lerobot`, else the synthetic G1 sample (`samples`) converted the same
way. Rows (CPU time is the primary clock on shared cores; wall time is printed too):
- reference, per-frame figure: the viewer as it was (a new Figure with one mplot3d axes per hand per frame,
  a Line3D per bone, bars and token grid redrawn), kept here as `_reference_frame`;
- reference, full redraw: the new figure with every artist redrawn by `canvas.draw()` each frame (no blit);
- renderer: `EpisodeRenderer.render(t)` (update the moving artists, blit onto the saved background);
- mp4 / gif end to end: `write_video` (render + encode, PyAV libx264 / Pillow), setup included;
- encode only, on the rendered frames: libx264 at its default preset and at the viewer's, and a GIF with
  Pillow's defaults (the previous writer: a palette searched per frame, palette optimisation).
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

import numpy as np

from lerobot_unidextok.converters.lerobot import G1_INSPIRE_HANDS
from lerobot_unidextok.utils.shared_data import real_data_dir

REPO = Path(__file__).resolve().parents[1]
REAL = real_data_dir(REPO) / "g1-inspire"
HANDS = {"hands": G1_INSPIRE_HANDS}


def _dataset(tmp: Path) -> tuple[Path, str]:
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    if REAL.is_dir():
        source, what = REAL, f"real G1 + Inspire ({REAL.name}, converted)"
    else:
        from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

        source = write_samples(tmp / "raw", sources=["lerobot"], episodes_per_source=1, frames_per_episode=400)
        source, what = source["lerobot"], "synthetic G1 sample (samples, converted)"
        HANDS.update(SAMPLE_SOURCE_OPTIONS["lerobot"])
    root = tmp / "g1_udhm"
    convert(ConvertOptions(source="lerobot", input=source, root=root, source_options=HANDS, progress=False))
    return root, what


def _reference_frame(view, t: int, camera: str = "oblique", dpi: int = 80) -> np.ndarray:
    """The viewer's frame as it was drawn before the renderer: a new figure with 3D axes for every frame."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the 3d projection)

    from lerobot_unidextok import hands as hand_registry
    from lerobot_unidextok.viz.render import BONES
    from lerobot_unidextok.viz.style import DARK_BG, GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR, VIEWS

    def skeleton(ax, kp_mm, color, width):
        for parent, child in BONES:
            seg = kp_mm[[parent, child]]
            ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color=color, linewidth=width, solid_capstyle="round")
        ax.scatter(kp_mm[:, 0], kp_mm[:, 1], kp_mm[:, 2], color=color, s=4 * width, depthshade=False)

    h = len(view.hands)
    fig = Figure(figsize=(4.2 * h, 7.0), facecolor=DARK_BG, dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    rows = fig.add_gridspec(3, h, height_ratios=[3.2, 1.0, 1.0], hspace=0.55, wspace=0.15)
    kp_all = view.keypoints_m * 1000.0
    centre = 0.5 * (kp_all.min(axis=(0, 2)) + kp_all.max(axis=(0, 2)))
    half = float(np.abs(kp_all - centre[None, :, None]).max()) * 1.05
    for k, (hand, side) in enumerate(zip(view.hands, view.sides, strict=True)):
        ax = fig.add_subplot(rows[0, k], projection="3d")
        ax.set_facecolor(DARK_BG)
        skeleton(ax, kp_all[t, k], GROUND_TRUTH_COLOR, 2.6)
        if view.decoded_keypoints_m is not None:
            skeleton(ax, view.decoded_keypoints_m[t, k] * 1000.0, UNIDEXTOK_COLOR, 1.6)
        for axis, c in zip("xyz", centre[k], strict=True):
            getattr(ax, f"set_{axis}lim")(c - half, c + half)
        ax.set_box_aspect((1, 1, 1), zoom=1.5)
        ax.view_init(elev=VIEWS[camera][0], azim=VIEWS[camera][1])
        ax.set_axis_off()
        ax.set_title(f"{side} {hand}", color="white", fontsize=9)
        panel = fig.add_subplot(rows[1, k])
        panel.set_facecolor(DARK_BG)
        panel.tick_params(colors="white", labelsize=6)
        values, names = view.native[k][t], view.native_names[k]
        panel.bar(range(len(values)), values, color=GROUND_TRUTH_COLOR)
        lo, hi = hand_registry.get(hand).raw_range(side).T
        panel.set_ylim(float(lo.min()), float(hi.max()))
        panel.set_xticks(range(len(values)), [n[:8] for n in names], rotation=60)
        panel.set_title("native values", color="white", fontsize=8)
        fig.add_subplot(rows[2, k]).set_axis_off()
    fig.suptitle(f"{view.dataset}  episode {view.episode}  frame {int(view.frame_index[t])}", color="white", fontsize=9)
    fig.subplots_adjust(left=0.05, right=0.98, top=0.93, bottom=0.03)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return image[: image.shape[0] // 2 * 2, : image.shape[1] // 2 * 2]


def _encode_mp4(frames: list[np.ndarray], path: Path, preset: str) -> int:
    """Encode `frames` with libx264 at `preset` (PyAV); returns the file size in bytes."""
    import av

    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=30)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt, stream.options = "yuv420p", {"preset": preset}
        for image in frames:
            container.mux(stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")))
        container.mux(stream.encode(None))
    return path.stat().st_size


def _reference_gif(frames: list[np.ndarray], path: Path, fps: float) -> None:
    """The GIF as it was written: Pillow's defaults (a palette searched per frame, palette optimisation)."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0)


def _timed(fn, n: int) -> tuple[float, float]:
    """(CPU s, wall s) of fn(t) for t in range(n)."""
    c0, w0 = time.process_time(), time.perf_counter()
    for t in range(n):
        fn(t)
    return time.process_time() - c0, time.perf_counter() - w0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=120, help="frames drawn by the renderer and the writers")
    parser.add_argument("--reference_frames", type=int, default=20, help="frames drawn by the per-frame reference")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)

    from lerobot_unidextok.viz.episode import load_episode, write_video
    from lerobot_unidextok.viz.render import EpisodeRenderer

    with tempfile.TemporaryDirectory() as tmp:
        root, what = _dataset(Path(tmp))
        view = load_episode(root, episode=0, max_frames=args.frames)
        n = view.num_frames
        rows = []
        cpu, wall = _timed(lambda t: _reference_frame(view, t), min(args.reference_frames, n))
        rows.append(("reference: new figure + 3D axes per frame", min(args.reference_frames, n), cpu, wall))

        full = EpisodeRenderer(view)
        for artist in full.update(0):
            artist.set_animated(False)  # every artist in the normal draw
        cpu, wall = _timed(lambda t: (full.update(t), full.canvas.draw()), n)
        rows.append(("reference: same figure, full redraw per frame", n, cpu, wall))

        c0, w0 = time.process_time(), time.perf_counter()
        renderer = EpisodeRenderer(view)
        setup = (time.process_time() - c0, time.perf_counter() - w0)
        cpu, wall = _timed(renderer.render, n)
        rows.append(("EpisodeRenderer.render (blit)", n, cpu, wall))
        for suffix in ("mp4", "gif"):
            c0, w0 = time.process_time(), time.perf_counter()
            write_video(view, Path(tmp) / f"ep0.{suffix}", progress=False)
            rows.append((f"write_video .{suffix} end to end", n, time.process_time() - c0, time.perf_counter() - w0))
        size = renderer.render(0).shape
        frames = [renderer.render(t) for t in range(n)]
        sizes = {}
        for preset in ("medium", "veryfast"):  # libx264's default, and the viewer's
            c0, w0 = time.process_time(), time.perf_counter()
            sizes[preset] = _encode_mp4(frames, Path(tmp) / f"{preset}.mp4", preset)
            rows.append((f"encode only: libx264 {preset}", n, time.process_time() - c0, time.perf_counter() - w0))
        m = min(args.reference_frames, n)
        c0, w0 = time.process_time(), time.perf_counter()
        _reference_gif(frames[:m], Path(tmp) / "ref.gif", view.fps)
        rows.append(
            ("encode only: gif, Pillow defaults (reference)", m, time.process_time() - c0, time.perf_counter() - w0)
        )

    print(f"data: {what}, episode 0, {n} frames, 2 hands, frame {size[1]} x {size[0]} px; "
          f"renderer setup {setup[0]:.2f} s CPU ({setup[1]:.2f} s wall)")  # fmt: skip
    print(f"{'path':48s} {'frames':>6s} {'CPU s':>7s} {'wall s':>7s} {'frames/CPU-s':>13s} {'frames/s wall':>13s}")
    for name, frames, cpu, wall in rows:
        print(f"{name:48s} {frames:6d} {cpu:7.2f} {wall:7.2f} {frames / cpu:13.1f} {frames / wall:13.1f}")
    ref = rows[0][1] / rows[0][2]
    for name, frames, cpu, _ in rows[1:5]:
        print(f"speed-up over the per-frame reference (CPU): {name}: {frames / cpu / ref:.0f}x")
    print("mp4 sizes: " + ", ".join(f"{p} {b / 1024:.0f} KB" for p, b in sizes.items()))


if __name__ == "__main__":
    main()
