"""Small rules of the pipeline and the mapping, checked without a dataset: frame rates, split keys, options that
disagree, hands with and without actions."""

from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from l10_robot import HAND, write_l10_robot

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.mapping import EpisodeError, map_episode
from lerobot_unidextok.conversion.pipeline import ConvertOptions, _int_fps, convert, episode_keys
from lerobot_unidextok.conversion.registry import SetupError


@dataclass
class _Ref:
    root: str
    index: int

    def __str__(self) -> str:
        return f"{self.root}#episode_{self.index:06d}"


def test_a_source_frame_rate_must_be_an_integer():
    assert _int_fps(30.0004, "ep") == 30
    with pytest.raises(EpisodeError, match="30.5"):
        _int_fps(30.5, "ep")


def test_split_keys_keep_the_dataset_names_when_an_input_holds_several(tmp_path):
    one = [_Ref(str(tmp_path / "lab" / "g1"), i) for i in range(3)]
    assert episode_keys(one, tmp_path / "lab") == episode_keys(one, tmp_path / "lab" / "g1") == [
        "#episode_000000", "#episode_000001", "#episode_000002"]
    two = [_Ref(str(tmp_path / "lab" / "a"), 0), _Ref(str(tmp_path / "lab" / "b"), 0)]
    assert episode_keys(two, tmp_path / "lab") == ["a#episode_000000", "b#episode_000000"]


def test_fps_given_twice_must_agree():
    opts = ConvertOptions(source="let", input=".", root="out", fps=30, source_options={"fps": 25})
    with pytest.raises(SetupError, match="--fps=30 and source option fps=25 disagree"):
        opts.reader_options()


def test_actions_for_some_hands_only_are_refused():
    q = np.full((10, 6), 0.5)
    raw = RawEpisode("ep", 30.0, [HandStream("left", "inspire_rh56_unitree", q, q),
                                  HandStream("right", "inspire_rh56_unitree", q)])  # fmt: skip
    with pytest.raises(EpisodeError, match="some hands have actions and others do not"):
        map_episode(raw)


def test_a_hand_absent_in_one_episode_only_is_counted_in_the_record(tmp_path):
    """A two-hand export whose left hand is 0 in episode 0 only: that episode's left block is absent, the
    others keep it, and the record counts the absent hand-frames (40) and the episode."""
    from lerobot_unidextok.data import load_record

    names = [f"{side}_hand_joint_{i}" for side in ("left", "right") for i in range(10)]
    raw = write_l10_robot(tmp_path / "raw", episodes=3, keys=("state", "actions"), names=names, left_zero=True)
    for path in sorted((raw / "data").rglob("*.parquet")):  # give episodes 1 and 2 a moving left hand
        table = pq.read_table(path)
        episode = table.column("episode_index").to_numpy()
        for key in ("state", "actions"):
            v = np.stack(table.column(key).to_pylist())
            v[episode > 0, :10] = v[episode > 0, 10:]
            column = pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1), pa.float32()), v.shape[1])
            table = table.set_column(table.schema.get_field_index(key), key, column)
        pq.write_table(table, path)
    report = convert(ConvertOptions(source="lerobot", input=raw, root=tmp_path / "out", progress=False,
                                    source_options={"hands": {"left": f"{HAND}:left_hand_", "right": f"{HAND}:right_hand_"}}))  # fmt: skip
    record = load_record(tmp_path / "out")
    assert record.absent_hand_frames == 40 and record.zero_hand_episodes == 1
    assert 0 < report.seconds < 600  # a duration, not a clock reading
