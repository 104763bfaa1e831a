"""Converting a robot dataset keeps the whole robot: arms, other observations, images and videos.

Fixtures are real LeRobot datasets: a v3.0 one written by LeRobot 0.6.1's own writer (videos encoded by
LeRobot), and a v2.1 one laid out as LeRobot 0.6 documents it (one parquet and one mp4 per episode, mp4s
encoded here with PyAV). Column names follow a Unitree G1 + Inspire layout written out in this file.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.conversion.validate import validate_dataset
from lerobot_unidextok.data import UdhmDatasetMeta, load_record

ARM = [f"k{side}{j}" for side in ("Left", "Right") for j in ("ShoulderPitch", "ShoulderRoll", "Elbow", "WristRoll")]
HAND = [
    f"k{side}Hand{j}"
    for side in ("Left", "Right")
    for j in ("Pinky", "Ring", "Middle", "Index", "ThumbBend", "ThumbRotation")
]
NAMES = ARM + HAND  # 8 arm + 12 hand columns
HANDS_OPT = {"hands": "unitree_g1_inspire"}
LENGTHS = (9, 12, 7)
H, W = 32, 48


def _episode(i: int, n: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(i)
    state = np.concatenate([rng.uniform(-1, 1, (n, 8)), rng.uniform(0.05, 0.95, (n, 12))], axis=1).astype(np.float32)
    frames = (np.arange(n)[:, None, None, None] * 20 + i * 60 + np.zeros((n, H, W, 3))).clip(0, 255).astype(np.uint8)
    frames[:, : H // 2, : W // 2, 0] = 255 - frames[:, : H // 2, : W // 2, 0]  # some structure per frame
    return {
        "observation.state": state,
        "action": (state + 0.01).clip(0, 1).astype(np.float32) * (np.arange(20) >= 8) + state * (np.arange(20) < 8),
        "observation.velocity": rng.normal(0, 1, (n, 3)).astype(np.float32),
        "frames": frames,
        "wrist": frames[:, ::-1].copy(),
    }


@pytest.fixture(scope="module")
def v30_source(tmp_path_factory):
    """A v3.0 dataset written by LeRobot's own writer: state/action 20-D, an extra observation, a camera
    stored as video (encoded by LeRobot) and one stored as images in the parquet."""
    from lerobot.datasets import LeRobotDataset

    root = tmp_path_factory.mktemp("v30") / "g1_like"
    features = {
        "observation.state": {"dtype": "float32", "shape": (20,), "names": NAMES},
        "action": {"dtype": "float32", "shape": (20,), "names": NAMES},
        "observation.velocity": {"dtype": "float32", "shape": (3,), "names": ["vx", "vy", "wz"]},
        "observation.images.cam_high": {"dtype": "video", "shape": (H, W, 3), "names": ["height", "width", "channels"]},
        "observation.images.wrist": {"dtype": "image", "shape": (H, W, 3), "names": ["height", "width", "channels"]},
    }
    ds = LeRobotDataset.create("t/g1_like", fps=30, features=features, root=root, use_videos=True, robot_type="g1")
    for i, n in enumerate(LENGTHS):
        ep = _episode(i, n)
        for t in range(n):
            ds.add_frame(
                {
                    "observation.state": ep["observation.state"][t],
                    "action": ep["action"][t].astype(np.float32),
                    "observation.velocity": ep["observation.velocity"][t],
                    "observation.images.cam_high": ep["frames"][t],
                    "observation.images.wrist": ep["wrist"][t],
                    "task": f"task {i % 2}",
                }
            )
        ds.save_episode()
    ds.finalize()
    return root


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def v30_converted(v30_source, tmp_path_factory):
    root = tmp_path_factory.mktemp("out") / "g1_udhm"
    convert(ConvertOptions(source="lerobot", input=v30_source, root=root, source_options=HANDS_OPT, progress=False))
    return root


def test_v30_keeps_arms_observations_images_and_videos(v30_source, v30_converted):
    """Every non-hand feature of the source survives unchanged (videos byte-identical files, frames
    decode equal). Catches the old converter, which wrote hand states only."""
    from lerobot.datasets import LeRobotDataset

    src = LeRobotDataset("t/g1_like", root=v30_source, video_backend="pyav")
    out = LeRobotDataset("t/g1_udhm", root=v30_converted, video_backend="pyav")
    assert out.num_frames == src.num_frames and out.num_episodes == 3
    for key in ("observation.velocity", "observation.images.cam_high", "observation.images.wrist"):
        assert key in out.meta.features
    assert out.meta.features["observation.state"]["names"][:8] == ARM
    assert out.meta.video_keys == ["observation.images.cam_high"]
    src_videos = sorted((v30_source / "videos").rglob("*.mp4"))
    out_videos = sorted((v30_converted / "videos").rglob("*.mp4"))
    assert [_sha(p) for p in src_videos] == [_sha(p) for p in out_videos]  # copied, never re-encoded
    for index in (0, 8, 9, 20, out.num_frames - 1):  # first/last frames of episodes
        a, b = src[index], out[index]
        assert a["episode_index"] == b["episode_index"] and a["frame_index"] == b["frame_index"]
        for key in ("observation.velocity", "observation.images.cam_high", "observation.images.wrist"):
            assert bool((a[key] == b[key]).all()), (key, index)
        np.testing.assert_array_equal(a["observation.state"][:8].numpy(), b["observation.state"][:8].numpy())
        assert a["task"] == b["task"]
    stats = json.loads((v30_converted / "meta/stats.json").read_text())
    assert {"observation.images.cam_high", "observation.images.wrist", "observation.velocity"} <= set(stats)
    assert validate_dataset(v30_converted).ok
    assert load_record(v30_converted).to_dict()["video_features"] == ["observation.images.cam_high"]


def test_v30_keeps_the_source_robot_type(v30_converted):
    """The converted dataset is still the source's robot (LeRobot's robot_type); catches the converter that
    wrote robot_type "udhm" for every dataset."""
    assert json.loads((v30_converted / "meta/info.json").read_text())["robot_type"] == "g1"
    assert load_record(v30_converted).to_dict()["robot_type"] == "g1"


def _native_action(root: Path, names: list[str]) -> np.ndarray:
    """The source action columns `names` rebuilt from a converted dataset with its recorded native layout."""
    import pyarrow.parquet as pq


    layout = UdhmDatasetMeta(root).native_layout("action")
    assert layout is not None and layout.native_names == names
    table = pq.read_table(sorted((root / "data").rglob("*.parquet")))
    action = np.stack(table["action"].to_numpy(zero_copy_only=False))
    return layout.to_native(action)


def test_keep_hands_writes_the_hands_only_dataset(v30_source, tmp_path):
    """--keep=hands: UDHM blocks only, a valid dataset whose native layout decodes the hand columns (in source
    order; `source_names` lists the whole robot). Catches the recorded layout that still named the arm columns
    as passthrough, so the dataset failed its own validation ('passthrough columns ... are not the first')."""
    root = tmp_path / "hands_only"
    convert(
        ConvertOptions(
            source="lerobot", input=v30_source, root=root, source_options=HANDS_OPT, keep="hands", progress=False
        )
    )
    info = json.loads((root / "meta/info.json").read_text())
    assert set(info["features"]) - {"timestamp", "frame_index", "episode_index", "index", "task_index"} == {
        "observation.state",
        "action",
        "hand_type",
        "udhm_mask",
    }
    assert info["features"]["observation.state"]["shape"] == [44] and not (root / "videos").exists()
    assert info["robot_type"] == "g1"
    report = validate_dataset(root)
    assert report.ok, report.table()
    layout = load_record(root).to_dict()["native_layout"]
    for key in ("observation.state", "action"):
        assert layout[key]["native_names"] == HAND and layout[key]["source_names"] == NAMES
    source_action = np.concatenate([_episode(i, n)["action"] for i, n in enumerate(LENGTHS)])
    np.testing.assert_allclose(_native_action(root, HAND), source_action[:, 8:], atol=1e-5)  # native units back


def test_keep_hands_needs_no_video_files(v30_source, tmp_path):
    """A dataset whose video files are gone converts hands-only (the videos are never opened); keeping the
    whole robot names the missing file. Catches the reader that demanded every video with --keep=hands."""
    import shutil

    from lerobot_unidextok.conversion.pipeline import ConversionError

    moved = tmp_path / "no_videos"
    shutil.copytree(v30_source, moved)
    shutil.rmtree(moved / "videos")
    root = tmp_path / "hands_only"
    report = convert(
        ConvertOptions(source="lerobot", input=moved, root=root, source_options=HANDS_OPT, keep="hands", progress=False)
    )
    assert report.num_episodes == 3 and report.num_frames == sum(LENGTHS)
    assert validate_dataset(root).ok
    with pytest.raises(ConversionError, match=r"\.mp4: video 'observation.images.cam_high' of episode 0 is missing"):
        convert(ConvertOptions(source="lerobot", input=moved, root=tmp_path / "all", source_options=HANDS_OPT,
                               progress=False))  # fmt: skip
    assert not (tmp_path / "all").exists()


def _write_v21_with_video(root: Path) -> None:
    """A LeRobot v2.1 dataset as LeRobot documents it: per-episode parquet and per-episode AV1 mp4."""
    import av
    import pyarrow as pa
    import pyarrow.parquet as pq

    (root / "meta").mkdir(parents=True)
    key = "observation.images.cam_high"
    episodes, stats, index = [], [], 0
    for i, n in enumerate(LENGTHS):
        ep = _episode(i, n)
        cols = {
            "observation.state": pa.FixedSizeListArray.from_arrays(pa.array(ep["observation.state"].ravel()), 20),
            "action": pa.FixedSizeListArray.from_arrays(pa.array(ep["action"].astype(np.float32).ravel()), 20),
            "observation.velocity": pa.FixedSizeListArray.from_arrays(pa.array(ep["observation.velocity"].ravel()), 3),
            "timestamp": pa.array((np.arange(n) / 30).astype(np.float32)),
            "frame_index": pa.array(np.arange(n, dtype=np.int64)),
            "episode_index": pa.array(np.full(n, i, np.int64)),
            "index": pa.array(np.arange(index, index + n, dtype=np.int64)),
            "task_index": pa.array(np.zeros(n, np.int64)),
        }
        path = root / f"data/chunk-000/episode_{i:06d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(cols), path)
        video = root / f"videos/chunk-000/{key}/episode_{i:06d}.mp4"
        video.parent.mkdir(parents=True, exist_ok=True)
        with av.open(str(video), "w") as container:
            stream = container.add_stream("libsvtav1", rate=30)
            stream.width, stream.height, stream.pix_fmt = W, H, "yuv420p"
            for frame in ep["frames"]:
                for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")):
                    container.mux(packet)
            for packet in stream.encode():
                container.mux(packet)
        episodes.append({"episode_index": i, "tasks": ["wave"], "length": n})
        img = ep["frames"].astype(np.float64) / 255.0
        stats.append(
            {
                "episode_index": i,
                "stats": {
                    key: {
                        "min": img.min(axis=(0, 1, 2)).reshape(3, 1, 1).tolist(),
                        "max": img.max(axis=(0, 1, 2)).reshape(3, 1, 1).tolist(),
                        "mean": img.mean(axis=(0, 1, 2)).reshape(3, 1, 1).tolist(),
                        "std": img.std(axis=(0, 1, 2)).reshape(3, 1, 1).tolist(),
                        "count": [n],
                    }
                },
            }
        )
        index += n
    scalar = {"dtype": "int64", "shape": [1], "names": None}
    info = {
        "codebase_version": "v2.1",
        "robot_type": "Unitree_G1_Inspire",
        "total_episodes": 3,
        "total_frames": index,
        "total_tasks": 1,
        "total_videos": 3,
        "total_chunks": 1,
        "chunks_size": 1000,
        "fps": 30,
        "splits": {"train": "0:3"},
        "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        "video_path": "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4",
        "features": {
            "observation.state": {"dtype": "float32", "shape": [20], "names": [NAMES]},
            "action": {"dtype": "float32", "shape": [20], "names": [NAMES]},
            "observation.velocity": {"dtype": "float32", "shape": [3], "names": ["vx", "vy", "wz"]},
            key: {
                "dtype": "video",
                "shape": [H, W, 3],
                "names": ["height", "width", "channels"],
                "info": {"video.fps": 30.0, "video.height": H, "video.width": W, "video.channels": 3,
                         "video.codec": "av1", "video.pix_fmt": "yuv420p", "video.is_depth_map": False,
                         "has_audio": False},
            },
            "timestamp": {"dtype": "float32", "shape": [1], "names": None},
            "frame_index": scalar,
            "episode_index": scalar,
            "index": scalar,
            "task_index": scalar,
        },
    }  # fmt: skip
    (root / "meta/info.json").write_text(json.dumps(info))
    (root / "meta/tasks.jsonl").write_text(json.dumps({"task_index": 0, "task": "wave"}) + "\n")
    (root / "meta/episodes.jsonl").write_text("".join(json.dumps(e) + "\n" for e in episodes))
    (root / "meta/episodes_stats.jsonl").write_text("".join(json.dumps(s) + "\n" for s in stats))


def test_v21_video_per_episode_files_are_copied_and_decode(tmp_path):
    """A v2.1 source (one mp4 per episode, like the upstream G1 + Inspire recordings with their camera):
    each file is copied unchanged and LeRobot decodes the converted episode's frames from it."""
    import av
    from lerobot.datasets import LeRobotDataset

    src = tmp_path / "v21"
    _write_v21_with_video(src)
    root = tmp_path / "out"
    convert(ConvertOptions(source="lerobot", input=src, root=root, source_options=HANDS_OPT, progress=False))
    out = LeRobotDataset("t/out", root=root, video_backend="pyav")
    key = "observation.images.cam_high"
    src_files = sorted((src / "videos").rglob("*.mp4"))
    assert sorted(_sha(p) for p in src_files) == sorted(_sha(p) for p in (root / "videos").rglob("*.mp4"))
    start = 0
    for i, n in enumerate(LENGTHS):
        with av.open(str(src_files[i])) as container:
            decoded = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
        for t in (0, n - 1):
            frame = (out[start + t][key].numpy().transpose(1, 2, 0) * 255).round().astype(np.uint8)
            np.testing.assert_array_equal(frame, decoded[t])
        start += n
    assert validate_dataset(root).ok
    stats = json.loads((root / "meta/stats.json").read_text())
    assert np.asarray(stats[key]["mean"]).shape == (3, 1, 1)  # the source's image stats, carried over
