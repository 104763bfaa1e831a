"""End-to-end conversion of synthetic sample sources and of a deliberately broken test source."""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.pipeline import (
    ConversionError,
    ConvertOptions,
    convert,
    episode_key,
    merge_shards,
)
from lerobot_unidextok.conversion.registry import (
    get_source,
    register_source,
    unregister_source,
)
from lerobot_unidextok.conversion.validate import validate_dataset
from lerobot_unidextok.data import UdhmDatasetMeta, load_record, load_udhm_frames
from lerobot_unidextok.data.splits import split_order


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    from lerobot_unidextok.samples import write_samples

    return write_samples(
        tmp_path_factory.mktemp("raw"),
        sources=["linkerhand", "dexycb"],
        episodes_per_source=6,
        frames_per_episode=40,
    )


@pytest.fixture(scope="module")
def linker(samples, tmp_path_factory):
    root = tmp_path_factory.mktemp("out") / "linker"
    report = convert(
        ConvertOptions(
            source="linkerhand",
            input=samples["linkerhand"],
            root=root,
            repo_id="t/linker",
            progress=False,
        )
    )
    return root, report


def _data(root):
    return pq.read_table(sorted((root / "data").rglob("*.parquet"))).replace_schema_metadata(None)


# ---------------------------------------------------------------------------------------------
# robot source
# ---------------------------------------------------------------------------------------------
def test_progress_bar_off_a_terminal_writes_the_start_and_the_end(samples, tmp_path, capsys, monkeypatch):
    """Conversion wrote 92 bar updates into a log in 2 s (one per episode). Off a terminal the bar refreshes
    every 30 s, so a short run writes its start and its end, the counter with the frame count."""
    monkeypatch.delenv("TQDM_MININTERVAL", raising=False)
    t0 = time.perf_counter()
    report = convert(ConvertOptions(source="linkerhand", input=samples["linkerhand"], root=tmp_path / "ds",
                                    repo_id="t/bar", progress=True))  # fmt: skip
    elapsed = time.perf_counter() - t0
    refreshes = re.findall(r"(\d+)/6 \[([^\]]*)\]", capsys.readouterr().err)  # stderr is captured: not a tty
    assert 2 <= len(refreshes) <= 2 + elapsed // 30, (elapsed, refreshes)  # start, end, one per 30 s between
    assert refreshes[0][0] == "0" and refreshes[-1][0] == "6"
    assert f"frames={report.num_frames}" in refreshes[-1][1]  # the postfix of the last episode, with its count


def test_robot_source_contract_and_round_trip(samples, linker):
    """Episodes keep the source order (episode i = i-th listed file) and the test split is recorded, not
    reordered. Catches the old pipeline, which wrote train episodes first and then the test ones."""
    from lerobot.datasets import LeRobotDataset

    root, report = linker
    assert (report.num_episodes, report.num_train, report.num_test) == (6, 5, 1)  # round(0.2 * 6) = 1
    ds = LeRobotDataset("t/linker", root=root)
    assert ds.num_episodes == 6 and ds.fps == 30
    names = ds.meta.features["observation.state"]["names"]
    sides = [names[0].split("_")[0], names[UDHM_DIM].split("_")[0]]
    assert sorted(sides) == ["left", "right"] and names[6] == f"{sides[0]}_index_mcp_flex"
    assert ds.meta.features["action"]["dtype"] == "float32"
    assert ds.meta.info.splits == {"train": "0:6"}  # LeRobot's own convention, valid for its tools
    assert validate_dataset(root).ok

    src = get_source("linkerhand")()
    refs = src.list_episodes(samples["linkerhand"])
    settings = load_record(root).to_dict()
    assert settings["source"] == "linkerhand" and settings["synthetic"] is True
    keys = [str(r).replace(str(samples["linkerhand"]) + "/", "") for r in refs]
    _, test_pos = split_order(keys, 0.2)
    assert settings["test_episodes"] == test_pos  # the sha1 rule over source keys, as a list of indices
    assert [r["source"] for r in settings["episodes"]] == keys  # source order, each source recorded
    assert [r["split"] for r in settings["episodes"]] == ["test" if i in test_pos else "train" for i in range(6)]
    frames = load_udhm_frames(root)
    for ep_index, ref in enumerate(refs):  # episode i is the i-th source file, value for value
        raw = src.read_episode(ref)
        state = frames.states_rad[frames.episode_index == ep_index].reshape(-1, 2, UDHM_DIM)
        by_side = {h.side: h for h in raw.hands}
        expect = np.stack([hands.get(by_side[s].hand).to_udhm(by_side[s].state_native, side=s) for s in sides], axis=1)
        np.testing.assert_allclose(state, expect, atol=1e-6)
        assert list(frames.hands[frames.episode_index == ep_index][:2]) == [by_side[s].hand for s in sides]
        spec = hands.get(by_side[sides[0]].hand)
        native = np.asarray(spec.from_udhm(state[:, 0].astype(np.float64), side=sides[0]))
        active = [i for i, j in enumerate(spec.joints) if j.slot is not None]
        np.testing.assert_allclose(native[:, active], by_side[sides[0]].state_native[:, active], atol=1e-3)  # SDK units
    test = load_udhm_frames(root, split="test")
    assert set(test.episode_index) == set(test_pos)
    card = (root / "README.md").read_text()
    assert "linkerhand" in card and "SYNTHETIC" in card and "license" in card.lower() and "linkerhand_l" in card
    assert "--dataset.episodes" in card  # how to keep the test episodes out of lerobot-train


