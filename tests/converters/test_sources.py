"""Every source reader on the synthetic samples: shapes, native units, sides, valid masks, tasks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from lerobot_unidextok import hands
from lerobot_unidextok.conversion.episode import RawEpisode
from lerobot_unidextok.conversion.registry import available_sources, get_source
from lerobot_unidextok.samples import SampleSpec, write_samples
from lerobot_unidextok.samples.formats import write_linkerhand_episodes

EPISODES, FRAMES = 3, 40
# Unitree's G1 + Inspire column names (xr_teleoperate teleop/robot_control/robot_hand_inspire.py), written out here
G1_HANDS = {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    out = tmp_path_factory.mktemp("source_samples")
    return write_samples(out, episodes_per_source=EPISODES, frames_per_episode=FRAMES, seed=1)


def _read_all(name: str, folder, **options) -> list[RawEpisode]:
    src = get_source(name)(**options)
    refs = src.list_episodes(folder)
    assert len(refs) == EPISODES
    return [src.read_episode(r) for r in refs]


def _labels(folder) -> dict:
    return json.loads((folder / "gestures.json").read_text())["episodes"]


def test_all_sources_registered_with_license_and_description():
    names = available_sources()
    for name in ("dexycb", "oakink2", "egodex", "let", "dexora", "linkerhand", "lerobot"):
        assert name in names
        cls = get_source(name)
        assert cls.license and cls.description


def test_dexycb(samples):
    labels = _labels(samples["dexycb"])
    for ep in _read_all("dexycb", samples["dexycb"]):
        (hand,) = ep.hands
        meta = yaml.safe_load(open(f"{ep.source_file}/meta.yml"))
        # 25 fps: handover-sim (same authors) steps raw DexYCB frames by 0.04 s; the old reader said 30
        assert hand.side == meta["mano_sides"][0] and hand.hand == "human" and ep.fps == 25.0
        assert hand.state_native.shape == (meta["num_frames"], 21, 3)
        key = "/".join(ep.source_file.split("/")[-2:])
        assert hand.valid.tolist() == [lab != "" for lab in labels[key][hand.side]]
        assert not hand.valid.all() and np.all(hand.state_native[~hand.valid] == -1)
        z = hand.state_native[hand.valid, :, 2]
        assert (z > 0.3).all() and (z < 1.2).all()  # in front of the camera, metres
        assert ep.task.startswith("grasp the ")


def test_dexycb_view_and_handedness(samples, tmp_path):
    import shutil

    src_cap = next(samples["dexycb"].glob("*/*/meta.yml")).parent
    cap = tmp_path / "s" / "c"
    shutil.copytree(src_cap, cap)
    meta = yaml.safe_load((cap / "meta.yml").read_text())
    meta["mano_sides"] = ["left" if meta["mano_sides"][0] == "right" else "right"]
    (cap / "meta.yml").write_text(yaml.safe_dump(meta))
    src = get_source("dexycb")()
    ep0 = src.read_episode(str(cap))
    assert ep0.hands[0].side == meta["mano_sides"][0]
    ep1 = get_source("dexycb")(view=1).read_episode(str(cap))
    v = ep0.hands[0].valid
    # another camera: different coordinates, same hand (same inter-keypoint distances)
    a, b = ep0.hands[0].state_native[v], ep1.hands[0].state_native[v]
    assert not np.allclose(a, b)
    np.testing.assert_allclose(
        np.linalg.norm(a[:, 8] - a[:, 0], axis=-1), np.linalg.norm(b[:, 8] - b[:, 0], axis=-1), atol=1e-5
    )


def test_egodex(samples):
    episodes = _read_all("egodex", samples["egodex"])
    confidences_missing = 0
    for ep in episodes:
        assert [h.side for h in ep.hands] == ["left", "right"] and ep.fps == 30.0
        assert ep.task and "synthetic" not in ep.task
        for h in ep.hands:
            assert h.hand == "human" and h.state_native.shape == (ep.num_frames, 21, 3)
            palm = np.linalg.norm(h.state_native[:, 9] - h.state_native[:, 0], axis=-1)
            assert 0.07 < palm.mean() < 0.13 and palm.std() < 1e-4  # wrist -> middle knuckle, metres
            confidences_missing += h.valid is None
        left, right = (h.state_native[:, 0, 0].mean() for h in ep.hands)
        assert left < right  # left hand on the left (ARKit x to the right)
    assert confidences_missing == 2  # the third file was written without confidences/


def _truth(folder) -> dict:
    return dict(np.load(folder / "udhm_truth.npz"))


def _udhm_error_rad(h, truth: np.ndarray) -> float:
    """Mean |UDHM(native action) - truth| over the hand's active slots, truth projected on what the hand can
    reach. The frames must line up: the generating track shifted by one frame either way fits worse."""
    spec = hands.get(h.hand)
    got = spec.to_udhm(h.action_native, side=h.side)
    truth = spec.to_udhm(spec.from_udhm(truth.astype(np.float64), side=h.side), side=h.side)
    active = spec.mask("semantic")
    n = min(len(got), len(truth)) - 2
    errors = [float(np.abs(got[1 : n + 1, active] - truth[1 + s : n + 1 + s, active]).mean()) for s in (-1, 0, 1)]
    assert errors[1] == min(errors), errors  # no frame offset, no stretched time axis
    return errors[1]


def test_egodex_task_text_as_apples_loader(samples):
    """Reversible EgoDex tasks are recorded both ways; Apple's loader takes llm_description2 unless
    which_llm_description is '1'. Catches the old reader, which always took llm_description (the reverse task)."""
    import h5py

    seen = set()
    for ep in _read_all("egodex", samples["egodex"]):
        with h5py.File(ep.source_file, "r") as f:
            attrs = {k: f.attrs[k] for k in f.attrs}
        if attrs.get("llm_type") == "reversible":
            key = "llm_description" if attrs["which_llm_description"] == "1" else "llm_description2"
            seen.add(key)
        else:
            key = "llm_description"
        assert ep.task == attrs[key]
    assert "llm_description2" in seen  # the sample has a reversible episode recorded the other way


def test_let_bags(samples):
    """LET from its real form, ROS 1 bags: jittered stamps resampled onto an exact 30 fps grid, hands routed
    by folder (dex_hand -> BrainCo, Linker_Hand_L6 -> LinkerHand L6), arms kept, gripper bags skipped.
    Catches the old reader, which only read a per-episode JSON no upstream tool writes."""
    labels, truth = _labels(samples["let"]), _truth(samples["let"])
    for ep in _read_all("let", samples["let"]):
        key = "/".join(ep.source_file.split("/")[-2:])
        folder = key.split("/")[0]
        expected = "linkerhand_l6" if folder.endswith("Linker_Hand_L6") else "brainco_revo1"
        assert [h.side for h in ep.hands] == ["left", "right"] and ep.fps == 30.0
        assert "grasp" in ep.task and labels[key]["hand"] == expected
        rate = ep.source_episode["measured_hz"]["/control_robot_hand_position"]
        assert abs(rate - 30.0) > 0.02  # the stamps really jitter: a stamp-derived fps would not be an integer
        assert ep.passthrough["observation.state"].values.shape == (ep.num_frames, 14)
        assert ep.passthrough["observation.state"].names[0] == "zarm_l1_link"
        assert np.abs(ep.passthrough["observation.state"].values).max() < np.pi  # radians, not degrees
        assert np.abs(ep.passthrough["action"].values).max() < np.pi  # /kuavo_arm_traj degrees converted
        for h in ep.hands:
            assert h.hand == expected and h.state_native.shape == (ep.num_frames, 6)
            assert h.action_native.shape == h.state_native.shape and h.state_columns[0] == f"{h.side[0]}_thumb"
            lo, hi = (0, 255) if expected == "linkerhand_l6" else (0, 100)
            assert h.state_native.min() >= lo and h.state_native.max() <= hi
            assert _udhm_error_rad(h, truth[f"{key}|{h.side}"]) < 0.012  # uint8 steps of the 0-100 scale
    assert not any("leju_claw" in r for r in get_source("let")().list_episodes(samples["let"]))


def test_let_nearest_interpolation_option(samples):
    src = get_source("let")(interpolation="nearest")
    ref = src.list_episodes(samples["let"])[0]
    a, b = src.read_episode(ref), get_source("let")().read_episode(ref)
    assert a.num_frames == b.num_frames and not np.array_equal(a.hands[0].state_native, b.hands[0].state_native)
    with pytest.raises(ValueError, match="interpolation must be one of"):
        get_source("let")(interpolation="cubic")


def test_dexora(samples):
    spec = hands.get("xhand1")
    episodes = _read_all("dexora", samples["dexora"])
    keys = set()
    for ep in episodes:
        assert ep.fps == 20.0 and ep.task
        keys.add(ep.native_keys.get("observation.state", "observation.state"))
        pt = ep.passthrough["observation.state"]
        assert pt.names[:2] in (
            ("left_arm_joint_1_obs", "left_arm_joint_2_obs"),
            ("left_arm_joint_0", "left_arm_joint_1"),
        )
        assert pt.values.shape[1] in (15, 12)  # 2 x 6 arm joints (+ head, spine in scheme 1)
        for h in ep.hands:
            assert h.hand == "xhand1" and h.state_native.shape == (ep.num_frames, 12)
            lo, hi = spec.limits_rad(h.side).T
            assert (h.action_native >= lo - 1e-6).all() and (h.action_native <= hi + 1e-6).all()  # radians
            assert np.abs(h.state_native).max() < 2.0
    assert keys == {"observation.state"}


@pytest.mark.parametrize("scheme", [1, 2])
def test_dexora_both_naming_schemes_give_the_generating_motion(scheme, tmp_path):
    """Scheme 2 (states/actions, joints 0..11, left_hand_action_k) reads like scheme 1. Catches the old
    reader, which accepted only left_hand_joint_1..12[_suffix] in observation.state."""
    from lerobot_unidextok.samples.formats import write_dexora_episodes

    labels = write_dexora_episodes(tmp_path, SampleSpec(EPISODES, FRAMES, 3), scheme=scheme)
    truth = {f"{k}|{s}": v["_angles_rad"][s] for k, v in labels.items() for s in ("left", "right")}
    src = get_source("dexora")()
    for ref in src.list_episodes(tmp_path):
        ep = src.read_episode(ref)
        assert ep.native_keys.get("observation.state", "observation.state") == (
            "states" if scheme == 2 else "observation.state"
        )
        key = f"{Path(ref.root).name}/episode_{ref.episode_index:06d}"
        for h in ep.hands:
            spec = hands.get("xhand1")
            q = truth[f"{key}|{h.side}"].astype(np.float64)
            expected = spec.to_udhm(spec.from_udhm(q, side=h.side), side=h.side)
            got = spec.to_udhm(h.action_native, side=h.side)
            assert np.abs(got - expected)[:, spec.mask()].max() < 1e-5


def test_dexora_slices_by_name_not_position(samples, tmp_path):
    """Reordering the columns (README vs converter order) does not change what the reader returns."""
    import shutil

    import pyarrow as pa
    import pyarrow.parquet as pq

    root = tmp_path / "dexora"
    shutil.copytree(samples["dexora"] / "airbot_pick_and_place", root)
    info = json.loads((root / "meta" / "info.json").read_text())
    names = info["features"]["observation.state"]["names"]
    perm = np.random.default_rng(0).permutation(len(names))
    for key in ("observation.state", "action"):
        info["features"][key]["names"] = [info["features"][key]["names"][i] for i in perm]
    (root / "meta" / "info.json").write_text(json.dumps(info))
    for path in (root / "data" / "chunk-000").glob("*.parquet"):
        table = pq.read_table(path)
        cols = {}
        for key in table.column_names:
            if key in ("observation.state", "action"):
                arr = np.stack(table[key].to_numpy(zero_copy_only=False))[:, perm].astype(np.float32)
                cols[key] = pa.FixedSizeListArray.from_arrays(pa.array(arr.ravel()), arr.shape[1])
            else:
                cols[key] = table[key]
        pq.write_table(pa.table(cols), path)
    src = get_source("dexora")()
    before = src.read_episode(src.list_episodes(samples["dexora"] / "airbot_pick_and_place")[0])
    after = src.read_episode(src.list_episodes(root)[0])
    for a, b in zip(before.hands, after.hands, strict=True):
        np.testing.assert_array_equal(a.state_native, b.state_native)
        np.testing.assert_array_equal(a.action_native, b.action_native)


def test_linkerhand_ros2_bags_l10_and_l20(samples, tmp_path):
    """LinkerHand from ROS 2 bags (sqlite3 and MCAP) of the SDK topics, model from /cb_<side>_hand_info.
    Catches the old reader, which only read invented per-episode JSON."""
    episodes = _read_all("linkerhand", samples["linkerhand"])
    truth = _truth(samples["linkerhand"])
    storages = set()
    for ep in episodes:
        number = int(ep.source_file.rsplit("_", 1)[1])  # episode_0003 -> 3
        hand, width = ("linkerhand_l10", 10) if number % 2 == 0 else ("linkerhand_l20", 20)  # models alternate
        assert [h.side for h in ep.hands] == ["left", "right"] and ep.task and ep.fps == 30.0
        assert ep.extra["hand_model"] == ("L10,L10" if width == 10 else "L20,L20")
        storages |= {p.suffix for p in Path(ep.source_file).iterdir() if p.suffix in (".db3", ".mcap")}
        key = "/".join(ep.source_file.split("/")[-2:])
        for h in ep.hands:
            assert h.hand == hand and h.state_native.shape == (ep.num_frames, width)
            assert h.action_native.shape == h.state_native.shape
            assert h.state_native.min() >= 0 and h.state_native.max() <= 255
            assert _udhm_error_rad(h, truth[f"{key}|{h.side}"]) < 0.01
    assert storages == {".db3", ".mcap"}
    write_linkerhand_episodes(tmp_path, SampleSpec(EPISODES, FRAMES, 0), models=("L20",))
    assert {h.hand for ep in _read_all("linkerhand", tmp_path) for h in ep.hands} == {"linkerhand_l20"}
    with pytest.raises(ValueError, match="unknown LinkerHand models"):
        write_linkerhand_episodes(tmp_path, SampleSpec(1, 20, 0), models=("L99",))


def test_generic_lerobot_on_sample(samples):
    labels = _labels(samples["lerobot"])
    episodes = _read_all("lerobot", samples["lerobot"], hands=json.dumps(G1_HANDS))
    for i, ep in enumerate(episodes):
        assert ep.fps == 30.0 and ep.task and ep.extra["codebase_version"] == "v2.1"
        assert ep.num_frames == len(labels[f"episode_{i:06d}"]["right"])
        for h in ep.hands:
            assert h.hand == "inspire_rh56_unitree" and h.state_native.shape == (ep.num_frames, 6)
            assert h.state_native.min() >= 0 and h.state_native.max() <= 1  # normalised, 1 = open
            assert h.action_native.shape == h.state_native.shape
    # the long form with explicit names selects the same columns
    explicit = {
        side: {
            "hand": "inspire_rh56_unitree",
            "state_names": [
                f"k{side.title()}Hand{j}" for j in ("Pinky", "Ring", "Middle", "Index", "ThumbBend", "ThumbRotation")
            ],
        }
        for side in ("left", "right")
    }
    again = _read_all("lerobot", samples["lerobot"], hands=explicit)
    for a, b in zip(episodes[0].hands, again[0].hands, strict=True):
        np.testing.assert_array_equal(a.state_native, b.state_native)


def test_generic_lerobot_bad_options(samples):
    with pytest.raises(ValueError, match="needs hands"):
        get_source("lerobot")()
    with pytest.raises(ValueError, match="'<hand spec>:<name prefix>'"):
        get_source("lerobot")(hands={"left": "inspire_rh56_unitree"})
    with pytest.raises(ValueError, match="'left' or 'right'"):
        get_source("lerobot")(hands={"middle": "x:y"})
    src = get_source("lerobot")(
        hands={"left": {"hand": "inspire_rh56_unitree", "state_names": ["kLeftHandPinky", "kLeftHandThumbTip"]}}
    )
    with pytest.raises(ValueError, match=r"info.json.*unknown names \['kLeftHandThumbTip'\]"):
        src.read_episode(src.list_episodes(samples["lerobot"])[0])


def test_generic_lerobot_reads_v30_written_by_lerobot(samples, tmp_path):
    """A v3.0 dataset written with LeRobot's own writer reads back like the v2.1 source it came from."""
    from lerobot.datasets import LeRobotDataset

    v21 = _read_all("lerobot", samples["lerobot"], hands=G1_HANDS)
    info = json.loads((samples["lerobot"] / "meta" / "info.json").read_text())
    names = info["features"]["observation.state"]["names"]
    features = {k: {"dtype": "float32", "shape": (26,), "names": names} for k in ("observation.state", "action")}
    ds = LeRobotDataset.create(
        repo_id="local/g1_v30", fps=30, features=features, root=tmp_path / "v30", use_videos=False
    )
    src21 = get_source("lerobot")(hands=G1_HANDS)
    import pyarrow.parquet as pq

    for ref, ep in zip(src21.list_episodes(samples["lerobot"]), v21, strict=True):
        table = pq.read_table(f"{ref.root}/data/chunk-000/episode_{ref.episode_index:06d}.parquet").to_pydict()
        for s, a in zip(table["observation.state"], table["action"], strict=True):
            ds.add_frame(
                {"observation.state": np.asarray(s, np.float32), "action": np.asarray(a, np.float32), "task": ep.task}
            )
        ds.save_episode()
    ds.finalize()
    v30 = _read_all("lerobot", tmp_path / "v30", hands=G1_HANDS)
    for a, b in zip(v21, v30, strict=True):
        assert b.extra["codebase_version"] == "v3.0" and a.task == b.task and a.fps == b.fps
        for ha, hb in zip(a.hands, b.hands, strict=True):
            np.testing.assert_array_equal(ha.state_native, hb.state_native)
            np.testing.assert_array_equal(ha.action_native, hb.action_native)


