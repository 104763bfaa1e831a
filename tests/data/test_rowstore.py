"""Reading converted datasets without materialising every frame: `iter_udhm_frames` (bounded pieces) and the
memory-mapped per-hand row store (`open_row_store`) hold exactly the rows `load_udhm_frames` gives."""

from __future__ import annotations

import json
import os
import tracemalloc

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.data import HandRowStore, build_row_store, iter_udhm_frames, load_udhm_frames, open_row_store
from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    """Two converted datasets: G1 whole robot (2 Inspire hands + arms) and LinkerHand bags (L10 / L20)."""
    raw_dir, out = tmp_path_factory.mktemp("raw"), tmp_path_factory.mktemp("conv")
    roots = []
    for source, episodes, frames in (("lerobot", 12, 200), ("linkerhand", 6, 40)):
        raw = write_samples(raw_dir, sources=[source], episodes_per_source=episodes, frames_per_episode=frames)
        root = out / source
        convert(ConvertOptions(source=source, input=raw[source], root=root, progress=False,
                               source_options=SAMPLE_SOURCE_OPTIONS.get(source, {})))  # fmt: skip
        roots.append(root)
    return roots


def _by_hand(states, masks, hands, episodes) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    return {h: (states[hands == h], masks[hands == h], episodes[hands == h]) for h in np.unique(hands)}


@pytest.mark.parametrize("split", ["train", "test", "all"])
def test_iter_udhm_frames_gives_the_rows_of_load_udhm_frames(datasets, split):
    root = datasets[0]
    whole = load_udhm_frames(root, split=split)
    pieces = list(iter_udhm_frames(root, split=split, batch_rows=97))  # many pieces, not aligned to episodes
    assert len(pieces) > 5
    for key in ("states_rad", "masks", "hands", "episode_index", "frame_index", "side", "actions_rad"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, key) for p in pieces]), getattr(whole, key), key)


def test_row_store_holds_each_hands_rows_in_order(datasets, tmp_path):
    store = open_row_store(datasets, "train", tmp_path / "store")
    frames = [load_udhm_frames(r, split="train") for r in datasets]
    expected = _by_hand(
        *(np.concatenate([getattr(f, k) for f in frames]) for k in ("states_rad", "masks", "hands", "episode_index"))
    )
    assert store.hand_names() == sorted(expected) and len(store) == sum(len(f) for f in frames)
    assert set(store.hand_names()) >= {"inspire_rh56_unitree", "linkerhand_l10", "linkerhand_l20"}
    for hand, (states, masks, episodes) in expected.items():
        rows = store.hands[hand]
        assert isinstance(rows.states_rad, np.memmap)  # on disk, not in memory
        np.testing.assert_array_equal(rows.states_rad, states)
        np.testing.assert_array_equal(rows.masks, masks)
        np.testing.assert_array_equal(rows.episode_index, episodes)
    # the test split holds the recorded test episodes only
    test = open_row_store(datasets[:1], "test", tmp_path / "test")
    test_eps = json.loads((datasets[0] / "meta/unidextok_conversion.json").read_text())["test_episodes"]
    assert sorted({int(e) for rows in test.hands.values() for e in rows.episode_index}) == sorted(test_eps)
    # without(): the zero-shot protocol drops a hand from training
    assert "linkerhand_l20" not in store.without("linkerhand_l20").hand_names()


def test_sample_rows_draws_uniformly_without_replacement(datasets, tmp_path):
    store = open_row_store(datasets, "all", tmp_path / "store")
    rows = store.sample_rows(500, seed=3)
    assert len(rows["states_rad"]) == 500 == len(rows["hands"]) == len(rows["masks"]) == len(rows["episode_index"])
    assert len(np.unique(rows["row_index"])) == 500  # no row twice
    for i in (0, 250, 499):  # each row is the store's row at its index
        hand = rows["hands"][i]
        local = rows["row_index"][i] - sum(n for h, n in store.hand_counts().items() if h < hand)
        np.testing.assert_array_equal(rows["states_rad"][i], store.hands[hand].states_rad[local])
    counts = store.hand_counts()
    for hand, n in counts.items():  # shares follow the hands' row counts (binomial, 4 sigma)
        p = n / len(store)
        assert abs(np.mean(rows["hands"] == hand) - p) < 4 * np.sqrt(p * (1 - p) / 500) + 1e-9, hand
    assert len(store.sample_rows(10**9, seed=0)["hands"]) == len(store)


def test_store_is_reused_until_a_dataset_changes(datasets, tmp_path):
    folder = tmp_path / "store"
    open_row_store(datasets, "train", folder)
    stamp = (folder / "index.json").stat().st_mtime_ns
    open_row_store(datasets, "train", folder)
    assert (folder / "index.json").stat().st_mtime_ns == stamp  # reused
    data_file = sorted((datasets[1] / "data").rglob("*.parquet"))[0]
    os.utime(data_file, ns=(data_file.stat().st_atime_ns, data_file.stat().st_mtime_ns + 10**9))  # "rewritten"
    open_row_store(datasets, "train", folder)
    assert (folder / "index.json").stat().st_mtime_ns != stamp  # rebuilt
    assert not list(tmp_path.glob(".store.*"))  # no temp or old folders left


def test_bad_rows_are_a_clear_error_and_leave_no_store(datasets, tmp_path):
    import shutil

    root = tmp_path / "broken"
    shutil.copytree(datasets[1], root)
    path = sorted((root / "data").rglob("*.parquet"))[0]
    table = pq.read_table(path)
    states = table.column("observation.state").combine_chunks()
    values = states.flatten().to_numpy().copy()
    values[5] = np.nan
    fixed = pa.FixedSizeListArray.from_arrays(pa.array(values), states.type.list_size)
    table = table.set_column(table.schema.get_field_index("observation.state"), "observation.state", fixed)
    pq.write_table(table, path)
    with pytest.raises(ValueError, match="NaN/inf UDHM angles"):
        build_row_store([root], "all", tmp_path / "store")
    assert not (tmp_path / "store").exists() and not list(tmp_path.glob(".store.tmp-*"))
    with pytest.raises(FileNotFoundError, match="row store"):
        HandRowStore(tmp_path / "store")


def test_building_a_store_holds_one_piece_in_memory_not_the_dataset(datasets, tmp_path):
    """Peak numpy memory (tracemalloc) while building from 64-frame pieces stays a small fraction of what
    load_udhm_frames allocates for the same dataset."""
    root = datasets[0]
    tracemalloc.start()
    frames = load_udhm_frames(root, split="all")
    _, whole = tracemalloc.get_traced_memory()
    del frames
    tracemalloc.stop()
    tracemalloc.start()
    build_row_store([root], "all", tmp_path / "store", batch_rows=64)
    _, streamed = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert streamed < 0.2 * whole, (streamed, whole)  # 2,400 frames, 64 per piece: about 0.1 measured