def test_split_deterministic_worker_and_folder_independent(samples, linker, tmp_path):
    """The same input moved to another folder and converted with 2 workers gives the same data and split.

    Catches: hashing the absolute episode path (`episode_key` keeping the input folder), which moves the
    test set whenever the input folder moves."""
    root, _ = linker
    moved = tmp_path / "elsewhere" / "copy_of_linkerhand"
    shutil.copytree(samples["linkerhand"], moved)
    again = tmp_path / "again"
    convert(ConvertOptions(source="linkerhand", input=moved, root=again, repo_id="t/linker", num_workers=2,
                           progress=False))  # fmt: skip
    assert _data(root).equals(_data(again))
    assert json.loads((again / "meta/info.json").read_text())["splits"] == {"train": "0:6"}
    first, second = load_record(root).to_dict(), load_record(again).to_dict()
    assert second["test_episodes"] == first["test_episodes"]
    keys = [r["source"] for r in first["episodes"]]
    assert keys == [r["source"] for r in second["episodes"]]  # keys relative to --input, not absolute paths
    assert not any(str(samples["linkerhand"]) in k or str(moved) in k for k in keys), keys


def test_episode_key_drops_the_input_folder(tmp_path):
    """Catches: a key that keeps the absolute path (the split would change when the input folder moves)."""
    for folder in (tmp_path / "a", tmp_path / "b" / "c"):
        assert episode_key(folder / "run1" / "episode_3.bag", folder) == str(Path("run1") / "episode_3.bag")
    assert episode_key("/data/x/ep.h5", "/data/x/") == "ep.h5"


def test_split_golden_keys_smallest_hashes():
    """A golden split for fixed keys: the test set is the round(0.2 * N) keys with the SMALLEST sha1.

    Recipe of the golden list: sorted(keys, key=lambda k: hashlib.sha1(k.encode()).hexdigest())[:4] for the
    20 keys below. Catches: the largest hashes instead of the smallest, another hash, rounding down/up,
    or returning positions in hash order instead of input order."""
    keys = [f"episode_{i:03d}.bag" for i in range(20)]
    train, test = split_order(keys, 0.2)
    assert test == [1, 10, 14, 18]
    assert train == [i for i in range(20) if i not in (1, 10, 14, 18)]
    assert split_order(keys, 0.1)[1] == [14, 18]  # the 2 smallest hashes of the same ranking
    assert split_order(keys, 0.12)[1] == [14, 18]  # round(2.4) = 2
    assert split_order(keys, 0.13)[1] == [10, 14, 18]  # round(2.6) = 3
    assert split_order(keys[:1], 0.5) == ([0], [])  # a single episode is never held out
    assert split_order(keys, 0.0) == (list(range(20)), [])
    # order-independent: the same keys shuffled select the same episodes
    shuffled = keys[::-1]
    _, test_rev = split_order(shuffled, 0.2)
    assert sorted(shuffled[i] for i in test_rev) == sorted(keys[i] for i in test)


