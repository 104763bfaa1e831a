"""What real LeRobot recordings of other robots look like, and what the lerobot reader makes of it: vectors
named `state` / `actions`, a hand's columns in another order than its joints, a hand never recorded (its
columns 0 throughout), a shape that disagrees with its names, videos in another folder than info.json says.
Each one line saying what was read past, and a dataset converted right."""

import json
import logging
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
from l10_robot import HAND, PREFIX, l10_motion, write_l10_robot

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.data import UdhmDatasetMeta, load_udhm_frames

JOINTS = list(hands.get(HAND).joint_names)


def _convert(raw, root, hand_option, **kw):
    return convert(ConvertOptions(source="lerobot", input=raw, root=root, progress=False,
                                  source_options={"hands": hand_option}, **kw))  # fmt: skip


def _state(root) -> np.ndarray:
    return np.stack(pq.read_table(sorted((root / "data").rglob("*.parquet"))).column(OBS_STATE).to_pylist())


def test_a_two_hand_export_named_state_actions_with_the_left_hand_at_zero(tmp_path, caplog):
    """The export of a robot with one LinkerHand L10 on the right: `state` / `actions` of 20 columns, the left
    hand's 10 at 0 in every frame. 0 is a fully flexed L10 joint: read as values it would be a closed fist."""
    names = [f"{side}_hand_joint_{i}" for side in ("left", "right") for i in range(10)]
    raw = write_l10_robot(tmp_path / "raw", episodes=3, keys=("state", "actions"), names=names, left_zero=True)
    with caplog.at_level(logging.WARNING):
        _convert(raw, tmp_path / "out", {"left": f"{HAND}:left_hand_", "right": f"{HAND}:right_hand_"})
    text = caplog.text
    assert "its state is the feature 'state'" in text and "its action is the feature 'actions'" in text
    assert "the left hand's columns are 0 in every frame of every episode" in text
    assert "name none of the linkerhand_l10 joints, so they are taken in the source's order" in text
    meta = UdhmDatasetMeta(tmp_path / "out")
    assert meta.names(OBS_STATE) == udhm_state_names(["right"]) and meta.block_hands() == [HAND]
    layout = meta.native_layout("action")
    assert layout.native_names == names and layout.dropped == names[:10]  # the robot's 20 columns, left zero
    assert layout.to_native(np.zeros((1, 22)))[0, :10].tolist() == [0.0] * 10
    # the right hand is the source's right columns, in the L10's SDK units through its spec
    source = l10_motion(41, 0)[:-1]
    np.testing.assert_allclose(_state(tmp_path / "out")[:40], hands.get(HAND).to_udhm(source.astype(float), "right"),
                               atol=1e-5)  # fmt: skip


def test_a_hand_zero_throughout_an_episode_is_absent_not_a_fist():
    """0 is a fully flexed L10 joint; every joint at 0 in every frame is a hand that was not recorded."""
    from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
    from lerobot_unidextok.conversion.mapping import map_episode

    moving = l10_motion(30, 0).astype(np.float64)
    raw = RawEpisode("ep", 30.0, [HandStream("left", HAND, np.zeros_like(moving)), HandStream("right", HAND, moving)])
    ep = map_episode(raw)
    assert ep.zero_hand_sides == ("left",) and not ep.mask[:, :22].any() and not ep.state_rad[:, :22].any()
    assert ep.absent_hand_frames == 30 and ep.mask[:, 22:].any()
    kept = map_episode(raw, zero_hands="keep")
    assert kept.zero_hand_sides == () and kept.mask[:, :22].any()  # read as values: the closed fist
    alone = RawEpisode("ep", 30.0, [HandStream("right", HAND, np.zeros_like(moving))])
    with pytest.raises(ValueError, match="every hand's state is 0 throughout"):
        map_episode(alone)


