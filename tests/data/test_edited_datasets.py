"""Datasets edited by LeRobot's own `lerobot-edit-dataset` (real CLI, subprocess) keep working: the reader
falls back to a hash split with a warning or says why with --holdout=recorded, and the validator warns
with the reason instead of failing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.conversion.validate import validate_dataset
from lerobot_unidextok.data import SplitError, UdhmDatasetMeta, load_record, load_udhm_frames
from lerobot_unidextok.data.splits import hash_test_episodes

BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

    base = tmp_path_factory.mktemp("edit")
    raw = write_samples(base / "raw", sources=["lerobot"], episodes_per_source=6, frames_per_episode=20)["lerobot"]
    root = base / "g1_udhm"
    convert(ConvertOptions(source="lerobot", input=raw, root=root, repo_id="t/g1_udhm",
                           source_options=SAMPLE_SOURCE_OPTIONS["lerobot"], progress=False))  # fmt: skip
    return root


def _edit(*args: str) -> None:
    env = dict(os.environ, HF_HUB_OFFLINE="1")
    r = subprocess.run([str(BIN / "lerobot-edit-dataset"), *args], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]


def test_recorded_split_of_a_fresh_conversion(converted):
    settings = load_record(converted).to_dict()
    split = UdhmDatasetMeta(converted).split(holdout="recorded")
    assert split.origin == "conversion record" and list(split.test) == settings["test_episodes"]
    test = load_udhm_frames(converted, split="test", holdout="recorded")
    assert set(test.episode_index) == set(settings["test_episodes"])


def test_delete_episodes_then_train_eval_validate(converted, tmp_path, caplog):
    """Catches the old reader ("split 'test' not in meta/info.json splits ['train']") and validator
    (failed without a reason) on a dataset after `lerobot-edit-dataset delete_episodes`."""
    out = tmp_path / "cut"
    _edit("--repo_id", "t/g1_udhm", "--root", str(converted), "--new_repo_id", "t/g1_cut", "--new_root", str(out),
          "--operation.type", "delete_episodes", "--operation.episode_indices", "[0]")  # fmt: skip
    info = json.loads((out / "meta/info.json").read_text())
    assert info["splits"] == {"train": "0:5"} and info["total_episodes"] == 5
    with pytest.raises(SplitError, match=r"records no test episodes .*--holdout=hash .*--split=all"):
        load_udhm_frames(out, split="test", holdout="recorded")
    with caplog.at_level("WARNING"):
        test = load_udhm_frames(out, split="test")  # holdout="auto": hash fallback, said out loud
    assert "holding out" in caplog.text and "--holdout" in caplog.text
    assert set(test.episode_index) == set(hash_test_episodes(5))
    train = load_udhm_frames(out, split="train")
    assert not set(train.episode_index) & set(test.episode_index)
    assert len(load_udhm_frames(out, split="all")) == len(train) + len(test)
    report = validate_dataset(out, repo_id="t/g1_cut")
    assert report.ok, report.table()
    warned = {c.name: c.detail for c in report.checks if c.warning and not c.ok}
    assert "recorded test episodes" in warned and "--holdout=hash" in warned["recorded test episodes"]
    if not (out / "README.md").exists():
        assert "lerobot-edit-dataset drops it" in warned["dataset card README.md"]


def test_split_operation_gives_datasets_usable_whole(converted, tmp_path):
    base = tmp_path / "splits"
    _edit("--repo_id", "t/g1_udhm", "--root", str(converted), "--new_root", str(base),
          "--operation.type", "split", "--operation.splits", '{"train": [0, 1, 2, 3], "test": [4, 5]}')  # fmt: skip
    test = load_udhm_frames(base / "test", split="all")
    original = load_udhm_frames(converted, split="all")
    np.testing.assert_array_equal(test.states_rad, original.states_rad[original.episode_index >= 4])
    assert validate_dataset(base / "test", repo_id="t/g1_udhm_test").ok


def test_lerobot_train_episodes_flag_in_card(converted):
    """The card names the flag that keeps the recorded test episodes out of `lerobot-train`."""
    settings = load_record(converted).to_dict()
    train = [i for i in range(settings["num_episodes"]) if i not in settings["test_episodes"]]
    card = (converted / "README.md").read_text()
    assert f"--dataset.episodes='{json.dumps(train)}'" in card