def test_existing_target_refused_then_overwritten(samples, linker, tmp_path):
    target = tmp_path / "t"
    target.mkdir()
    (target / "keep.txt").write_text("x")
    opts = {
        "source": "linkerhand",
        "input": samples["linkerhand"],
        "root": target,
        "progress": False,
        "max_episodes": 2,
    }
    # a folder this tool did not write: refused, even with --overwrite=true, and never touched
    for overwrite in (False, True):
        with pytest.raises(FileExistsError, match="holds other files, not a dataset written by unidextok-convert: "
                                                  "nothing is replaced there"):  # fmt: skip
            convert(ConvertOptions(**opts, overwrite=overwrite))
    assert [p.name for p in target.iterdir()] == ["keep.txt"]
    # a converted dataset: the error recommends the flag, and the flag replaces it
    target = tmp_path / "d"
    convert(ConvertOptions(**{**opts, "root": target, "max_episodes": 1}))
    with pytest.raises(FileExistsError, match="already holds a dataset written by unidextok-convert: pass --overwrite=true"):
        convert(ConvertOptions(**{**opts, "root": target}))
    convert(ConvertOptions(**{**opts, "root": target}, overwrite=True))
    assert json.loads((target / "meta/info.json").read_text())["total_episodes"] == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "t"]  # no temp or backup folders left


def test_a_root_that_is_holds_or_sits_inside_the_input_is_refused(samples, tmp_path):
    """The default root of `--repo_id=lab/g1 --input=$HF_LEROBOT_HOME/lab/g1` is the input itself: refused,
    with or without --overwrite, and the input is untouched."""
    import shutil

    raw = tmp_path / "raw"
    shutil.copytree(samples["linkerhand"], raw)
    before = sorted(str(p.relative_to(raw)) for p in raw.rglob("*"))
    for root in (raw, raw / "sub" / "out", tmp_path):
        for overwrite in (False, True):
            with pytest.raises(FileExistsError, match="is, holds or sits inside the input"):
                convert(ConvertOptions(source="linkerhand", input=raw, root=root, overwrite=overwrite,
                                       progress=False))  # fmt: skip
    assert sorted(str(p.relative_to(raw)) for p in raw.rglob("*")) == before


def test_shards_merge_equals_single_run(samples, linker, tmp_path):
    from lerobot.datasets import LeRobotDataset

    root, _ = linker
    shards = []
    for k in range(2):
        shard = tmp_path / f"shard{k}"
        convert(
            ConvertOptions(
                source="linkerhand",
                input=samples["linkerhand"],
                root=shard,
                progress=False,
                shard_index=k,
                num_shards=2,
            )
        )
        shards.append(shard)
    merged = merge_shards(shards, tmp_path / "merged", repo_id="t/merged")
    info = json.loads((merged / "meta/info.json").read_text())
    assert info["splits"] == {"train": "0:6"} and info["total_episodes"] == 6
    single_settings, merged_settings = load_record(root).to_dict(), load_record(merged).to_dict()
    assert merged_settings["test_episodes"] == single_settings["test_episodes"]
    assert [r["source"] for r in merged_settings["episodes"]] == [r["source"] for r in single_settings["episodes"]]
    single, both = _data(root), _data(merged)
    for col in (
        "observation.state",
        "action",
        "udhm_mask",
        "hand_type",
        "episode_index",
        "frame_index",
        "index",
    ):
        assert single.column(col).to_pylist() == both.column(col).to_pylist(), (
            col
        )  # aggregate writes list<>, not fixed_size_list<>
    assert LeRobotDataset("t/merged", root=merged).num_frames == single.num_rows
    assert validate_dataset(merged).ok


# ---------------------------------------------------------------------------------------------
# human source
# ---------------------------------------------------------------------------------------------
def test_human_source_left_or_right_sequences(samples, tmp_path, monkeypatch):
    root = tmp_path / "dexycb"
    cls = get_source("dexycb")
    monkeypatch.setattr(cls, "sides", None)  # without a declared layout the first episode's side wins
    with pytest.raises(ConversionError, match="--sides=right,left"):
        convert(ConvertOptions(source="dexycb", input=samples["dexycb"], root=root, progress=False))
    assert not root.exists()
    report = convert(
        ConvertOptions(
            source="dexycb",
            input=samples["dexycb"],
            root=root,
            progress=False,
            sides=("right", "left"),
        )
    )
    assert report.hands == ["human"]
    frames = load_udhm_frames(root)
    assert set(frames.hands) == {"human"} and frames.masks.all()  # absent hands dropped, human = 22 DoF
    assert np.isfinite(frames.states_rad).all() and np.abs(frames.states_rad).max() < np.pi
    every = load_udhm_frames(root, drop_absent=False)
    assert len(every) > len(frames)  # each sequence has one hand: the other block is masked
    assert validate_dataset(root).ok
    assert load_record(root).to_dict()["synthetic"] is True  # npz marker unread by the reader: the labels file says so
    assert "SYNTHETIC" in (root / "README.md").read_text()


