"""Corrupt or partial inputs: every reader raises an error naming the file and the field."""

from __future__ import annotations

import json
import pickle
import shutil

import h5py
import numpy as np
import pytest
import yaml

from lerobot_unidextok.conversion.registry import get_source
from lerobot_unidextok.samples import write_samples

G1_HANDS = {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    out = tmp_path_factory.mktemp("pristine")
    return write_samples(out, episodes_per_source=1, frames_per_episode=20, seed=2)


@pytest.fixture
def samples(pristine, tmp_path):
    """A private copy per test, free to corrupt."""
    return {name: shutil.copytree(folder, tmp_path / name) for name, folder in pristine.items()}


def _truncate(path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def _first(name, folder, **options):
    src = get_source(name)(**options)
    return src, src.list_episodes(folder)[0]


# --------------------------------------------------------------------------------------------- dexycb
def test_dexycb_truncated_npz(samples):
    src, ref = _first("dexycb", samples["dexycb"])
    npz = sorted((samples["dexycb"]).rglob("836212060125/labels_000005.npz"))[0]
    _truncate(npz)
    with pytest.raises(ValueError, match=r"labels_000005\.npz.*'joint_3d'"):
        src.read_episode(ref)


def test_dexycb_missing_field_and_frame(samples):
    src, ref = _first("dexycb", samples["dexycb"])
    npz = next(samples["dexycb"].rglob("836212060125/labels_000003.npz"))
    np.savez(npz, joint_2d=np.zeros((1, 21, 2)))
    with pytest.raises(ValueError, match=r"labels_000003\.npz: missing field 'joint_3d'"):
        src.read_episode(ref)
    npz.unlink()
    with pytest.raises(ValueError, match=r"labels_000003\.npz: missing"):
        src.read_episode(ref)


def test_dexycb_meta_without_handedness(samples):
    src, ref = _first("dexycb", samples["dexycb"])
    meta_path = next(samples["dexycb"].rglob("meta.yml"))
    meta = yaml.safe_load(meta_path.read_text())
    del meta["mano_sides"]
    meta_path.write_text(yaml.safe_dump(meta))
    with pytest.raises(ValueError, match=r"meta\.yml: missing field 'mano_sides'"):
        src.read_episode(ref)


# --------------------------------------------------------------------------------------------- egodex
def test_egodex_truncated_hdf5(samples):
    src, ref = _first("egodex", samples["egodex"])
    from pathlib import Path

    _truncate(Path(ref), 0.3)
    with pytest.raises(ValueError, match=r"\.hdf5: (unreadable or truncated|cannot read)"):
        src.read_episode(ref)


def test_egodex_missing_joint(samples):
    src, ref = _first("egodex", samples["egodex"])
    with h5py.File(ref, "a") as f:
        del f["transforms/rightIndexFingerTip"]
    with pytest.raises(ValueError, match=r"\.hdf5: missing dataset 'transforms/rightIndexFingerTip'"):
        src.read_episode(ref)


def test_egodex_partial_confidences(samples):
    src, ref = _first("egodex", samples["egodex"])
    with h5py.File(ref, "a") as f:
        if "confidences/leftThumbTip" not in f:
            pytest.skip("sample file has no confidences")
        del f["confidences/leftThumbTip"]
    with pytest.raises(ValueError, match=r"confidences/ holds 20 of the 21 left hand joints"):
        src.read_episode(ref)


# --------------------------------------------------------------------------------------------- ROS bags
def test_let_truncated_bag_and_missing_topic(samples, tmp_path):
    from pathlib import Path

    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    src, ref = _first("let", samples["let"])
    _truncate(Path(ref), 0.4)
    with pytest.raises(ValueError, match=r"\.bag: (unreadable bag|topic)"):
        src.read_episode(ref)
    store = get_typestore(Stores.ROS1_NOETIC)  # a bag with the hand state but no command topic
    bag = tmp_path / "x-P4-dex_hand" / "only_state.bag"
    bag.parent.mkdir()
    js = store.types["sensor_msgs/msg/JointState"]
    hdr, stamp = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    with Writer(bag) as w:
        conn = w.add_connection("/dexhand/state", "sensor_msgs/msg/JointState", typestore=store)
        for k in range(5):
            msg = js(header=hdr(seq=k, stamp=stamp(sec=k, nanosec=0), frame_id=""), name=[], position=np.zeros(12),
                     velocity=np.zeros(0), effort=np.zeros(0))  # fmt: skip
            w.write(conn, k * 10**9, store.serialize_ros1(msg, "sensor_msgs/msg/JointState"))
    with pytest.raises(ValueError, match=r"only_state\.bag: missing topic '/control_robot_hand_position'"):
        src.read_episode(str(bag))


def test_let_unknown_folder_needs_hand_option(samples, tmp_path):
    import shutil

    src, ref = _first("let", samples["let"])
    odd = tmp_path / "odd" / "some_task" / "a.bag"
    odd.parent.mkdir(parents=True)
    shutil.copy(ref, odd)
    with pytest.raises(ValueError, match=r"cannot tell the hand of .*a\.bag .*pass hand=brainco_revo1"):
        get_source("let")().list_episodes(tmp_path / "odd")
    (ep_ref,) = get_source("let")(hand="brainco_revo1").list_episodes(tmp_path / "odd")
    assert get_source("let")(hand="brainco_revo1").read_episode(ep_ref).hands[0].hand == "brainco_revo1"


def test_linkerhand_wrong_width_for_model(samples):
    src = get_source("linkerhand")(model="L20")
    refs = src.list_episodes(samples["linkerhand"])
    bag = next(r for r in refs if r.endswith("episode_0000"))
    ep = src.read_episode(bag)  # the bag's /cb_<side>_hand_info says L10: it wins over the option
    assert ep.extra["hand_model"] == "L10,L10"


def test_linkerhand_lerobot_export(samples, tmp_path):
    """A LeRobot-style export with <side>_hand_joint_<k> names, mapped by model."""
    from lerobot_unidextok.samples.formats import _write_lerobot_v21

    rng = np.random.default_rng(0)
    names = [f"right_hand_joint_{k}" for k in range(10)]
    values = rng.integers(0, 256, size=(25, 10)).astype(np.float64)
    _write_lerobot_v21(
        tmp_path / "lh",
        30.0,
        "linkerhand_l10",
        {"observation.state": names, "action": names},
        [({"observation.state": values, "action": values}, "wave")],
    )
    with pytest.raises(ValueError, match="needs model="):
        get_source("linkerhand")().list_episodes(tmp_path / "lh")
    src = get_source("linkerhand")(model="L10")
    (ep,) = [src.read_episode(r) for r in src.list_episodes(tmp_path / "lh")]
    (hand,) = ep.hands
    assert hand.side == "right" and hand.hand == "linkerhand_l10" and ep.task == "wave"
    np.testing.assert_array_equal(hand.state_native, values)
    with pytest.raises(ValueError, match=r"right hand has joints .* expected 20 for L20"):
        src20 = get_source("linkerhand")(model="L20")
        src20.read_episode(src20.list_episodes(tmp_path / "lh")[0])


# --------------------------------------------------------------------------------------------- LeRobot layouts
def test_lerobot_truncated_and_missing_parquet(samples):
    src, ref = _first("lerobot", samples["lerobot"], hands=G1_HANDS)
    path = samples["lerobot"] / "data" / "chunk-000" / "episode_000000.parquet"
    _truncate(path)
    with pytest.raises(ValueError, match=r"episode_000000\.parquet: unreadable parquet"):
        src.read_episode(ref)
    path.unlink()
    with pytest.raises(ValueError, match=r"episode_000000\.parquet: data file of episode 0 is missing"):
        src.read_episode(ref)


def test_lerobot_info_without_names_or_feature(samples):
    src, ref = _first("lerobot", samples["lerobot"], hands=G1_HANDS)
    info_path = samples["lerobot"] / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"]["observation.state"]["names"] = None
    info_path.write_text(json.dumps(info))
    with pytest.raises(ValueError, match=r"info\.json features\['observation.state'\]: has no 'names'"):
        src.read_episode(ref)
    del info["features"]["observation.state"]
    info_path.write_text(json.dumps(info))
    with pytest.raises(ValueError, match=r"info\.json features\['observation.state'\]: missing"):
        src.read_episode(ref)
    del info["fps"]
    info_path.write_text(json.dumps(info))
    with pytest.raises(ValueError, match=r"info\.json: missing field 'fps'"):
        src.read_episode(ref)


def test_lerobot_names_in_dict_form(samples):
    """`names` given as {"motors": [...]} is flattened like a list."""
    src, ref = _first("lerobot", samples["lerobot"], hands=G1_HANDS)
    before = src.read_episode(ref)
    info_path = samples["lerobot"] / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    for key in ("observation.state", "action"):
        info["features"][key]["names"] = {"motors": info["features"][key]["names"][0]}
    info_path.write_text(json.dumps(info))
    after = src.read_episode(ref)
    np.testing.assert_array_equal(before.hands[1].state_native, after.hands[1].state_native)


def test_dexora_missing_hand_joint_names(samples):
    src, ref = _first("dexora", samples["dexora"])
    info_path = samples["dexora"] / "airbot_pick_and_place" / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    names = info["features"]["observation.state"]["names"]
    names[names.index("right_hand_joint_7_obs")] = "right_hand_joint_seven_obs"
    info_path.write_text(json.dumps(info))
    with pytest.raises(
        ValueError,
        match=r"info\.json features\['observation.state'\]: missing right hand joint names \['right_hand_joint_7'\]",
    ):
        src.read_episode(ref)


def test_not_a_lerobot_dataset(tmp_path):
    with pytest.raises(ValueError, match="no meta/info.json"):
        get_source("dexora")().list_episodes(tmp_path)


# --------------------------------------------------------------------------------------------- oakink2
def test_oakink2_needs_mano(tmp_path):
    anno = tmp_path / "anno_preview"
    anno.mkdir()
    frame = {
        f"{p}__{k}": np.zeros(s)
        for p in ("rh", "lh")
        for k, s in (("pose_coeffs", (1, 16, 4)), ("tsl", (1, 3)), ("betas", (1, 10)))
    }
    with open(anno / "seq_a.pkl", "wb") as f:
        pickle.dump({"mocap_frame_id_list": [0, 1], "raw_mano": {0: frame, 1: frame}}, f)
    src = get_source("oakink2")()
    (ref,) = src.list_episodes(tmp_path)
    with pytest.raises(RuntimeError, match="install the mano extra .* point --mano_assets to your licensed MANO files"):
        src.read_episode(ref)
    with pytest.raises(RuntimeError, match=r"MANO files \['MANO_RIGHT.pkl', 'MANO_LEFT.pkl'\] not found"):
        get_source("oakink2")(mano_assets=str(tmp_path)).read_episode(ref)
    _truncate(anno / "seq_a.pkl")
    with pytest.raises(ValueError, match=r"seq_a\.pkl: unreadable or truncated pickle"):
        src.read_episode(ref)
