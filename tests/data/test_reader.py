"""load_udhm_frames on a dataset written by LeRobot's own per-frame writer."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_unidextok.constants import UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.data import load_udhm_frames, split_episode_range

NAMES = [f"{s}_{j}" for s in ("right", "left") for j in UDHM_JOINT_NAMES]


@pytest.fixture(scope="module")
def lerobot_written(tmp_path_factory):
    from lerobot.datasets import LeRobotDataset

    root = tmp_path_factory.mktemp("ds") / "reader_ds"
    features = {
        "observation.state": {"dtype": "float32", "shape": (44,), "names": NAMES},
        "action": {"dtype": "float32", "shape": (44,), "names": NAMES},
        "hand_type": {"dtype": "string", "shape": (1,), "names": None},
        "udhm_mask": {"dtype": "bool", "shape": (44,), "names": NAMES},
    }
    ds = LeRobotDataset.create("test/reader", fps=25, features=features, root=root, use_videos=False)
    rng = np.random.default_rng(0)
    mask = np.ones(44, bool)
    mask[[1, 3, 30]] = False
    states = []
    for ep, (length, ht) in enumerate([(7, "inspire_rh56,inspire_rh56"), (5, "human,inspire_rh56"), (6, "a,b")]):
        s = rng.uniform(-1, 1, size=(length, 44)).astype(np.float32)
        states.append(s)
        for t in range(length):
            ds.add_frame(
                {
                    "observation.state": s[t],
                    "action": -s[t],
                    "hand_type": ht,
                    "udhm_mask": mask,
                    "task": f"t{ep}",
                }
            )
        ds.save_episode()
    ds.finalize()
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["splits"] = {"train": "0:2", "test": "2:3"}
    info_path.write_text(json.dumps(info))
    return root, states, mask


def test_rows_are_frame_major_per_hand(lerobot_written):
    root, states, mask = lerobot_written
    fr = load_udhm_frames(root)
    all_s = np.concatenate(states)  # (18, 44)
    assert len(fr) == 2 * 18
    np.testing.assert_array_equal(fr.states_rad, all_s.reshape(-1, UDHM_DIM))
    np.testing.assert_array_equal(fr.actions_rad, -all_s.reshape(-1, UDHM_DIM))
    assert fr.states_rad.dtype == np.float32 and fr.masks.dtype == np.bool_
    np.testing.assert_array_equal(fr.masks, np.tile(mask.reshape(2, UDHM_DIM), (18, 1)))
    assert list(fr.side[:4]) == ["right", "left", "right", "left"]
    assert list(fr.hands[14:16]) == ["human", "inspire_rh56"]  # episode 1, frame 0
    assert list(fr.episode_index[:2]) == [0, 0] and fr.episode_index[-1] == 2
    assert list(fr.frame_index[12:16]) == [6, 6, 0, 0]
    assert fr.fps == 25


def test_split_filters_by_episode_range(lerobot_written):
    root, states, _ = lerobot_written
    train = load_udhm_frames(root, split="train")
    test = load_udhm_frames(root, split="test")
    assert set(train.episode_index) == {0, 1} and set(test.episode_index) == {2}
    assert len(train) == 2 * 12 and len(test) == 2 * 6
    np.testing.assert_array_equal(test.states_rad, states[2].reshape(-1, UDHM_DIM))
    assert set(test.hands) == {"a", "b"}
    sel = train.select(train.hands == "human")
    assert len(sel) == 5 and set(sel.side) == {"right"}


def test_bad_inputs_raise_clear_errors(lerobot_written, tmp_path):
    root, _, _ = lerobot_written
    with pytest.raises(ValueError, match="split must be one of"):
        load_udhm_frames(root, split="val")
    with pytest.raises(FileNotFoundError, match="meta/info.json missing"):
        load_udhm_frames(tmp_path)
    with pytest.raises(ValueError, match="not in meta/info.json splits"):
        split_episode_range({"splits": {"train": "0:3"}}, "test")


def test_absent_hand_rows_dropped_by_default(tmp_path):
    from lerobot.datasets import LeRobotDataset

    features = {
        "observation.state": {"dtype": "float32", "shape": (44,), "names": NAMES},
        "hand_type": {"dtype": "string", "shape": (1,), "names": None},
        "udhm_mask": {"dtype": "bool", "shape": (44,), "names": NAMES},
    }
    ds = LeRobotDataset.create("test/absent", fps=30, features=features, root=tmp_path / "d", use_videos=False)
    mask = np.zeros(44, bool)
    mask[:22] = True  # left hand absent
    for t in range(4):
        ds.add_frame(
            {
                "observation.state": np.full(44, t, np.float32) * mask,
                "hand_type": "human,human",
                "udhm_mask": mask,
                "task": "",
            }
        )
    ds.save_episode()
    ds.finalize()
    kept = load_udhm_frames(tmp_path / "d")
    assert len(kept) == 4 and set(kept.side) == {"right"} and kept.actions_rad is None
    assert len(load_udhm_frames(tmp_path / "d", drop_absent=False)) == 8


def test_an_empty_split_names_the_flag_and_the_argument(tmp_path):
    """One converted episode is a training episode: asking for the test split said "use split='all'", which is
    no flag of unidextok-eval; the message now names both spellings."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.data import SplitError
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["linkerhand"], episodes_per_source=1, frames_per_episode=20)
    convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=tmp_path / "out", progress=False))
    with pytest.raises(SplitError, match=r"has no test episodes .*`--split=all` on the command line, split='all' in"):
        load_udhm_frames(tmp_path / "out", split="test")
    assert len(load_udhm_frames(tmp_path / "out", split="all")) > 0