def test_signature_difference_names_what_differs_and_hints_sides_only_for_sides():
    """The mixed-episode error lists each difference; the `--sides` hint appears only when the hand sides
    differ. Catches the hint keyed on another part of the signature (then every such error, e.g. an
    episode without actions, wrongly suggests --sides)."""
    from types import SimpleNamespace

    from lerobot_unidextok.conversion.pipeline import _signature_difference

    first = (("right",), True, (), (), ())
    no_actions = _signature_difference(SimpleNamespace(signature=(("right",), False, (), (), ())), 30, first, 30)
    assert "actions False vs True" in no_actions and "--sides" not in no_actions
    other_fps = _signature_difference(SimpleNamespace(signature=first), 25, first, 30)
    assert "fps 25 vs 30" in other_fps and "--sides" not in other_fps
    left = _signature_difference(SimpleNamespace(signature=(("left",), True, (), (), ())), 30, first, 30)
    assert "hand sides ('left',) vs ('right',)" in left and "--sides=right,left" in left


# ---------------------------------------------------------------------------------------------
# bad episodes
# ---------------------------------------------------------------------------------------------
@register_source("_broken_test")
class BrokenSource:
    license = "test"
    description = "episodes with known defects"

    def list_episodes(self, input_path):
        return [
            "good_a",
            "truncated",
            "nan",
            "out_of_range",
            "unknown_hand",
            "good_b",
            "interrupt",
        ]

    def read_episode(self, ref):
        spec = hands.get("linkerhand_l10")
        rng = np.random.default_rng(len(ref))
        state = rng.uniform(10, 240, size=(20, spec.num_native))
        hand = "linkerhand_l10"
        if ref == "truncated":
            raise OSError("file truncated at byte 120")
        if ref == "nan":
            state[4, 2] = np.nan
        if ref == "out_of_range":
            state[3, 1] = 900.0
        if ref == "unknown_hand":
            hand = "robo_x"
        if ref == "interrupt" and getattr(self, "interrupt", False):
            raise KeyboardInterrupt
        return RawEpisode(
            source_file=f"/data/{ref}.json",
            fps=30,
            hands=[HandStream("right", hand, state)],
            task="t",
        )


@pytest.fixture
def broken_input(tmp_path):
    (tmp_path / "in").mkdir()
    return tmp_path / "in"


def test_on_error_raise_stops_and_writes_nothing(broken_input, tmp_path):
    target = tmp_path / "out"
    with pytest.raises(ConversionError) as err:
        convert(
            ConvertOptions(
                source="_broken_test",
                input=broken_input,
                root=target,
                progress=False,
                test_fraction=0.0,
            )
        )
    assert (
        "truncated" in str(err.value)
        and "file truncated at byte 120" in str(err.value)
        and "--on_error=skip" in str(err.value)
    )
    assert not target.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_on_error_skip_reports_each_file_and_reason(broken_input, tmp_path):
    report = convert(
        ConvertOptions(
            source="_broken_test",
            input=broken_input,
            root=tmp_path / "out",
            progress=False,
            on_error="skip",
            test_fraction=0.0,
        )
    )
    assert report.num_episodes == 3  # good_a, good_b, interrupt (not interrupting here)
    reasons = {f.source_file: f.reason for f in report.failures}
    assert set(reasons) == {
        "truncated",
        "/data/nan.json",
        "/data/out_of_range.json",
        "/data/unknown_hand.json",
    }
    assert "OSError" in reasons["truncated"]
    assert "NaN" in reasons["/data/nan.json"] and "[4]" in reasons["/data/nan.json"]
    assert "range" in reasons["/data/out_of_range.json"]
    assert "robo_x" in reasons["/data/unknown_hand.json"]
    frames = load_udhm_frames(tmp_path / "out")
    assert np.isfinite(frames.states_rad).all() and len(frames) == 60
    assert load_record(tmp_path / "out").to_dict()["skipped_episodes"] == 4
    assert "Skipped episodes (4)" in (tmp_path / "out" / "README.md").read_text()