def test_generic_lerobot_on_real_g1_inspire(real_data_dir):
    """The real Unitree G1 + Inspire v2.1 episodes (nested names, hands normalised 0-1)."""
    root = real_data_dir / "g1-inspire"
    src = get_source("lerobot")(hands=G1_HANDS)
    refs = src.list_episodes(root)
    assert len(refs) == 10
    episodes = [src.read_episode(r) for r in refs]
    assert sum(ep.num_frames for ep in episodes) == 4236
    assert episodes[0].num_frames == 479
    for ep in episodes:
        assert ep.fps == 30.0 and ep.task == "Pick up the yellow bottle on the table."
        for h in ep.hands:
            assert h.state_native.shape == (ep.num_frames, 6) and h.action_native.shape == (ep.num_frames, 6)
            assert h.state_native.min() >= 0.0 and h.state_native.max() <= 1.0
    right = np.concatenate([ep.hands[1].state_native for ep in episodes])
    assert right.max() > 0.95 and right.min() < 0.5  # opens fully, closes for the grasp


def test_dexora_sample_converts_with_lerobots_v21_to_v30_script(samples, tmp_path):
    """LeRobot's own v2.1 -> v3.0 converter accepts the v2.1 sample; the reader gives the same episodes after."""
    import shutil

    from lerobot.scripts.convert_dataset_v21_to_v30 import convert_dataset

    root = tmp_path / "dexora"
    shutil.copytree(samples["dexora"] / "airbot_pick_and_place", root)
    convert_dataset(repo_id="local/dexora_sample", root=root, push_to_hub=False)  # in place, v2.1 -> root_old
    assert json.loads((root / "meta" / "info.json").read_text())["codebase_version"] == "v3.0"
    src = get_source("dexora")()
    v21 = [src.read_episode(r) for r in src.list_episodes(samples["dexora"] / "airbot_pick_and_place")]
    v30 = [src.read_episode(r) for r in src.list_episodes(root)]
    for a, b in zip(v21, v30, strict=True):
        assert a.task == b.task and a.fps == b.fps and a.num_frames == b.num_frames
        for ha, hb in zip(a.hands, b.hands, strict=True):
            np.testing.assert_array_equal(ha.state_native, hb.state_native)
            np.testing.assert_array_equal(ha.action_native, hb.action_native)


