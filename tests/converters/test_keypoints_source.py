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
from lerobot_unidextok.data import load_udhm_frames
from lerobot_unidextok.samples.motion import gesture_track


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
    src = get_source("keypoints")(side="right")  # no fps: every file keeps its own integer rate
    refs = src.list_episodes(tmp_path)
    assert [r.rsplit("/", 1)[1] for r in refs] == ["both.npz", "clip_a.npy", "mp.json", "take_left.npy", "web.json"]
    with pytest.raises(ValueError, match=r"take_left\.npy: no frame rate"):
        src.read_episode(str(tmp_path / "take_left.npy"))
    eps = {r.rsplit("/", 1)[1]: src.read_episode(r) for r in refs if "take_left" not in r and "web" not in r}
    assert [(h.side, e.fps) for h in eps["clip_a.npy"].hands for e in [eps["clip_a.npy"]]] == [("right", 25.0)]
    assert sorted(h.side for h in eps["both.npz"].hands) == ["left", "right"] and eps["both.npz"].fps == 20.0
    mp = eps["mp.json"]
    assert mp.fps == 15.0 and mp.hands[0].side == "right" and not mp.hands[0].valid[[3, 4]].any()
    np.testing.assert_allclose(mp.hands[0].state_native[5], right[5])
    with_fps = get_source("keypoints")(fps=30)  # fps: the rate of files that state none (and the output grid)
    take_left = with_fps.read_episode(str(tmp_path / "take_left.npy"))
    assert take_left.hands[0].side == "left" and take_left.fps == 30.0 and take_left.num_frames == len(left)
    assert with_fps.read_episode(str(tmp_path / "web.json")).hands[0].side == "left"
    res = udhm.inverse_kinematics(eps["clip_a.npy"].hands[0].state_native, side="right")
    assert np.degrees(np.abs(res.angles_rad - truth)).mean() < 1.0  # the keypoints reach the IK unchanged


def _smooth_angles_rad(t_s: np.ndarray) -> np.ndarray:
    """(T, 22) UDHM angles of a slow continuous motion inside the joint limits, at times `t_s`."""
    lo, hi = udhm.JOINT_LIMITS_RAD[:, 0], udhm.JOINT_LIMITS_RAD[:, 1]
    phase = np.linspace(0.0, 2.0 * np.pi, 22, endpoint=False)
    return (lo + hi) / 2 + 0.25 * (hi - lo) * np.sin(2 * np.pi * 0.4 * t_s[:, None] + phase)


def _keypoints_at(t_s: np.ndarray, side: str = "right") -> np.ndarray:
    n = len(t_s)
    pose = (np.tile(np.eye(3), (n, 1, 1)), np.tile([0.1, 0.0, 0.5], (n, 1)))
    return np.asarray(udhm.forward_kinematics(_smooth_angles_rad(t_s), None, pose, side=side), dtype=np.float64)


@pytest.mark.parametrize(
    ("rate_hz", "frames", "fps", "out_fps", "out_frames"),
    [
        (29.97, 90, None, 30, 90),  # NTSC video tracker, no --fps: the rounded rate
        (29.97, 90, 30, 30, 90),
        (60.0, 91, 30, 30, 46),  # an integer rate other than --fps is resampled too
        (115.3, 200, 30, 30, 52),  # a headset hand tracker
    ],
)
def test_tracker_rates_are_resampled_onto_fps(tmp_path, rate_hz, frames, fps, out_fps, out_frames):
    """Real tracker rates (29.97 Hz video, 54-115 Hz headsets) go onto the integer --fps grid (or the rounded
    rate): the converted angles equal the motion's own angles at the grid times. Catches the reader that
    refused 'fps 29.97 is not an integer' and ignored --fps for files that state their rate."""
    raw = tmp_path / "raw"
    raw.mkdir()
    t_src = np.arange(frames) / rate_hz
    np.save(raw / "take_right.npy", _keypoints_at(t_src))
    (raw / "take_right.json").write_text(json.dumps({"fps": rate_hz}))
    root = tmp_path / "out"
    convert(ConvertOptions(source="keypoints", input=raw, root=root, fps=fps, progress=False, test_fraction=0.0))
    out = load_udhm_frames(root)
    assert out.fps == out_fps and len(out) == out_frames
    from lerobot_unidextok import hands

    truth = hands.get("human").to_udhm(_keypoints_at(np.arange(out_frames) / out_fps), "right")
    err_deg = np.degrees(np.abs(out.states_rad - truth))
    assert err_deg.mean() < 0.05 and err_deg.max() < 1.0, (err_deg.mean(), err_deg.max())
    from lerobot_unidextok.data import load_record

    (record,) = load_record(root).to_dict()["episodes"]
    assert (record["source_fps"], record["resampled_fps"]) == (rate_hz, out_fps)


