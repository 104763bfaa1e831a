"""The synthetic sample generator: native layouts, determinism, labels, plausible gesture motion."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from lerobot_unidextok import udhm
from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.conversion.registry import get_source
from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, SAMPLE_SOURCES, write_samples
from lerobot_unidextok.samples.motion import GESTURES, gesture_track

EPISODES, FRAMES = 3, 45


@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    out = tmp_path_factory.mktemp("samples")
    return write_samples(out, episodes_per_source=EPISODES, frames_per_episode=FRAMES, seed=0)


def _source(name: str):
    return get_source(name)(**SAMPLE_SOURCE_OPTIONS.get(name, {}))


def test_every_source_written_with_synthetic_labels(samples):
    assert sorted(samples) == sorted(SAMPLE_SOURCES)
    for folder in samples.values():
        assert "SYNTHETIC" in (folder / "README.md").read_text()
        labels = json.loads((folder / "gestures.json").read_text())
        assert labels["synthetic"] is True and len(labels["episodes"]) == EPISODES
    info = json.loads((samples["lerobot"] / "meta" / "info.json").read_text())
    assert info["synthetic"] is True and info["codebase_version"] == "v2.1"
    with h5py.File(next(samples["egodex"].rglob("*.hdf5")), "r") as f:
        assert bool(f.attrs["synthetic"]) and "SYNTHETIC" in f.attrs["note"]
    assert bool(np.load(next(samples["dexycb"].rglob("labels_000000.npz")))["synthetic"])
    import pyarrow.parquet as pq

    for name in ("dexora", "lerobot"):
        meta = pq.read_schema(next(samples[name].rglob("episode_000000.parquet"))).metadata
        assert b"SYNTHETIC" in meta[b"unidextok_synthetic"]
    let_sidecar = next(samples["let"].rglob("*-P4-*/*.json"))  # annotation sidecar next to each bag
    assert json.loads(let_sidecar.read_text())["synthetic"] is True


def test_native_layouts(samples, tmp_path):
    d = samples["dexycb"]
    captures = sorted(d.glob("*/*/meta.yml"))
    assert len(captures) == EPISODES
    cap = captures[0].parent
    npz = np.load(next((cap / "836212060125").glob("labels_*.npz")))
    assert npz["joint_3d"].shape == (1, 21, 3) and npz["joint_2d"].shape == (1, 21, 2)
    assert np.load(cap / "pose.npz")["pose_m"].shape[1:] == (1, 51)
    with h5py.File(next(samples["egodex"].rglob("*.hdf5")), "r") as f:
        assert f["transforms/rightHand"].shape[1:] == (4, 4) and "transforms/camera" in f
        assert "transforms/leftLittleFingerMetacarpal" in f and f.attrs["llm_description"]
    assert len(list((samples["lerobot"] / "data" / "chunk-000").glob("episode_*.parquet"))) == EPISODES
    assert len(list(samples["dexora"].rglob("data/chunk-000/episode_*.parquet"))) == EPISODES
    scheme1 = json.loads((samples["dexora"] / "airbot_pick_and_place" / "meta" / "info.json").read_text())
    assert scheme1["features"]["observation.state"]["shape"] == [39]
    assert scheme1["features"]["action"]["names"][6] == "left_hand_joint_1"
    from lerobot_unidextok.samples import SampleSpec
    from lerobot_unidextok.samples.formats import write_dexora_episodes

    write_dexora_episodes(tmp_path, SampleSpec(2, 20, 0), scheme=2)
    scheme2 = json.loads((tmp_path / "airbot_dexterous" / "meta" / "info.json").read_text())
    assert (
        scheme2["features"]["states"]["shape"] == [36]
        and "left_hand_action_0" in scheme2["features"]["actions"]["names"]
    )
    g1 = json.loads((samples["lerobot"] / "meta" / "info.json").read_text())
    assert isinstance(g1["features"]["observation.state"]["names"][0], list)  # nested, as Unitree ports
    assert len(g1["features"]["observation.state"]["names"][0]) == 26


def test_deterministic_by_seed(tmp_path):
    a = write_samples(tmp_path / "a", sources=["let", "egodex"], episodes_per_source=2, frames_per_episode=30, seed=3)
    b = write_samples(tmp_path / "b", sources=["let", "egodex"], episodes_per_source=2, frames_per_episode=30, seed=3)
    c = write_samples(tmp_path / "c", sources=["let"], episodes_per_source=2, frames_per_episode=30, seed=4)
    for name in ("let", "egodex"):
        src = _source(name)
        for ra, rb in zip(src.list_episodes(a[name]), src.list_episodes(b[name]), strict=True):
            ea, eb = src.read_episode(ra), src.read_episode(rb)
            for ha, hb in zip(ea.hands, eb.hands, strict=True):
                np.testing.assert_array_equal(ha.state_native, hb.state_native)
    let = _source("let")
    ea = let.read_episode(let.list_episodes(a["let"])[0])
    ec = let.read_episode(let.list_episodes(c["let"])[0])
    assert ea.num_frames != ec.num_frames or not np.array_equal(ea.hands[0].state_native, ec.hands[0].state_native)


def test_bad_requests_raise(tmp_path):
    with pytest.raises(ValueError, match="unknown sample source"):
        write_samples(tmp_path, sources=["nope"])
    write_samples(tmp_path, sources=["let"], episodes_per_source=1, frames_per_episode=20)
    with pytest.raises(FileExistsError, match="overwrite"):
        write_samples(tmp_path, sources=["let"], episodes_per_source=1, frames_per_episode=20)


def test_gesture_track_is_smooth_coupled_and_labelled():
    rng = np.random.default_rng(0)
    track = gesture_track(rng, 600, 30.0)
    q = track.angles_rad
    assert q.shape == (600, UDHM_DIM) and len(track.labels) == 600
    assert set(track.labels) <= set(GESTURES) and len(set(track.labels)) >= 4
    assert not udhm.limit_violations(q).any()
    # smooth: no frame-to-frame jump beyond ~15 deg, and strongly autocorrelated unlike random angles
    assert np.degrees(np.abs(np.diff(q, axis=0))).max() < 15.0
    centred = q - q.mean(0)
    lag1 = (centred[1:] * centred[:-1]).sum() / (centred**2).sum()
    assert lag1 > 0.95
    # coupling: PIP follows MCP across the whole track
    idx = udhm.joint_index
    assert np.corrcoef(q[:, idx("middle_mcp_flex")], q[:, idx("middle_pip_flex")])[0, 1] > 0.9
    # held frames sit near their gesture's prototype
    held = np.flatnonzero(track.holding)
    protos = np.stack([GESTURES[track.labels[i]].angles_rad() for i in held])
    assert np.degrees(np.abs(q[held] - protos)).mean() < 6.0


def test_human_samples_decode_to_their_gesture_labels(samples):
    """IK on the DexYCB sample's keypoints gives back the labelled gesture on held frames."""
    names = list(GESTURES)
    protos = np.stack([GESTURES[n].angles_rad() for n in names])  # (G, 22)
    labels = json.loads((samples["dexycb"] / "gestures.json").read_text())["episodes"]
    src = _source("dexycb")
    hits = total = 0
    for ref in src.list_episodes(samples["dexycb"]):
        ep = src.read_episode(ref)
        hand = ep.hands[0]
        key = "/".join(ref.split("/")[-2:])
        lab = labels[key][hand.side]
        held = np.asarray(labels[key][f"{hand.side}_holding"]) & hand.valid
        assert [bool(x) for x in hand.valid] == [bool(x) for x in lab]  # '' label exactly where no hand
        kp = hand.state_native[held]
        res = udhm.inverse_kinematics(kp, side=hand.side)
        # bone lengths are constant within an episode (one person) and adult-sized
        palm = np.linalg.norm(kp[:, 9] - kp[:, 0], axis=-1)
        assert palm.std() < 1e-4 and 0.075 < palm.mean() < 0.13  # 99 mm x 0.85-1.15 x proportions
        nearest = np.argmin(np.abs(res.angles_rad[:, None] - protos[None]).sum(-1), axis=1)
        truth = [lab[i] for i in np.flatnonzero(held)]
        hits += sum(names[j] == t for j, t in zip(nearest, truth, strict=True))
        total += len(truth)
    assert total > 30 and hits / total > 0.9


