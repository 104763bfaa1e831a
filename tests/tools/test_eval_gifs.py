"""tools/sim/eval_gifs.py: the mp4 -> GIF step on a synthetic 3-frame video, and which episode the GIF shows.

No CLI is run here (the tool's record/train/eval steps are the project's CLIs, tested where they live).
"""

from pathlib import Path

import av
import numpy as np
import pytest
from PIL import Image, ImageSequence
from tool_module import tool_module

ROOT = Path(__file__).resolve().parents[2]
COLOURS = ((220, 30, 30), (30, 220, 30), (30, 30, 220))  # frame i: one solid colour (RGB)


@pytest.fixture(scope="module")
def eval_gifs():
    with tool_module("sim/eval_gifs.py", "unidextok_eval_gifs_tool") as module:
        yield module


def _write_mp4(path: Path, fps: int) -> None:
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = 64, 48, "yuv420p"
        for colour in COLOURS:
            frame = np.full((48, 64, 3), colour, dtype=np.uint8)  # (H, W, 3)
            container.mux(stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
        container.mux(stream.encode())


def test_mp4_to_gif_keeps_every_nth_frame_and_the_last(eval_gifs, tmp_path):
    mp4, gif = tmp_path / "episode.mp4", tmp_path / "out" / "episode.gif"
    _write_mp4(mp4, fps=10)
    size = eval_gifs.mp4_to_gif(mp4, gif, width_px=32, fps=5.0)
    assert size == gif.stat().st_size
    with Image.open(gif) as im:
        frames = [(f.convert("RGB"), f.info["duration"]) for f in ImageSequence.Iterator(im)]
    # 10 fps at 5 fps: frames 0 and 2, which is also the last; 200 ms each, the last held 1 s
    assert [f.size for f, _ in frames] == [(32, 24)] * 2
    assert [d for _, d in frames] == [200, 1000]
    for (frame, _), colour in zip(frames, (COLOURS[0], COLOURS[2]), strict=True):
        assert np.abs(np.asarray(frame, dtype=int)[12, 16] - colour).max() < 40  # h264 + palette error


def test_the_gif_shows_the_first_success_else_episode_0(eval_gifs):
    info = {"per_task": [{"metrics": {"successes": [False, True, True], "video_paths": ["a.mp4", "b.mp4"]}}]}
    successes, videos = eval_gifs.episodes_of(info)
    assert eval_gifs.pick_episode(successes, len(videos)) == 1
    assert eval_gifs.pick_episode([False, False, True], 2) == 0  # the success has no video
    with pytest.raises(ValueError, match="no video"):
        eval_gifs.pick_episode([True], 0)
    assert eval_gifs.gif_name("FingerSequence-v0") == "eval_fingersequence.gif"