def test_interrupt_leaves_no_partial_dataset(broken_input, tmp_path, monkeypatch):
    monkeypatch.setattr(BrokenSource, "interrupt", True, raising=False)
    target = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        convert(
            ConvertOptions(
                source="_broken_test",
                input=broken_input,
                root=target,
                progress=False,
                on_error="skip",
                test_fraction=0.0,
            )
        )
    assert not target.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_options_validation():
    with pytest.raises(ValueError, match="mapping must be one of"):
        ConvertOptions(source="x", input=".", root=".", mapping="nearest")
    with pytest.raises(ValueError, match="on_error"):
        ConvertOptions(source="x", input=".", root=".", on_error="ignore")
    with pytest.raises(ValueError, match="sides must be distinct"):
        ConvertOptions(source="x", input=".", root=".", sides=("right", "right"))
    with pytest.raises(ValueError, match="unknown source 'nope'"):
        get_source("nope")


def teardown_module():
    unregister_source("_broken_test")


# ---------------------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------------------
def test_real_g1_inspire_end_to_end(real_data_dir, tmp_path):
    """Real Unitree G1 + two Inspire hands (LeRobot v2.1, hands normalised 0-1) -> UDHM v3.0 that keeps the
    whole robot: the 14 arm columns bit-identical before 2 x 22 UDHM columns, source episode order, source
    episode recorded. Catches the old converter, which dropped the arms and reordered episodes."""
    import pyarrow.parquet as pq
    from lerobot.datasets import LeRobotDataset

    hands_opt = {
        "left": "inspire_rh56_unitree:kLeftHand",
        "right": "inspire_rh56_unitree:kRightHand",
    }
    src_root = real_data_dir / "g1-inspire"
    root = tmp_path / "g1"
    report = convert(
        ConvertOptions(
            source="lerobot",
            input=src_root,
            root=root,
            repo_id="t/g1",
            source_options={"hands": hands_opt},
            progress=False,
        )
    )
    assert (report.num_episodes, report.num_frames, report.num_train, report.num_test) == (10, 4236, 8, 2)
    ds = LeRobotDataset("t/g1", root=root)
    source_info = json.loads((src_root / "meta/info.json").read_text())
    source_names = source_info["features"]["observation.state"]["names"][0]  # nested [[...]] in the source
    arms = source_names[:14]
    for key in ("observation.state", "action"):
        names = ds.meta.features[key]["names"]
        assert ds.meta.features[key]["shape"] == (58,) and names[:14] == arms
        assert names[14:] == [f"{s}_{j}" for s in ("left", "right") for j in UDHM_JOINT_NAMES]
    assert ds[0]["task"] == "Pick up the yellow bottle on the table."
    assert validate_dataset(root).ok
    assert ds.meta.robot_type == source_info["robot_type"] == "Unitree_G1_Inspire"  # the robot, not "udhm"
    settings = load_record(root).to_dict()
    assert settings["synthetic"] is False and "SYNTHETIC" not in (root / "README.md").read_text()
    assert [r["source_episode_index"] for r in settings["episodes"]] == list(range(10))  # source order, recorded
    assert len(settings["test_episodes"]) == 2
    layout = settings["native_layout"]["observation.state"]
    assert layout["native_names"] == source_names and [h["columns"][0] for h in layout["hands"]] == [
        "kLeftHandPinky",
        "kRightHandPinky",
    ]

    converted = pq.read_table(sorted((root / "data").rglob("*.parquet")))
    episode = converted["episode_index"].to_numpy()
    spec = hands.get("inspire_rh56_unitree")
    for ep_index in range(10):
        source = pq.read_table(src_root / f"data/chunk-000/episode_{ep_index:06d}.parquet")
        for key in ("observation.state", "action"):
            raw = np.stack(source[key].to_numpy(zero_copy_only=False))  # (T, 26) float32
            out = np.stack(converted[key].to_numpy(zero_copy_only=False)[episode == ep_index])  # (T, 58)
            assert out.dtype == raw.dtype == np.float32
            np.testing.assert_array_equal(out[:, :14].view(np.uint32), raw[:, :14].view(np.uint32))  # bit-identical
            for b, (side, cols) in enumerate((("left", slice(14, 20)), ("right", slice(20, 26)))):
                expect = spec.to_udhm(raw[:, cols].astype(np.float64), side=side)
                np.testing.assert_allclose(out[:, 14 + 22 * b : 36 + 22 * b], expect, atol=1e-6)