def _truth(folder) -> dict[str, np.ndarray]:
    with np.load(folder / "udhm_truth.npz") as npz:
        return {k: npz[k] for k in npz.files}


@pytest.mark.parametrize("name", ["dexora", "lerobot"])
def test_robot_samples_store_their_udhm_truth(samples, name):
    """Commands read back from the native files map to the generating UDHM angles (per side, per column).
    The bag samples (let, linkerhand) are checked against their truth after resampling in test_sources."""
    from lerobot_unidextok import hands

    truth = _truth(samples[name])
    src = _source(name)
    for i, ref in enumerate(src.list_episodes(samples[name])):
        ep = src.read_episode(ref)
        key = f"episode_{i:06d}" if name == "lerobot" else f"{Path(ref.root).name}/episode_{ref.episode_index:06d}"
        for h in ep.hands:
            spec = hands.get(h.hand)
            q = truth[f"{key}|{h.side}"].astype(np.float64)
            expected = spec.to_udhm(spec.from_udhm(q, side=h.side), side=h.side)  # clipped into the hand's range
            got = spec.to_udhm(h.action_native, side=h.side)
            mask = spec.mask()
            # integer commands (0-100, 0-255) quantise; float sources are exact to float32
            tol = 1e-5
            assert np.abs(got[:, mask] - expected[:, mask]).max() < tol


