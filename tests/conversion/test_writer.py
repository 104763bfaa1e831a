"""UdhmDatasetWriter vs LeRobot 0.6.1's own per-frame writer on the same episodes."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from lerobot_unidextok.constants import UDHM_JOINT_NAMES
from lerobot_unidextok.conversion.writer import UdhmDatasetWriter

NAMES = [f"{s}_{j}" for s in ("right", "left") for j in UDHM_JOINT_NAMES]
FEATURES = {
    "observation.state": {"dtype": "float32", "shape": (44,), "names": NAMES},
    "action": {"dtype": "float32", "shape": (44,), "names": NAMES},
    "hand_type": {"dtype": "string", "shape": (1,), "names": None},
    "udhm_mask": {"dtype": "bool", "shape": (44,), "names": NAMES},
}


def add_episode_per_frame(ref, ep: dict) -> None:
    """One episode through LeRobot's own per-frame writer (the reference)."""
    for t in range(len(ep["observation.state"])):
        ref.add_frame(
            {
                "observation.state": ep["observation.state"][t],
                "action": ep["action"][t],
                "hand_type": ep["hand_type"],
                "udhm_mask": ep["udhm_mask"][t],
                "task": ep["task"],
            }
        )
    ref.save_episode()


def _episodes():
    rng = np.random.default_rng(3)
    eps = []
    for i, length in enumerate([40, 1, 2, 57, 33]):  # includes LeRobot's <2-frame stats path
        state = np.cumsum(rng.normal(0, 0.05, size=(length, 44)), axis=0).astype(np.float32)
        state[:, 5] = 0.25  # a constant joint
        mask = np.ones(44, bool)
        mask[[1, 3, 22 + 17]] = False
        state[:, ~mask] = 0.0
        eps.append(
            {
                "observation.state": state,
                "action": (state + 0.01).astype(np.float32),
                "hand_type": "inspire_rh56,linkerhand_l10" if i % 2 else "human,human",
                "udhm_mask": np.tile(mask, (length, 1)),
                "task": ["pick", "place", "pick", "", "wave"][i],
            }
        )
    return eps


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    from lerobot.datasets import LeRobotDataset

    base = tmp_path_factory.mktemp("cmp")
    ref_root, fast_root = base / "lerobot", base / "fast"
    eps = _episodes()
    ref = LeRobotDataset.create(
        "test/ref",
        fps=30,
        features=FEATURES,
        root=ref_root,
        robot_type="hands",
        use_videos=False,
    )
    for ep in eps:
        add_episode_per_frame(ref, ep)
    ref.finalize()

    w = UdhmDatasetWriter(fast_root, "test/fast", fps=30, features=FEATURES, robot_type="hands")
    for ep in eps:
        w.add_episode({k: v for k, v in ep.items() if k != "task"}, task=ep["task"])
    w.finalize(splits={"train": "0:5"})
    return ref_root, fast_root, eps


def test_same_files(both):
    ref_root, fast_root, _ = both
    rel = lambda root: sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())
    assert rel(ref_root) == rel(fast_root)


def test_same_data_parquet(both):
    ref_root, fast_root, _ = both
    a = pq.read_table(ref_root / "data/chunk-000/file-000.parquet")
    b = pq.read_table(fast_root / "data/chunk-000/file-000.parquet")
    assert a.schema.remove_metadata() == b.schema.remove_metadata()
    hf_a = json.loads(a.schema.metadata[b"huggingface"])["info"]
    hf_b = json.loads(b.schema.metadata[b"huggingface"])["info"]
    assert hf_a == hf_b
    assert a.equals(b.replace_schema_metadata(a.schema.metadata))  # bit-exact content
    ra = pq.ParquetFile(ref_root / "data/chunk-000/file-000.parquet").metadata
    rb = pq.ParquetFile(fast_root / "data/chunk-000/file-000.parquet").metadata
    assert ra.num_row_groups == rb.num_row_groups == 5


def test_same_meta(both):
    ref_root, fast_root, _ = both
    ia = json.loads((ref_root / "meta/info.json").read_text())
    ib = json.loads((fast_root / "meta/info.json").read_text())
    ia.pop("splits"), ib.pop("splits")
    assert ia == ib
    assert pq.read_table(ref_root / "meta/tasks.parquet").equals(pq.read_table(fast_root / "meta/tasks.parquet"))
    ea = pq.read_table(ref_root / "meta/episodes/chunk-000/file-000.parquet")
    eb = pq.read_table(fast_root / "meta/episodes/chunk-000/file-000.parquet")
    assert ea.schema == eb.schema
    assert ea.equals(eb)  # per-episode stats bit-exact