def test_real_g1_inspire_keep_hands(real_data_dir, tmp_path):
    """`--keep=hands` on the real G1 + Inspire dataset: valid (it failed its own native-layout check), the
    robot's own type kept, and the native layout decodes the converted actions back to the source's hand
    columns (Inspire 0-1 values, source order)."""
    import pyarrow.parquet as pq


    src_root = real_data_dir / "g1-inspire"
    root = tmp_path / "g1_hands"
    hands_opt = {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}
    convert(ConvertOptions(source="lerobot", input=src_root, root=root, repo_id="t/g1_hands", keep="hands",
                           source_options={"hands": hands_opt}, max_episodes=2, progress=False))  # fmt: skip
    report = validate_dataset(root)
    assert report.ok, report.table()
    info = json.loads((root / "meta/info.json").read_text())
    assert info["robot_type"] == "Unitree_G1_Inspire" and info["features"]["action"]["shape"] == [44]
    source_names = json.loads((src_root / "meta/info.json").read_text())["features"]["action"]["names"][0]
    layout = UdhmDatasetMeta(root).native_layout("action")
    assert layout.native_names == source_names[14:]  # the 12 hand columns, source order
    assert load_record(root).to_dict()["native_layout"]["action"]["source_names"] == source_names
    converted = pq.read_table(sorted((root / "data").rglob("*.parquet")))
    for ep_index in range(2):
        raw = np.stack(
            pq.read_table(src_root / f"data/chunk-000/episode_{ep_index:06d}.parquet")["action"].to_numpy(
                zero_copy_only=False
            )
        )
        rows = converted["episode_index"].to_numpy() == ep_index
        out = np.stack(converted["action"].to_numpy(zero_copy_only=False)[rows])
        np.testing.assert_allclose(layout.to_native(out), raw[:, 14:], atol=1e-5)


def test_append_pad_mapping_and_stale_temp_cleanup(samples, tmp_path):
    target = tmp_path / "pad"
    stale = tmp_path / ".pad.tmp-999999999-deadbeef"  # a run killed with SIGKILL (no such pid)
    (stale / "data").mkdir(parents=True)
    convert(
        ConvertOptions(
            source="linkerhand",
            input=samples["linkerhand"],
            root=target,
            progress=False,
            mapping="append_pad",
            max_episodes=2,
        )
    )
    assert not stale.exists()
    frames = load_udhm_frames(target)
    for hand in set(frames.hands):
        n_active = hands.get(hand).num_active
        rows = frames.masks[frames.hands == hand]
        assert rows[:, :n_active].all() and not rows[:, n_active:].any()  # packed at the front
    assert load_record(target).to_dict()["mapping"] == "append_pad"
    assert validate_dataset(target).ok  # the validator checks masks against the recorded mapping


def test_input_is_synthetic_reads_the_sample_labels_up_to_two_folders_up(tmp_path):
    """A sample written by `samples` carries a labels file saying it is synthetic; an input inside
    it (up to two folders down) is marked synthetic on the card, a labels file saying false or a damaged one
    is not (a damaged file must not stop the conversion)."""
    from lerobot_unidextok.constants import SAMPLE_LABELS_FILE
    from lerobot_unidextok.conversion.pipeline import input_is_synthetic

    sample = tmp_path / "sample"
    (sample / "a" / "b" / "c").mkdir(parents=True)
    (sample / SAMPLE_LABELS_FILE).write_text(json.dumps({"synthetic": True}))
    assert input_is_synthetic(sample) and input_is_synthetic(sample / "a" / "b")
    assert not input_is_synthetic(sample / "a" / "b" / "c")  # three folders down: not looked for
    (sample / SAMPLE_LABELS_FILE).write_text(json.dumps({"synthetic": False}))
    assert not input_is_synthetic(sample / "a")
    for damaged in ("{not json", "[1, 2]"):
        (sample / SAMPLE_LABELS_FILE).write_text(damaged)
        assert input_is_synthetic(sample) is False
