"""data.record and data.meta: the conversion record read and written in one place, version 1 records translated,
a converted dataset's hands, layouts and test episodes read once."""

import json
import shutil

import pytest
from robot_udhm import ARM_NAMES, HAND_NAMES, INSPIRE, NATIVE_NAMES, STATE_NAMES

from lerobot_unidextok.constants import ACTION, CONVERSION_PATH, OBS_STATE
from lerobot_unidextok.data import (
    ConversionRecord,
    EpisodeRecord,
    RecordError,
    UdhmDatasetMeta,
    load_record,
    write_record,
)
from lerobot_unidextok.data.record import RECORD_VERSION
from lerobot_unidextok.layout import NativeLayout


def test_a_version_1_record_is_read_with_the_converted_names_from_info_json(g1_like):
    """The fixture's record is version 1 (native_layout "names" = the robot's 26 columns): the typed layout has
    the 58 converted names from meta/info.json and the 26 native ones."""
    raw = json.loads((g1_like["root"] / CONVERSION_PATH).read_text())
    assert "record_version" not in raw and raw["native_layout"][OBS_STATE]["names"] == NATIVE_NAMES
    record = load_record(g1_like["root"])
    layout = record.native_layouts[OBS_STATE]
    assert layout.names == STATE_NAMES and layout.native_names == NATIVE_NAMES and layout.mapping == "semantic"
    assert [h["columns"] for h in layout.hands] == [HAND_NAMES["left"], HAND_NAMES["right"]]
    assert record.episode(1).origin == {"source_episode": 1}  # version 1 kept source fields flat
    assert record.test_episodes == [2] and record.num_episodes == 3


def test_write_then_load_gives_the_same_record_and_layouts_round_trip(g1_like, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(g1_like["root"], root)
    record = load_record(root)
    record.episodes[0].native_layouts = {ACTION: record.native_layouts[ACTION]}  # an episode with its own layout
    write_record(root, record)
    raw = json.loads((root / CONVERSION_PATH).read_text())
    assert raw["record_version"] == RECORD_VERSION and raw["native_layout"][OBS_STATE]["names"] == STATE_NAMES
    assert raw["native_layout"][OBS_STATE]["native_names"] == NATIVE_NAMES  # one schema: NativeLayout.to_dict()
    again = load_record(root)
    assert again == record
    assert again.native_layout(ACTION, episode=0) == record.native_layouts[ACTION]
    layout = again.native_layouts[OBS_STATE]
    assert NativeLayout.from_dict(layout.to_dict()) == layout
    with pytest.raises(ValueError, match=r"unknown \['native'\], missing \['native_names'\]"):
        NativeLayout.from_dict({"names": STATE_NAMES, "native": NATIVE_NAMES, "hands": []})


def test_damaged_and_newer_records_are_clear_errors(g1_like, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(g1_like["root"], root)
    path = root / CONVERSION_PATH
    path.write_text("{not json")
    with pytest.raises(RecordError, match="unidextok_conversion.json is not valid JSON"):
        load_record(root)
    path.write_text(json.dumps({"source": "x", "record_version": RECORD_VERSION + 1}))
    with pytest.raises(RecordError, match="newer than this lerobot_unidextok reads.*upgrade"):
        load_record(root)
    path.write_text(json.dumps({"source": "x", "record_version": 2, "episodes": [{"episode_index": 0, "split": "dev"}]}))
    with pytest.raises(RecordError, match=r"episode splits must be \('train', 'test'\), got \['dev'\]"):
        load_record(root)
    path.unlink()
    assert load_record(root) is None


def test_meta_reads_hands_from_the_record_without_the_data_files(g1_like, tmp_path):
    """With a record that describes the dataset, the hand types come from it (no parquet is read); without one
    they come from the hand_type column."""
    root = tmp_path / "ds"
    shutil.copytree(g1_like["root"], root)
    record = load_record(root)
    for e in record.episodes:
        e.hand_type = f"{INSPIRE},{INSPIRE}"
    write_record(root, record)
    shutil.rmtree(root / "data")
    meta = UdhmDatasetMeta(root)
    assert not meta.record_problem and meta.block_hands() == [INSPIRE, INSPIRE]
    assert meta.hand_layout().passthrough_names == ARM_NAMES
    assert list(meta.split("recorded").episodes("test")) == [2]
    (root / CONVERSION_PATH).unlink()
    with pytest.raises(FileNotFoundError, match="no data parquet"):
        UdhmDatasetMeta(root).block_hands()


def test_a_record_of_another_dataset_is_not_its_split(g1_like, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(g1_like["root"], root)
    record = load_record(root)
    write_record(root, ConversionRecord(**{**record.__dict__, "num_episodes": 5}))
    meta = UdhmDatasetMeta(root)
    assert "describes 5 episodes but the dataset has 3" in meta.record_problem
    split = meta.split("auto")
    assert split.origin == "episode hash"
    assert EpisodeRecord(0, "a", "train", 1, origin={"fps": 3}).to_dict()["fps"] == 3  # origin beside the fields
