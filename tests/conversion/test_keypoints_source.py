"""`--source=keypoints`: .npy / .npz arrays and MediaPipe JSON results, with unit and handedness checks.

Fixture keypoints come from UDHM forward kinematics of gesture tracks (a right and a mirrored left hand,
in metres); the MediaPipe JSON is written in the field names of MediaPipe's Python and web APIs.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_unidextok import udhm
from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.conversion.registry import get_source
from lerobot_unidextok.conversion.sample_motion import gesture_track
from lerobot_unidextok.data import load_udhm_frames


def _hand(side: str, n: int = 40, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    track = gesture_track(rng, n, 30.0)
    rot = np.tile(np.eye(3), (n, 1, 1))
    pos = np.tile([0.1 if side == "right" else -0.1, 0.0, 0.5], (n, 1))
    kp = np.asarray(udhm.forward_kinematics(track.angles_rad, None, (rot, pos), side=side), dtype=np.float64)
    return kp, track.angles_rad


def _mediapipe_frames(kp_by_label: dict[str, np.ndarray], web: bool = False, drop: tuple[int, ...] = ()) -> list:
    n = len(next(iter(kp_by_label.values())))
    frames = []
    for t in range(n):
        hands = [(label, kp[t]) for label, kp in kp_by_label.items() if t not in drop]
        cats = [
            [{"score": 0.98, "index": 0, "category_name" if not web else "categoryName": label}] for label, _ in hands
        ]
        world = [[{"x": float(x), "y": float(y), "z": float(z)} for x, y, z in kp] for _, kp in hands]
        frames.append(
            {"handednesses": cats, "worldLandmarks": world}
            if web
            else {"handedness": cats, "hand_world_landmarks": world}
        )
    return frames


def test_npy_with_sidecar_npz_keys_and_mediapipe_json(tmp_path):
    right, truth = _hand("right")
    left, _ = _hand("left", seed=1)
    np.save(tmp_path / "clip_a.npy", right)
    (tmp_path / "clip_a.json").write_text(json.dumps({"fps": 25}))  # sidecar: not an episode
    np.save(tmp_path / "take_left.npy", left)  # side from the file name
    np.savez(tmp_path / "both.npz", kp_right=right, left_hand=left, fps=np.array(20.0))
    (tmp_path / "mp.json").write_text(
        json.dumps({"fps": 15, "frames": _mediapipe_frames({"Right": right}, drop=(3, 4))})
    )
    (tmp_path / "web.json").write_text(json.dumps(_mediapipe_frames({"Left": left}, web=True)))
    src = get_source("keypoints")(side="right", fps=30)
    refs = src.list_episodes(tmp_path)
    assert [r.rsplit("/", 1)[1] for r in refs] == ["both.npz", "clip_a.npy", "mp.json", "take_left.npy", "web.json"]
    eps = {r.rsplit("/", 1)[1]: src.read_episode(r) for r in refs}
    assert [(h.side, e.fps) for h in eps["clip_a.npy"].hands for e in [eps["clip_a.npy"]]] == [("right", 25.0)]
    assert eps["take_left.npy"].hands[0].side == "left" and eps["take_left.npy"].fps == 30.0  # option fps
    assert sorted(h.side for h in eps["both.npz"].hands) == ["left", "right"] and eps["both.npz"].fps == 20.0
    mp = eps["mp.json"]
    assert mp.fps == 15.0 and mp.hands[0].side == "right" and not mp.hands[0].valid[[3, 4]].any()
    np.testing.assert_allclose(mp.hands[0].state_native[5], right[5])
    assert eps["web.json"].hands[0].side == "left"
    res = udhm.inverse_kinematics(eps["clip_a.npy"].hands[0].state_native, side="right")
    assert np.degrees(np.abs(res.angles_rad - truth)).mean() < 1.0  # the keypoints reach the IK unchanged


def test_units_and_handedness_are_checked(tmp_path):
    right, _ = _hand("right")
    np.save(tmp_path / "mm_right.npy", right * 1000)
    src = get_source("keypoints")(fps=30)
    with pytest.raises(ValueError, match=r"mm_right\.npy: .*a hand in mm: pass units='mm'"):
        src.read_episode(str(tmp_path / "mm_right.npy"))
    ep = get_source("keypoints")(fps=30, units="mm").read_episode(str(tmp_path / "mm_right.npy"))
    np.testing.assert_allclose(ep.hands[0].state_native, right)
    np.save(tmp_path / "wrong_left.npy", right)  # a right hand labelled left by its name
    with pytest.raises(ValueError, match=r"labelled left but the keypoints fit a right hand"):
        src.read_episode(str(tmp_path / "wrong_left.npy"))
    assert get_source("keypoints")(fps=30, check_handedness=False).read_episode(str(tmp_path / "wrong_left.npy"))
    (tmp_path / "selfie.json").write_text(json.dumps(_mediapipe_frames({"Left": right})))  # legacy mirrored label
    with pytest.raises(ValueError, match="swap_handedness=true"):
        src.read_episode(str(tmp_path / "selfie.json"))
    swapped = get_source("keypoints")(fps=30, swap_handedness=True).read_episode(str(tmp_path / "selfie.json"))
    assert swapped.hands[0].side == "right"
    image_only = [
        {"handedness": [[{"category_name": "Right"}]], "hand_landmarks": [[{"x": 0.5, "y": 0.5, "z": 0.0}] * 21]}
    ]
    (tmp_path / "image.json").write_text(json.dumps(image_only))
    with pytest.raises(ValueError, match="only normalised image landmarks"):
        src.read_episode(str(tmp_path / "image.json"))
    np.save(tmp_path / "nohand.npy", right)
    with pytest.raises(ValueError, match="which hand"):
        get_source("keypoints")(fps=30).read_episode(str(tmp_path / "nohand.npy"))
    np.save(tmp_path / "flat_right.npy", right.reshape(40, 63))
    with pytest.raises(ValueError, match=r"shape \(40, 63\), expected \(T, 21, 3\)"):
        src.read_episode(str(tmp_path / "flat_right.npy"))


def test_converts_into_udhm_dataset(tmp_path):
    raw = tmp_path / "raw"
    raw.mkdir()
    np.save(raw / "a_right.npy", _hand("right")[0])
    np.save(raw / "b_left.npy", _hand("left", seed=2)[0])
    report = convert(ConvertOptions(source="keypoints", input=raw, root=tmp_path / "out", fps=30, progress=False))
    frames = load_udhm_frames(tmp_path / "out")
    assert report.num_episodes == 2 and frames.fps == 30 and set(frames.side) == {"right", "left"}
    assert set(frames.hands) == {"human"} and frames.masks.all()


def test_real_mediapipe_outputs(real_data_dir, tmp_path):
    """Real MediaPipe world landmarks: the 621-frame right-hand clip and MediaPipe's own test results."""
    clip = np.load(real_data_dir / "dex-retargeting" / "human_joint_right.npy")
    np.save(tmp_path / "clip_right.npy", clip)
    ep = get_source("keypoints")(fps=30).read_episode(str(tmp_path / "clip_right.npy"))  # units and side pass
    assert ep.hands[0].side == "right" and ep.num_frames == 621
    fixtures = json.loads((real_data_dir / "mediapipe" / "mediapipe_hand_fixtures.json").read_text())
    poses = {k: v for k, v in fixtures.items() if isinstance(v, dict) and "world_landmarks_m" in v}
    kp = np.stack([np.asarray(v["world_landmarks_m"]) for v in poses.values()])
    (tmp_path / "mp.json").write_text(json.dumps(_mediapipe_frames({"Right": kp})))
    ep = get_source("keypoints")(fps=30).read_episode(str(tmp_path / "mp.json"))
    assert ep.hands[0].side == "right" and ep.num_frames == len(poses)
