"""Hand prints (conversion/fingerprint.py): the same for the same hands however they are stored, also within a
tolerance far below any real difference; none for a hand that never moves (it tells nothing about where it came
from); one hand of a two-hand recording converted alone is found beside a conversion of both."""

import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from g1_real import G1_HANDS

from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.conversion.fingerprint import TOLERANCE_RAD, find_repeat, hand_prints, same_hands
from lerobot_unidextok.conversion.mix import MixError, MixOptions, mix


def _data(root):
    files = sorted((root / "data").rglob("*.parquet"))
    return files, pa.concat_tables(pq.read_table(f) for f in files)


def _rewrite_state(root, change) -> None:
    """Rewrite the dataset's `observation.state` as `change(state, table)` gives it, in one data file."""
    files, table = _data(root)
    state = np.stack(table.column(OBS_STATE).to_pylist()).astype(np.float32)
    state = change(state, table).astype(np.float32)
    column = pa.FixedSizeListArray.from_arrays(pa.array(state.ravel()), state.shape[1])
    table = table.set_column(table.column_names.index(OBS_STATE), OBS_STATE, column)
    for f in files:
        f.unlink()
    pq.write_table(table, files[0])


def test_the_same_hands_have_the_same_prints_in_other_files_and_order(l10_robot, tmp_path):
    base = hand_prints(l10_robot)
    assert sorted(base.episodes.tolist()) == list(range(5)) and set(base.sides) == {"right"}  # one hand, 5 episodes
    assert [(a, b) for a, b, _, _ in same_hands(base, base)] == [(e, e) for e in range(5)]  # each only itself
    moved = tmp_path / "rechunked"
    shutil.copytree(l10_robot, moved)
    files, table = _data(moved)
    for f in files:
        f.unlink()
    episodes = table.column("episode_index").to_numpy()
    later = np.isin(episodes, [3, 4])  # episodes 3 and 4 first, in a file of their own, then the rest
    pq.write_table(table.filter(pa.array(later)), moved / "data" / "chunk-000" / "file-000.parquet")
    pq.write_table(table.filter(pa.array(~later)), moved / "data" / "chunk-000" / "file-001.parquet")
    again = hand_prints(moved)
    order = np.argsort(again.episodes)
    np.testing.assert_allclose(again.means_rad[order], base.means_rad[np.argsort(base.episodes)], rtol=0, atol=1e-12)
    repeat = find_repeat([("a", l10_robot), ("b", moved)])
    assert repeat is not None and repeat.shared == [(e, e) for e in range(5)] and not repeat.same_folder
    assert not repeat.partial_sides and "hold the same episodes (5 of 5 by content" in repeat.describe()


def test_a_near_copy_is_found_and_a_real_difference_is_not(l10_robot, tmp_path):
    """+1e-6 rad on every value (noise a rounded hash would not survive: with ~900 values per episode some sit
    next to a rounding boundary) is the same hand; a change of 10x the tolerance in one joint of one stretch is
    another."""
    near = tmp_path / "near"
    shutil.copytree(l10_robot, near)
    _rewrite_state(near, lambda s, _: s + np.float32(1e-6))
    repeat = find_repeat([("a", l10_robot), ("b", near)])
    assert repeat is not None and repeat.shared == [(e, e) for e in range(5)]
    other = tmp_path / "other"
    shutil.copytree(l10_robot, other)

    def nudge(state, table):  # the first frames of each episode: one joint moved by 10x the tolerance
        state[table.column("frame_index").to_numpy() < 5, 0] += 10 * TOLERANCE_RAD
        return state

    _rewrite_state(other, nudge)
    assert find_repeat([("a", l10_robot), ("b", other)]) is None


def test_a_hand_that_never_moves_has_no_print(l10_robot, tmp_path):
    still = tmp_path / "still"
    shutil.copytree(l10_robot, still)

    def hold(state, table):  # episode 0: its first pose held throughout
        rows = table.column("episode_index").to_numpy() == 0
        state[rows] = state[rows][0]
        return state

    _rewrite_state(still, hold)
    prints = hand_prints(still)
    assert sorted(prints.episodes.tolist()) == [1, 2, 3, 4]
    assert [(a, b) for a, b, _, _ in same_hands(hand_prints(l10_robot), prints)] == [(e, e) for e in (1, 2, 3, 4)]


def test_one_hand_of_a_two_hand_recording_is_found_beside_a_conversion_of_both(real_data_dir, tmp_path):
    """The real G1 + Inspire recording converted with both hands and with its right hand only: the right hands are
    the same, the episodes are not, and the repeat names the hand."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    both, right = tmp_path / "g1_both", tmp_path / "g1_right"
    for root, hands in ((both, G1_HANDS), (right, {"right": "inspire_rh56_unitree:kRightHand"})):
        convert(ConvertOptions(source="lerobot", input=real_data_dir / "g1-inspire", root=root, keep="hands",
                               source_options={"hands": hands}, max_episodes=2, progress=False))  # fmt: skip
    assert set(hand_prints(right).sides) == {"right"} and set(hand_prints(both).sides) == {"left", "right"}
    repeat = find_repeat([(str(both), both), (str(right), right)])
    assert repeat is not None and repeat.shared == [(0, 0), (1, 1)] and repeat.partial_sides == ["right"]
    assert repeat.describe().startswith(f"inputs {both} and {right} hold the same right hand of episodes (2 of 2")
    out = tmp_path / "mix"  # the mix refuses them as it refuses a copy, and writes nothing
    with pytest.raises(MixError, match=r"hold the same right hand of episodes .* --allow_repeats=true"):
        mix(MixOptions(inputs=[str(both), str(right)], root=str(out), progress=False))
    assert not out.exists()
