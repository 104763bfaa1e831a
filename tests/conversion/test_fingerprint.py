"""Episode fingerprints (conversion/fingerprint.py): the same for the same episodes however they are stored,
none for an episode whose hands never move (it tells nothing about where it came from)."""

import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.conversion.fingerprint import episode_fingerprints, find_repeat


def _data(root):
    files = sorted((root / "data").rglob("*.parquet"))
    return files, pa.concat_tables(pq.read_table(f) for f in files)


def test_the_same_episodes_have_the_same_fingerprints_in_other_files_and_order(l10_robot, tmp_path):
    base = episode_fingerprints(l10_robot)
    assert sorted(base.values()) == list(range(5))  # 5 episodes, 5 distinct fingerprints
    moved = tmp_path / "rechunked"
    shutil.copytree(l10_robot, moved)
    files, table = _data(moved)
    for f in files:
        f.unlink()
    episodes = table.column("episode_index").to_numpy()
    later = np.isin(episodes, [3, 4])  # episodes 3 and 4 first, in a file of their own, then the rest
    pq.write_table(table.filter(pa.array(later)), moved / "data" / "chunk-000" / "file-000.parquet")
    pq.write_table(table.filter(pa.array(~later)), moved / "data" / "chunk-000" / "file-001.parquet")
    assert episode_fingerprints(moved) == base
    repeat = find_repeat([("a", l10_robot), ("b", moved)])
    assert repeat is not None and repeat.shared == [(e, e) for e in range(5)] and not repeat.same_folder


def test_an_episode_whose_hands_never_move_has_no_fingerprint(l10_robot, tmp_path):
    still = tmp_path / "still"
    shutil.copytree(l10_robot, still)
    files, table = _data(still)
    state = np.stack(table.column(OBS_STATE).to_pylist()).astype(np.float32)
    rows = table.column("episode_index").to_numpy() == 0
    state[rows] = state[rows][0]  # episode 0: its first pose held throughout
    column = pa.FixedSizeListArray.from_arrays(pa.array(state.ravel()), state.shape[1])
    table = table.set_column(table.column_names.index(OBS_STATE), OBS_STATE, column)
    for f in files:
        f.unlink()
    pq.write_table(table, files[0])
    prints = episode_fingerprints(still)
    assert sorted(prints.values()) == [1, 2, 3, 4]
    assert set(prints) < set(episode_fingerprints(l10_robot))