def test_hand_columns_are_bound_by_name_whatever_their_order(tmp_path):
    """The same joints listed in another order than the hand spec's convert to the same UDHM state: columns
    that name the joints are bound by name (before, by position: up to 43 deg off without a word)."""
    ordered = [f"r_l10_{j}" for j in JOINTS]
    shuffled = ordered[::-1]
    a = write_l10_robot(tmp_path / "a", episodes=2, names=ordered)
    b = write_l10_robot(tmp_path / "b", episodes=2, names=shuffled)
    # the same motion written in the reversed column order
    for path in sorted((b / "data").rglob("*.parquet")):
        t = pq.read_table(path)
        import pyarrow as pa

        for key in ("observation.state", "action"):
            v = np.stack(t.column(key).to_pylist())[:, ::-1].copy()
            t = t.set_column(t.schema.get_field_index(key), key,
                             pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1), pa.float32()), 10))  # fmt: skip
        pq.write_table(t, path)
    _convert(a, tmp_path / "ua", {"right": f"{HAND}:r_l10_"})
    _convert(b, tmp_path / "ub", {"right": f"{HAND}:r_l10_"})
    np.testing.assert_array_equal(_state(tmp_path / "ua"), _state(tmp_path / "ub"))
    assert UdhmDatasetMeta(tmp_path / "ub").native_layout().native_names == shuffled  # the robot's own order back
    half = ordered[:5] + [f"r_l10_extra_{i}" for i in range(5)]
    c = write_l10_robot(tmp_path / "c", episodes=1, names=half)
    with pytest.raises(ValueError, match=r"only partly name the joints of linkerhand_l10.*name none"):
        _convert(c, tmp_path / "uc", {"right": f"{HAND}:r_l10_"})


def test_a_shape_that_disagrees_with_its_names_and_videos_in_another_folder(tmp_path, caplog):
    raw = write_l10_robot(tmp_path / "raw", episodes=2)
    info_path = raw / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"]["observation.state"]["shape"] = [12]  # seen: shape [30] with 28 names (rows: 28 wide)
    info_path.write_text(json.dumps(info))
    with caplog.at_level(logging.WARNING):
        _convert(raw, tmp_path / "out", {"right": f"{HAND}:r_l10_"})
    assert "shape [12] disagrees with its 10 names; the data rows are 10 wide, so the names are used" in caplog.text
    info["features"]["observation.state"]["names"] = info["features"]["observation.state"]["names"][:8]
    info["features"]["observation.state"]["shape"] = [10]
    info_path.write_text(json.dumps(info))
    with pytest.raises(ValueError, match="8 names for shape .10., and the data rows are 10 wide"):
        _convert(raw, tmp_path / "out2", {"right": f"{HAND}:r_l10_"})


def test_videos_under_another_folder_than_info_json_says(tmp_path, caplog):
    from lerobot_unidextok.converters._lerobot_files import moved_file, video_folder_note

    root = tmp_path / "ds"
    (root / "video" / "cam" / "chunk-000").mkdir(parents=True)
    (root / "video" / "cam" / "chunk-000" / "file-000.mp4").write_bytes(b"x")
    info = {"video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
            "features": {"cam": {"dtype": "video"}}}  # fmt: skip
    assert "video_path says videos/, but the videos are under video/: reading them there" in video_folder_note(root, info)
    want = root / "videos" / "cam" / "chunk-000" / "file-000.mp4"
    assert moved_file(root, want) == root / "video" / "cam" / "chunk-000" / "file-000.mp4"
    (root / "videos").mkdir()
    assert video_folder_note(root, info) is None


def test_a_dataset_whose_every_hand_is_zero_is_refused(tmp_path):
    names = [f"{side}_hand_joint_{i}" for side in ("left", "right") for i in range(10)]
    raw = write_l10_robot(tmp_path / "raw", episodes=1, names=names, left_zero=True)
    with pytest.raises(Exception, match="every hand's columns are 0 in every frame"):
        _convert(raw, tmp_path / "out", {"left": f"{HAND}:left_hand_"})
    assert not (tmp_path / "out").exists()
    _ = shutil, load_udhm_frames


def test_timestamps_all_zero_or_repeated_are_named_when_rebuilt(tmp_path, caplog):
    """Source timestamps all 0 (episode 0) or repeating (episode 1) were rebuilt from the frame indices without
    a word; now the conversion says which episodes and that the rebuilt clock assumes frames 1/fps apart."""
    import pyarrow as pa

    raw = write_l10_robot(tmp_path / "raw", episodes=3)
    for path in sorted((raw / "data").rglob("*.parquet")):
        table = pq.read_table(path)
        episode = table.column("episode_index").to_numpy()
        t = table.column("timestamp").to_numpy().copy()
        t[episode == 0] = 0.0
        t[np.flatnonzero(episode == 1)[5:8]] = t[np.flatnonzero(episode == 1)[4]]
        pq.write_table(table.set_column(table.schema.get_field_index("timestamp"), "timestamp",
                                        pa.array(t, table.schema.field("timestamp").type)), path)  # fmt: skip
    with caplog.at_level(logging.WARNING):
        report = _convert(raw, tmp_path / "out", {"right": f"{HAND}:{PREFIX}"})
    assert report.num_episodes == 3
    text = caplog.text
    assert "2 episode(s) have source timestamps that do not step by 1/fps" in text and "frame_index / 30" in text
    assert "timestamps all 0" in text and "repeat or go back at 3 of 40 frames" in text