def test_resampling_keeps_undetected_frames_absent(tmp_path):
    """A 29.97 Hz MediaPipe JSON with undetected frames: the grid frames next to them are absent, not bridged."""
    t_src = np.arange(60) / 29.97
    kp = _keypoints_at(t_src)
    frames = _mediapipe_frames({"Right": kp}, drop=(20, 21))
    (tmp_path / "mp.json").write_text(json.dumps({"fps": 29.97, "frames": frames}))
    ep = get_source("keypoints")().read_episode(str(tmp_path / "mp.json"))
    (hand,) = ep.hands
    assert ep.fps == 30.0 and ep.num_frames == 60
    t_out = np.arange(60) / 30.0
    expect_absent = (t_out > 19 / 29.97) & (t_out < 22 / 29.97)  # between the last and next detected frames
    np.testing.assert_array_equal(~hand.valid, expect_absent)


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


def test_constant_fill_frames_are_missing_and_a_bad_frame_is_named_by_its_own_number(tmp_path, caplog):
    """DexYCB's toolkit fills the frames of a hand it did not see with -1: such frames (21 coincident keypoints)
    used to reach the inverse kinematics and fail as "degenerate palm in frames [0, 1, 16]", numbered among the
    present frames only and with no word that NaN marks a missing frame. Now they are missing frames, said
    once; a genuinely degenerate frame is named by its frame number in the file."""
    import logging

    kp, _ = _hand("right", n=40)
    filled = kp.copy()
    filled[[3, 4, 20]] = -1.0
    (tmp_path / "fill").mkdir()
    np.save(tmp_path / "fill" / "clip_right.npy", filled)
    (tmp_path / "fill" / "clip_right.json").write_text(json.dumps({"fps": 30}))
    with caplog.at_level(logging.WARNING):
        report = convert(ConvertOptions(source="keypoints", input=tmp_path / "fill", root=tmp_path / "out",
                                        progress=False))  # fmt: skip
    assert report.num_frames == 40 and "3 of 40 frames hold 21 coincident keypoints (value -1" in caplog.text
    rows = load_udhm_frames(root=tmp_path / "out")
    present = set(rows.frame_index[(rows.side == "right") & rows.masks.any(axis=1)].tolist())
    assert not present & {3, 4, 20} and {0, 5, 21} <= present

    bad = kp.copy()
    bad[:, :] = np.nan
    bad[10:30] = kp[10:30]
    bad[25, [5, 9, 13, 17]] = bad[25, 0]  # knuckles on the wrist: no palm
    folder = tmp_path / "degenerate"
    folder.mkdir()
    np.save(folder / "clip_right.npy", bad)
    (folder / "clip_right.json").write_text(json.dumps({"fps": 30}))
    with pytest.raises(Exception, match=r"degenerate palm .* in frames \[25\].*; a frame without a hand must be NaN"):
        convert(ConvertOptions(source="keypoints", input=folder, root=tmp_path / "out2", progress=False))


def test_a_truncated_npy_is_named_as_such(tmp_path):
    kp, _ = _hand("right", n=40)
    np.save(tmp_path / "whole.npy", kp)
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "cut_right.npy").write_bytes((tmp_path / "whole.npy").read_bytes()[:3000])
    (tmp_path / "in" / "cut_right.json").write_text(json.dumps({"fps": 30}))
    with pytest.raises(Exception, match=r"cut_right.npy: not a readable .npy file .*truncated"):
        convert(ConvertOptions(source="keypoints", input=tmp_path / "in", root=tmp_path / "out", progress=False))