def test_same_stats(both):
    ref_root, fast_root, _ = both
    sa = json.loads((ref_root / "meta/stats.json").read_text())
    sb = json.loads((fast_root / "meta/stats.json").read_text())
    assert sa.keys() == sb.keys()
    for key in sa:
        assert sa[key].keys() == sb[key].keys()
        for stat in sa[key]:
            np.testing.assert_allclose(
                np.array(sb[key][stat], float),
                np.array(sa[key][stat], float),
                rtol=1e-6,
                atol=1e-9,
                err_msg=f"{key}/{stat}",
            )


def test_loads_with_lerobot_offline(both):
    from lerobot.datasets import LeRobotDataset

    _ref_root, fast_root, eps = both
    ds = LeRobotDataset("test/fast", root=fast_root)
    assert ds.num_episodes == 5 and ds.num_frames == sum(len(e["observation.state"]) for e in eps)
    item = ds[40]  # episode 1, its only frame
    np.testing.assert_array_equal(item["observation.state"].numpy(), eps[1]["observation.state"][0])
    assert item["task"] == "place" and item["hand_type"] == "inspire_rh56,linkerhand_l10"
    assert int(item["episode_index"]) == 1
    assert ds.meta.info.splits == {"train": "0:5"}


def test_data_file_rollover_matches_lerobot(tmp_path):
    """Tiny data_files_size_in_mb forces several data files; layout equals LeRobot's."""
    from lerobot.datasets import LeRobotDataset

    eps = _episodes()
    ref = LeRobotDataset.create(
        "t/r",
        fps=30,
        features=FEATURES,
        root=tmp_path / "r",
        use_videos=False,
        data_files_size_in_mb=0.01,
    )
    w = UdhmDatasetWriter(tmp_path / "f", "t/f", fps=30, features=FEATURES, data_files_size_in_mb=0.01)
    for ep in eps:
        frames = {k: v for k, v in ep.items() if k != "task"}
        add_episode_per_frame(ref, ep)
        w.add_episode(frames, task=ep["task"])
    ref.finalize()
    w.finalize()
    ea = pq.read_table(tmp_path / "r/meta/episodes").select(["episode_index", "data/chunk_index", "data/file_index"])
    eb = pq.read_table(tmp_path / "f/meta/episodes").select(["episode_index", "data/chunk_index", "data/file_index"])
    assert ea.equals(eb)
    assert max(eb.column("data/file_index").to_pylist()) >= 1
    assert LeRobotDataset("t/f", root=tmp_path / "f").num_frames == sum(len(e["observation.state"]) for e in eps)


def test_bad_episode_raises(tmp_path):
    w = UdhmDatasetWriter(tmp_path / "x", "t/x", fps=30, features=FEATURES)
    good = {k: v for k, v in _episodes()[0].items() if k != "task"}
    with pytest.raises(ValueError, match="expected dtype float32"):
        w.add_episode({**good, "action": good["action"].astype(np.float64)}, task="a")
    with pytest.raises(ValueError, match="missing \\['udhm_mask'\\]"):
        w.add_episode({k: v for k, v in good.items() if k != "udhm_mask"}, task="a")
    with pytest.raises(ValueError, match="fps must be a positive integer"):
        UdhmDatasetWriter(tmp_path / "y", "t/y", fps=29.97, features=FEATURES)
    with pytest.raises(FileExistsError):
        UdhmDatasetWriter(tmp_path / "x", "t/x", fps=30, features=FEATURES)


def test_stats_folding_in_blocks_matches_one_aggregate(tmp_path, monkeypatch):
    """Folding episode stats every few episodes (bounded memory) gives LeRobot's aggregate."""
    from lerobot.datasets.compute_stats import aggregate_stats

    from lerobot_unidextok.conversion import writer as writer_mod

    monkeypatch.setattr(writer_mod, "STATS_FOLD_EPISODES", 2)
    eps = _episodes()
    w = UdhmDatasetWriter(tmp_path / "f", "t/f", fps=30, features=FEATURES)
    per_episode = []
    for ep in eps:
        frames = {k: v for k, v in ep.items() if k != "task"}
        w.add_episode(frames, task=ep["task"])
    w.finalize()
    table = pq.read_table(tmp_path / "f/meta/episodes/chunk-000/file-000.parquet").to_pylist()
    for row in table:
        per_episode.append(
            {
                key: {
                    stat: np.array(row[f"stats/{key}/{stat}"])
                    for stat in (
                        "min",
                        "max",
                        "mean",
                        "std",
                        "count",
                        "q01",
                        "q10",
                        "q50",
                        "q90",
                        "q99",
                    )
                }
                for key in (
                    "observation.state",
                    "action",
                    "udhm_mask",
                    "timestamp",
                    "frame_index",
                    "episode_index",
                    "index",
                    "task_index",
                )
            }
        )
    expect = aggregate_stats(per_episode)
    got = json.loads((tmp_path / "f/meta/stats.json").read_text())
    for key in expect:
        for stat in expect[key]:
            np.testing.assert_allclose(
                np.array(got[key][stat], float),
                np.array(expect[key][stat], float),
                rtol=1e-6,
                atol=1e-9,
            )