def test_generic_lerobot_hand_in_its_own_feature(tmp_path):
    """A dataset storing each hand in its own (unnamed) feature: `state_key` / `action_key` per hand."""
    from lerobot_unidextok.samples.formats import _write_lerobot_v21

    rng = np.random.default_rng(0)
    right = rng.uniform(0, 1, (30, 6))
    cols = {"observation.state.right_hand": right, "action.right_hand": right[::-1].copy()}
    _write_lerobot_v21(tmp_path / "own", 15.0, "x", {k: None for k in cols}, [(cols, "wave")])
    hands_opt = {
        "right": {
            "hand": "inspire_rh56_unitree",
            "state_key": "observation.state.right_hand",
            "action_key": "action.right_hand",
        }
    }
    (ep,) = _read_all_n("lerobot", tmp_path / "own", 1, hands=hands_opt)
    (h,) = ep.hands
    np.testing.assert_allclose(h.state_native, right.astype(np.float32))
    np.testing.assert_allclose(h.action_native, right[::-1].astype(np.float32))
    assert ep.fps == 15.0 and ep.task == "wave"
    with pytest.raises(ValueError, match=r"needs 'state_names' or 'prefix'.*or 'state_key'"):
        get_source("lerobot")(hands={"right": {"hand": "inspire_rh56_unitree"}})


