"""The episode viewer: 3D hands from FK, native values and decoded tokens, as mp4 / gif / rerun recording."""

import sys
import warnings

import numpy as np
import pytest
import torch
from robot_udhm import INSPIRE

from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.viz.episode import load_episode, write_rerun, write_video
from lerobot_unidextok.viz.render import render_frame
from lerobot_unidextok.viz.style import GROUND_TRUTH_COLOR, UNIDEXTOK_COLOR


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(3)
    path = tmp_path_factory.mktemp("tok") / "tok"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=[INSPIRE])).save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def view(g1_like, tok_dir):
    return load_episode(g1_like["root"], episode=1, tokenizer=str(tok_dir), stride=4)


def _has_color(img: np.ndarray, hex_color: str, min_pixels: int = 20) -> bool:
    rgb = np.array([int(hex_color[i : i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(img.astype(int) - rgb).max(-1) < 16).sum()) >= min_pixels


def test_episode_holds_native_values_tokens_and_decoded_hands(view, g1_like):
    assert view.hands == [INSPIRE, INSPIRE] and view.sides == ["left", "right"]
    assert view.num_frames == 10 and view.fps == 7.5  # 40 frames, every 4th, 30 fps / 4
    np.testing.assert_array_equal(view.frame_index, np.arange(0, 40, 4))
    native = g1_like["native_state"][40:80:4]  # episode 1, 26 native columns (Unitree order)
    np.testing.assert_allclose(view.native[0], native[:, 14:20], atol=1e-5)  # left hand, [0, 1] units
    np.testing.assert_allclose(view.native[1], native[:, 20:26], atol=1e-5)
    assert view.native_names[0] == ["little", "ring", "middle", "index", "thumb_bend", "thumb_rotation"]
    assert view.tokens.shape == (10, 2, 4, 8) and view.decoded_rad.shape == (10, 2, 22)
    assert view.keypoints_m.shape == view.decoded_keypoints_m.shape == (10, 2, 21, 3)
    assert 0 <= view.decoded_native[1].min() and view.decoded_native[1].max() <= 1


def test_frame_draws_dataset_and_decoded_hands(view):
    img = render_frame(view, 3)
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[0] % 2 == 0 and img.shape[1] % 2 == 0
    assert _has_color(img, GROUND_TRUTH_COLOR) and _has_color(img, UNIDEXTOK_COLOR)


def test_mp4_and_gif(view, tmp_path):
    import av
    from PIL import Image

    mp4 = write_video(view, tmp_path / "ep.mp4", progress=False)
    with av.open(str(mp4)) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(frames) == view.num_frames
    expected = render_frame(view, 4)
    assert frames[4].shape == expected.shape and np.abs(frames[4].astype(int) - expected).mean() < 4  # lossy H.264
    gif = write_video(view, tmp_path / "ep.gif", camera="side", progress=False)
    with Image.open(gif) as im:
        assert im.n_frames == view.num_frames and abs(im.info["duration"] - 1000 / 7.5) <= 10  # GIF: 10 ms units
        im.seek(3)
        drawn = np.asarray(im.convert("RGB")).astype(int)
    # one palette for every frame, no dithering: frame 3 keeps its colours within the palette's rounding
    expected = render_frame(view, 3, camera="side").astype(int)
    assert np.abs(drawn - expected).mean() < 2.0 and _has_color(drawn.astype(np.uint8), UNIDEXTOK_COLOR)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep.gif", "ep.mp4"]  # no partial files left
    with pytest.raises(ValueError, match=r"\.mp4.*\.gif"):
        write_video(view, tmp_path / "ep.avi")


def test_rerun_recording(view, tmp_path):
    pytest.importorskip("rerun", reason="rerun-sdk not installed (pip install 'lerobot[viz]')")
    from rerun.recording import load_recording

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = write_rerun(view, tmp_path / "ep.rrd")
    assert not [w for w in caught if "Rerun" in type(w.message).__name__], [str(w.message) for w in caught]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        entities = {c.entity_path for c in load_recording(str(path)).schema().component_columns()}
    assert {f"/left_{INSPIRE}/dataset/keypoints", f"/right_{INSPIRE}/decoded/bones",
            f"/right_{INSPIRE}/native/thumb_rotation", f"/left_{INSPIRE}/tokens"} <= entities  # fmt: skip


def test_cli_writes_a_gif_and_refuses_bad_input(g1_like, tmp_path, monkeypatch, capsys):
    from lerobot_unidextok.scripts.view import main

    out = tmp_path / "v.gif"
    monkeypatch.setattr(sys, "argv", ["unidextok-view", f"--dataset={g1_like['root']}", f"--output={out}",
                                      "--stride=10", "--episode=2"])  # fmt: skip
    main()
    assert out.is_file() and "wrote" in capsys.readouterr().out
    for argv, message in [
        ([f"--dataset={g1_like['root']}", "--output=x.avi"], "error: --output must end in .mp4, .gif or .rrd"),
        (
            [f"--dataset={g1_like['root']}", f"--urdf={tmp_path / 'none'}", f"--output={out}"],
            f"error: --urdf {tmp_path / 'none'} is neither a URDF file nor a folder",
        ),
        (
            [f"--dataset={g1_like['root']}", f"--urdf={tmp_path}", f"--output={out}"],
            f"error: no URDF for the left {INSPIRE} hand under {tmp_path}: tried",
        ),
        ([f"--dataset={g1_like['root']}", "--episode=9", f"--output={out}"], "error: episode 9 is not in"),
        (["--dataset=lab/not-here", f"--output={out}"], "error: dataset 'lab/not-here' is not on this machine"),
    ]:
        monkeypatch.setattr(sys, "argv", ["unidextok-view", *argv])
        with pytest.raises(SystemExit):
            main()
        err = capsys.readouterr().err
        assert err.startswith(message) and "Traceback" not in err