def test_nan_or_infinite_timestamps_are_named_when_rebuilt(tmp_path, caplog):
    """A NaN source timestamp (episode 0) or an infinite one (episode 1) was rebuilt from the frame index without
    the warning repeated timestamps get (NaN compares false with everything, so no step looked wrong)."""
    import pyarrow as pa

    raw = write_l10_robot(tmp_path / "raw", episodes=3)
    for path in sorted((raw / "data").rglob("*.parquet")):
        table = pq.read_table(path)
        episode = table.column("episode_index").to_numpy()
        t = table.column("timestamp").to_numpy().copy()
        t[np.flatnonzero(episode == 0)[7]] = np.nan
        t[np.flatnonzero(episode == 1)[[0, 9]]] = np.inf
        pq.write_table(table.set_column(table.schema.get_field_index("timestamp"), "timestamp",
                                        pa.array(t, table.schema.field("timestamp").type)), path)  # fmt: skip
    with caplog.at_level(logging.WARNING):
        report = _convert(raw, tmp_path / "out", {"right": f"{HAND}:{PREFIX}"})
    assert report.num_episodes == 3
    text = caplog.text
    assert "2 episode(s) have source timestamps that do not step by 1/fps" in text and "frame_index / 30" in text
    assert "timestamps are not numbers (NaN or infinite) at 1 of 40 frames" in text
    assert "timestamps are not numbers (NaN or infinite) at 2 of 40 frames" in text
    t = pq.read_table(sorted((tmp_path / "out" / "data").rglob("*.parquet"))).column("timestamp").to_numpy()
    assert np.isfinite(t).all()

def test_the_test_split_does_not_depend_on_where_input_points(tmp_path):
    """A dataset converted from its own folder or from a folder above it holds out the same episodes (before:
    the keys kept the part of the path below --input, so `--input=$HF_LEROBOT_HOME/lab` gave other test
    episodes than `--input=$HF_LEROBOT_HOME/lab/g1`)."""
    write_l10_robot(tmp_path / "lab" / "g1", episodes=10)
    option = {"right": f"{HAND}:{PREFIX}"}
    splits = []
    for i, where in enumerate([tmp_path / "lab" / "g1", tmp_path / "lab"]):
        _convert(where, tmp_path / f"out{i}", option)
        splits.append(UdhmDatasetMeta(tmp_path / f"out{i}").split("recorded").test)
    assert len(splits[0]) == 2 and splits[1] == splits[0], splits


def test_a_g1_dex3_export_binds_each_hand_by_name(tmp_path):
    """A Unitree G1 + Dex3-1 export as unitree_lerobot writes it: 14 arm columns, then the left hand (SDK order:
    thumb, middle, index) and the right hand (thumb, index, middle). `hands="unitree_g1_dex3"` binds both by
    name: each UDHM slot holds its own finger's column on both sides, the arms pass through unchanged."""
    from lerobot.datasets import LeRobotDataset

    arms = [f"k{s}{j}" for s in ("Left", "Right") for j in ("ShoulderPitch", "ShoulderRoll", "ShoulderYaw", "Elbow",
                                                             "WristRoll", "WristPitch", "WristYaw")]  # fmt: skip
    left = [f"kLeftHand{j}" for j in ("Thumb0", "Thumb1", "Thumb2", "Middle0", "Middle1", "Index0", "Index1")]
    right = [f"kRightHand{j}" for j in ("Thumb0", "Thumb1", "Thumb2", "Index0", "Index1", "Middle0", "Middle1")]
    names = arms + left + right
    spec = hands.get("unitree_dex3_1")
    rng = np.random.default_rng(0)
    values = np.zeros((41, len(names)), np.float32)
    values[:, :14] = rng.uniform(-0.5, 0.5, (41, 14))
    for side, cols in (("left", left), ("right", right)):
        lim = spec.raw_range(side)  # (7, 2), the spec's joint order
        for k, (joint, (lo, hi)) in enumerate(zip(spec.joint_names, lim, strict=True)):  # a phase per joint
            col = next(c for c in cols if c.lower().endswith(joint.replace("_", "")))
            values[:, names.index(col)] = lo + (hi - lo) * (0.5 + 0.4 * np.sin(np.linspace(0, 3, 41) + k))
    features = {k: {"dtype": "float32", "shape": (len(names),), "names": names} for k in ("observation.state", "action")}
    ds = LeRobotDataset.create(repo_id="test/g1_dex3", fps=30, features=features, root=tmp_path / "raw",
                               robot_type="unitree_g1_dex3", use_videos=False)  # fmt: skip
    for state, action in zip(values[:-1], values[1:], strict=True):
        ds.add_frame({"observation.state": state, "action": action, "task": "pick"})
    ds.save_episode()
    ds.finalize()
    _convert(tmp_path / "raw", tmp_path / "out", "unitree_g1_dex3")
    state = _state(tmp_path / "out")
    meta = UdhmDatasetMeta(tmp_path / "out")
    assert meta.block_hands() == ["unitree_dex3_1", "unitree_dex3_1"]
    np.testing.assert_array_equal(state[:, :14], values[:-1, :14])  # the arms, bit for bit
    for b, (side, cols) in enumerate((("left", left), ("right", right))):
        native = np.stack([values[:-1, names.index(next(c for c in cols if c.lower().endswith(j.replace("_", ""))))]
                           for j in spec.joint_names], axis=1)  # fmt: skip
        np.testing.assert_allclose(state[:, 14 + 22 * b : 36 + 22 * b], spec.to_udhm(native.astype(float), side),
                                   atol=1e-5)  # fmt: skip



