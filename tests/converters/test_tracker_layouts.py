"""One hand, one UDHM through the real readers: the synthetic hand of tests/fixtures/tracker_layouts.py written
as an EgoDex HDF5 file (ARKit joints, wrist on the forearm's twist axis) and as a MediaPipe-layout keypoint
file gives the same UDHM abductions after `read_episode` + `map_episode`, for both hands.

With z = wrist -> middle MCP the EgoDex file read every finger of the right hand 13.7 deg toward the little
finger (the real EgoDex recordings of issue 24: -14.6 to -18.9 deg) and the MediaPipe file 0 deg.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from tracker_layouts import arkit_joints_m, mano21_keypoints_m

from lerobot_unidextok.conversion.mapping import map_episode
from lerobot_unidextok.conversion.registry import get_source
from lerobot_unidextok.udhm.joints import joint_index

FRAMES = 6
DEVIATION_DEG = 15.0  # hand turned toward the little finger on the forearm, the resting posture
ABD = [joint_index(f"{f}_mcp_abd") for f in ("index", "middle", "ring", "pinky")]
MIRROR = np.diag([-1.0, 1.0, 1.0])  # a left hand is the mirror image of the right one


def _world_poses(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rot = Rotation.random(FRAMES, random_state=seed).as_matrix()
    return rot, np.random.default_rng(seed).normal(scale=0.3, size=(FRAMES, 3)) + (0.0, 1.0, 0.0)


def _in_world(points_m: np.ndarray, side: str, seed: int) -> np.ndarray:
    """(K, 3) hand-frame points -> (T, K, 3) world points, one rigid pose per frame; left = mirrored."""
    rot, pos = _world_poses(seed)
    local = points_m @ MIRROR if side == "left" else points_m
    return local[None] @ np.swapaxes(rot, -1, -2) + pos[:, None, :]


def _write_egodex(path, seed: int) -> None:
    h5py = pytest.importorskip("h5py", reason="the egodex source needs h5py (egodex extra)")
    joints = {
        name: p for name, p in arkit_joints_m(deviation_deg=DEVIATION_DEG).items() if not name.startswith("Forearm")
    }
    names, points = list(joints), np.stack(list(joints.values()))  # 25 ARKit hand joints, hand frame
    with h5py.File(path, "w") as f:
        for side in ("left", "right"):
            world = _in_world(points, side, seed)  # (T, 25, 3)
            for k, name in enumerate(names):
                pose = np.tile(np.eye(4), (FRAMES, 1, 1))
                pose[:, :3, 3] = world[:, k]
                f.create_dataset(f"transforms/{side}{name}", data=pose.astype(np.float32))


def _write_mediapipe_npz(path, seed: int) -> None:
    kp = mano21_keypoints_m("mediapipe", deviation_deg=DEVIATION_DEG)
    np.savez(path, right=_in_world(kp, "right", seed), left=_in_world(kp, "left", seed + 1), fps=30)


def _abductions_deg(source: str, ref: str) -> dict[str, np.ndarray]:
    episode = map_episode(get_source(source)().read_episode(ref))
    state = np.degrees(episode.state_rad.astype(np.float64))  # (T, 22 * H)
    return {side: state[:, 22 * i : 22 * (i + 1)][:, ABD] for i, side in enumerate(episode.sides)}


def test_egodex_and_mediapipe_files_of_one_hand_give_the_same_udhm(tmp_path):
    _write_egodex(tmp_path / "episode.hdf5", seed=1)
    _write_mediapipe_npz(tmp_path / "episode.npz", seed=2)
    egodex = _abductions_deg("egodex", str(tmp_path / "episode.hdf5"))
    mediapipe = _abductions_deg("keypoints", str(tmp_path / "episode.npz"))
    assert set(egodex) == set(mediapipe) == {"left", "right"}
    for side in ("left", "right"):
        # the fingers-together hand: 0 deg for all four fingers (float32 dataset values, 0.05 mm IK fit)
        np.testing.assert_allclose(egodex[side], 0.0, atol=0.3, err_msg=f"egodex {side}")
        np.testing.assert_allclose(mediapipe[side], egodex[side], atol=0.3, err_msg=side)