def test_egodex_keypoints_invert_to_their_udhm_truth(samples):
    """IK on both hands of the EgoDex sample recovers the generating angles (left-hand mirroring included)."""
    truth = _truth(samples["egodex"])
    src = _source("egodex")
    ref = src.list_episodes(samples["egodex"])[0]
    ep = src.read_episode(ref)
    key = "/".join(ref.split("/")[-2:])
    for h in ep.hands:
        res = udhm.inverse_kinematics(h.state_native, side=h.side)
        err = np.degrees(np.abs(res.angles_rad - truth[f"{key}|{h.side}"]))
        assert err.mean() < 0.5, (h.side, err.mean())


def test_failed_write_leaves_nothing_behind(tmp_path, monkeypatch):
    from lerobot_unidextok.samples import formats as samples_mod

    def boom(folder, spec):
        (folder / "half.txt").write_text("x")
        raise RuntimeError("disk full")

    monkeypatch.setitem(samples_mod._WRITERS, "let", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_samples(tmp_path, sources=["let"], episodes_per_source=1, frames_per_episode=20)
    assert list(tmp_path.iterdir()) == []  # no target folder, no partial folder


def test_sources_whose_extra_is_missing_are_left_out_with_the_install_command(monkeypatch):
    """A plain install has no h5py (extra `egodex`) and no rosbags (extra `ros`): the demo converted every
    sample and failed with ModuleNotFoundError: h5py. Now those samples are left out, each with a note."""
    import importlib.util

    from lerobot_unidextok.samples import SAMPLE_SOURCES, available_sample_sources

    assert available_sample_sources() == (list(SAMPLE_SOURCES), [])  # the dev install has every extra
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name in ("h5py", "rosbags")
                        else real_find_spec(name, *a))  # fmt: skip
    available, notes = available_sample_sources()
    assert available == ["dexycb", "dexora", "lerobot"]
    assert notes[0] == "egodex: skipped, it needs h5py (pip install 'lerobot_policy_unidextok[egodex]')"
    assert [n.split(":")[0] for n in notes] == ["egodex", "let", "linkerhand"] and "[ros]" in notes[1]