def test_nan_in_a_copied_feature_is_refused_with_the_feature_and_frames(tmp_path):
    """NaN in an extra float feature copied through (`observation.effort`) used to end in an IndexError from
    the statistics that named no column; now the episode is refused naming the feature, the frames and fixes,
    and with --on_error=skip the other episodes convert."""
    import pyarrow as pa

    from lerobot_unidextok.conversion.pipeline import ConversionError

    raw = write_l10_robot(tmp_path / "raw", episodes=3, effort=True)
    for path in sorted((raw / "data").rglob("*.parquet")):
        table = pq.read_table(path)
        episode = table.column("episode_index").to_numpy()
        effort = np.stack(table.column("observation.effort").to_pylist()).astype(np.float32)
        effort[np.flatnonzero(episode == 1)[[4, 9]], 2] = np.nan
        field = table.schema.field("observation.effort")
        column = pa.FixedSizeListArray.from_arrays(pa.array(effort.reshape(-1), pa.float32()), 3)
        pq.write_table(table.set_column(table.schema.get_field_index(field.name), field.name,
                                        column.cast(field.type)), path)  # fmt: skip
    with pytest.raises(ConversionError, match=r"NaN/inf in the copied feature observation.effort at frames \[4, 9\].*"
                                              r"--keep=hands"):  # fmt: skip
        _convert(raw, tmp_path / "out", {"right": f"{HAND}:{PREFIX}"})
    assert not (tmp_path / "out").exists()
    report = _convert(raw, tmp_path / "out", {"right": f"{HAND}:{PREFIX}"}, on_error="skip")
    assert report.num_episodes == 2 and len(report.failures) == 1


def test_metadata_that_disagrees_with_the_data_is_said_and_the_data_converted(tmp_path, caplog):
    """info.json announcing more episodes than exist, an episode whose recorded length is not its data's and a
    1-frame episode were converted without a word; now each is one line, and what the data holds is converted."""
    import pyarrow as pa

    raw = write_l10_robot(tmp_path / "raw", episodes=3, frames=[40, 1, 30])
    info = json.loads((raw / "meta/info.json").read_text())
    (raw / "meta/info.json").write_text(json.dumps({**info, "total_episodes": 5}))
    (episodes_file,) = sorted((raw / "meta" / "episodes").rglob("*.parquet"))
    table = pq.read_table(episodes_file)
    lengths = table.column("length").to_numpy().copy()
    lengths[2] = 35
    pq.write_table(table.set_column(table.schema.get_field_index("length"), "length",
                                    pa.array(lengths, table.schema.field("length").type)), episodes_file)  # fmt: skip
    with caplog.at_level(logging.WARNING):
        report = _convert(raw, tmp_path / "out", {"right": f"{HAND}:{PREFIX}"})
    text = caplog.text
    assert "total_episodes is 5, the episode metadata lists 3" in text
    assert "total_frames is 71, the episodes' lengths add up to 76" in text
    assert "2 episode(s) have source metadata that disagrees with their data, or a single frame" in text
    assert "it has a single frame" in text and "its episode metadata says 35 frames, its data holds 30" in text
    assert report.num_episodes == 3 and report.num_frames == 71
