"""`unidextok-convert --source=retarget`: human motion -> a robot-hand LeRobotDataset, written and reloaded."""

import json

import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.data import load_udhm_frames
from lerobot_unidextok.retarget import HandRetargeter


def _empty(folder):
    """An input folder apart from the output (a root inside the input is refused)."""
    folder.mkdir(exist_ok=True)
    return folder


def test_keypoint_files_to_robot_dataset(urdf_dir, human_clip, tmp_path):
    """Two real keypoint clips become two LinkerHand L10 episodes whose UDHM states are the retargeter's."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    src = tmp_path / "kp"
    src.mkdir()
    np.save(src / "a.npy", human_clip[:40])
    np.save(src / "b.npy", human_clip[300:345])
    opts = {"hand": "linkerhand_l10", "urdf": str(urdf_dir)}
    root = tmp_path / "l10"
    report = convert(ConvertOptions(source="retarget", input=src, root=root, repo_id="t/l10_retargeted",
                                    source_options=opts, progress=False, test_fraction=0.0))  # fmt: skip
    assert report.num_episodes == 2 and report.num_frames == 85 and report.hands == ["linkerhand_l10"]
    ds = LeRobotDataset("t/l10_retargeted", root=root)
    assert ds.num_episodes == 2 and ds.num_frames == 85
    frames = load_udhm_frames(root)
    assert set(frames.hands.tolist()) == {"linkerhand_l10"}
    expected = HandRetargeter("linkerhand_l10", urdf_dir, "right").retarget(human_clip[:40]).udhm_rad
    np.testing.assert_allclose(frames.states_rad[frames.episode_index == 0], expected, atol=1e-5)


def test_human_dataset_to_robot_dataset(urdf_dir, tmp_path):
    """A converted human dataset (sample DexYCB, UDHM) -> XHand1: every human frame gets a robot frame."""
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["dexycb"], episodes_per_source=2, frames_per_episode=20)
    human = tmp_path / "human"
    convert(ConvertOptions(source="dexycb", input=raw["dexycb"], root=human, repo_id="t/human", progress=False))
    robot = tmp_path / "xhand"
    report = convert(ConvertOptions(source="retarget", input=human, root=robot, repo_id="t/xhand",
                                    source_options={"hand": "xhand1", "urdf": str(urdf_dir)}, progress=False))  # fmt: skip
    h, r = load_udhm_frames(human), load_udhm_frames(robot)
    assert len(r) == len(h) and report.num_episodes == 2
    assert set(r.hands.tolist()) == {"xhand1"} and not r.masks[:, 17].any()  # XHand1 has no pinky twist
    assert np.abs(r.states_rad).max() > 0.1  # the robot moves


def test_retarget_source_errors(tmp_path, urdf_dir):
    with pytest.raises(ValueError, match="needs the target hand and its URDF"):
        convert(ConvertOptions(source="retarget", input=_empty(tmp_path / "in"), root=tmp_path / "o", progress=False))
    (tmp_path / "x.json").write_text(json.dumps({}))
    from lerobot_unidextok.conversion.pipeline import ConversionError

    with pytest.raises((ValueError, ConversionError), match="keypoint .npy files|converted human dataset"):
        convert(ConvertOptions(source="retarget", input=tmp_path / "x.json", root=tmp_path / "o", progress=False,
                               source_options={"hand": "xhand1", "urdf": str(urdf_dir)}))  # fmt: skip
    assert not (tmp_path / "o").exists()


def test_one_side_of_a_two_hand_dataset_needs_only_that_urdf(urdf_dir, human_clip, tmp_path):
    """`side=right` on a human dataset with both hands retargets the right hand alone, with only the right
    URDF given. Catches the source that retargeted every side and so demanded the left URDF as well."""
    kp = tmp_path / "kp"
    kp.mkdir()
    right = human_clip[:30]
    np.savez(kp / "both.npz", right=right, left=right * np.array([-1.0, 1.0, 1.0]), fps=np.array(30.0))  # mirrored
    human = tmp_path / "human"
    convert(ConvertOptions(source="keypoints", input=kp, root=human, repo_id="t/human2", progress=False))
    assert set(load_udhm_frames(human).side.tolist()) == {"left", "right"}
    right_urdf = sorted(urdf_dir.rglob("xhand_right.urdf"))[0]  # the right URDF file alone
    robot = tmp_path / "xhand_right"
    opts = {"hand": "xhand1", "urdf": str(right_urdf), "side": "right"}
    report = convert(ConvertOptions(source="retarget", input=human, root=robot, repo_id="t/xr", source_options=opts,
                                    progress=False, test_fraction=0.0))  # fmt: skip
    frames = load_udhm_frames(robot)
    assert report.num_frames == 30 and set(frames.side.tolist()) == {"right"} and set(frames.hands) == {"xhand1"}
    h = load_udhm_frames(human)
    human_right = np.asarray(hands.get("human").from_udhm(h.states_rad[h.side == "right"].astype(np.float64), "right"))
    expected = HandRetargeter("xhand1", right_urdf, "right").retarget(human_right).udhm_rad
    np.testing.assert_allclose(frames.states_rad, expected, atol=1e-5)