def _read_all_n(name: str, folder, n: int, **options) -> list[RawEpisode]:
    src = get_source(name)(**options)
    refs = src.list_episodes(folder)
    assert len(refs) == n
    return [src.read_episode(r) for r in refs]


def test_egodex_valid_mask_matches_labels(samples):
    labels = _labels(samples["egodex"])
    src = get_source("egodex")()
    for ref in src.list_episodes(samples["egodex"]):
        ep = src.read_episode(ref)
        key = "/".join(ref.split("/")[-2:])
        for h in ep.hands:
            present = [lab != "" for lab in labels[key][h.side]]
            assert (h.valid.tolist() if h.valid is not None else [True] * ep.num_frames) == present


@pytest.fixture(scope="module")
def oakink2(tmp_path_factory):
    return write_samples(tmp_path_factory.mktemp("oak"), sources=["oakink2"], episodes_per_source=2,
                         frames_per_episode=40, seed=1)["oakink2"]  # fmt: skip


STANDIN = "mano_standin:make_layer"  # tests/fixtures: MANO's interface without the licensed model


def test_oakink2_mocap_ids_are_120hz(oakink2):
    """OakInk-v2 mocap ids tick at 120 Hz (FPS_MOCAP in OakInk2-PreviewTool): every id is a frame at 120 fps,
    or every k-th at 120/k. Catches the old reader, which declared 30 fps (episodes played 4x slow)."""
    import pickle

    import torch
    from mano_standin import make_layer

    src = get_source("oakink2")(mano_layer=STANDIN)
    refs = src.list_episodes(oakink2)
    assert len(refs) == 2
    for ref in refs:
        ep = src.read_episode(ref)
        anno = pickle.load(open(ref, "rb"))
        ids = anno["mocap_frame_id_list"]
        assert ep.fps == 120.0 and ep.num_frames == max(ids) - min(ids) + 1
        for h in ep.hands:
            assert h.valid.sum() == len(ids)  # a missing id is a frame without hands, not a shorter clock
            fid = ids[len(ids) // 3]
            prefix = "rh" if h.side == "right" else "lh"
            entry = anno["raw_mano"][fid]
            joints = make_layer(h.side)(entry[f"{prefix}__pose_coeffs"], entry[f"{prefix}__betas"])[0]
            expect = (joints + entry[f"{prefix}__tsl"]).numpy()  # joints + tsl, as seg_3d.py
            np.testing.assert_allclose(h.state_native[fid - min(ids)], expect, atol=1e-6)
            assert isinstance(entry[f"{prefix}__tsl"], torch.Tensor)
    quarter = get_source("oakink2")(mano_layer=STANDIN, subsample=4).read_episode(refs[0])
    full = src.read_episode(refs[0])
    assert quarter.fps == 30.0 and quarter.num_frames == (full.num_frames + 3) // 4
    np.testing.assert_array_equal(quarter.hands[0].state_native, full.hands[0].state_native[::4])
    with pytest.raises(ValueError, match=r"subsample must divide the 120 Hz .* use one of \[1, 2, 3, 4, 5, 6, 8"):
        get_source("oakink2")(subsample=7)


def test_oakink2_converts_at_120fps(oakink2, tmp_path):
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.data import load_udhm_frames

    report = convert(ConvertOptions(source="oakink2", input=oakink2, root=tmp_path / "oak", progress=False,
                                    source_options={"mano_layer": STANDIN}))  # fmt: skip
    frames = load_udhm_frames(tmp_path / "oak")
    assert report.num_episodes == 2 and frames.fps == 120 and set(frames.side) == {"right", "left"}
    assert np.isfinite(frames.states_rad).all()


@pytest.mark.parametrize(
    "name_of", [lambda side, k: f"{side}_hand.joint_{k}.pos", lambda side, k: f"{side}_hand_joint_{k}.pos"]
)
def test_linkerhand_lerobot_v30_export_with_state_key_and_pos_names(name_of, tmp_path):
    """A LeRobot v3.0 dataset written by LeRobot's own writer, as real LinkerHand exports are: vectors named
    `state` / `actions`, joints `right_hand.joint_1.pos` (LeRobot's `<motor>.pos` convention). Catches the reader
    that had no state_key / action_key and matched only `<side>_hand[_joint]_<k>`."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, SetupError, convert
    from lerobot_unidextok.conversion.validate import validate_dataset
    from lerobot_unidextok.data import load_udhm_frames

    names = [name_of(side, k) for side in ("left", "right") for k in range(1, 11)]
    features = {
        "state": {"dtype": "float32", "shape": (20,), "names": names},
        "actions": {"dtype": "float32", "shape": (20,), "names": names},
    }
    src = tmp_path / "lh"
    ds = LeRobotDataset.create("t/lh", fps=30, features=features, root=src, use_videos=False, robot_type="linkerhand")
    rng = np.random.default_rng(0)
    values = rng.integers(0, 256, size=(2, 15, 20)).astype(np.float32)  # SDK units 0-255
    for episode in values:
        for row in episode:
            ds.add_frame({"state": row, "actions": row, "task": "grasp"})
        ds.save_episode()
    ds.finalize()

    with pytest.raises(SetupError, match=r"features\['observation.state'\]: missing"):
        convert(ConvertOptions(source="linkerhand", input=src, root=tmp_path / "bad", progress=False,
                               source_options={"model": "L10"}))  # fmt: skip
    root = tmp_path / "udhm"
    options = {"model": "L10", "state_key": "state", "action_key": "actions"}
    convert(ConvertOptions(source="linkerhand", input=src, root=root, source_options=options, progress=False))
    assert validate_dataset(root).ok
    frames = load_udhm_frames(root, split=None)
    spec = hands.get("linkerhand_l10")
    for side, cols in (("left", slice(0, 10)), ("right", slice(10, 20))):
        got = frames.states_rad[frames.side == side]
        expected = spec.to_udhm(values.reshape(-1, 20)[:, cols].astype(np.float64), side)
        np.testing.assert_allclose(got, expected, atol=1e-5)
    layout = json.loads((root / "meta/unidextok_conversion.json").read_text())["native_layout"]
    assert layout["observation.state"]["native_names"] == names and layout["observation.state"]["source_key"] == "state"
    assert json.loads((root / "meta/info.json").read_text())["robot_type"] == "linkerhand"


def test_the_known_g1_inspire_layout_is_unitrees_column_names():
    """`hands="unitree_g1_inspire"` names Unitree's own columns (written out above, not taken from the reader)."""
    from lerobot_unidextok.converters.lerobot import KNOWN_HANDS, parse_hands

    assert KNOWN_HANDS["unitree_g1_inspire"] == G1_HANDS
    assert parse_hands("unitree_g1_inspire") == parse_hands(G1_HANDS)
