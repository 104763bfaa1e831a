"""conversion.mapping: trimming frames without a hand keeps every other stream aligned; the dataset layout.

A source episode often starts and ends with the hand untracked. Those frames are cut from the hands, the
arm columns, the copied features and the video segment alike; a stream cut differently would shift the
robot against its hands by a few frames, silently.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest

from lerobot_unidextok.conversion.episode import HandStream, Passthrough, RawEpisode, VideoSegment
from lerobot_unidextok.conversion.mapping import EpisodeError, map_episode, to_sides

NUM, FPS = 20, 30.0
HEAD, TAIL = 2, 3  # frames without a tracked hand at the start and the end


def _episode(side: str = "right") -> RawEpisode:
    t = np.linspace(0.0, 1.0, NUM)[:, None]
    values = 0.55 + 0.35 * np.sin(2 * np.pi * t + np.arange(6))  # normalised 0-1 Unitree Inspire values
    valid = np.ones(NUM, dtype=bool)
    valid[:HEAD] = valid[NUM - TAIL :] = False
    arm = np.arange(NUM * 2, dtype=np.float32).reshape(NUM, 2)  # row i holds 2i, 2i + 1
    return RawEpisode(
        source_file="episode_000.parquet",
        fps=FPS,
        hands=[HandStream(side, "inspire_rh56_unitree", values, values, valid=valid)],
        passthrough={"observation.state": Passthrough(("arm_a", "arm_b"), arm)},
        copied={"observation.frame_id": pa.array(np.arange(NUM) + 100)},
        copied_features={"observation.frame_id": {"dtype": "int64", "shape": (1,), "names": None}},
        videos={"observation.images.cam": VideoSegment("videos/cam/file-000.mp4", 10.0, 10.0 + NUM / FPS)},
    )


def test_frames_without_a_hand_are_cut_from_every_stream_alike():
    """Catches a copied column sliced to the wrong length (`last - first` -> `last + first` copies frames of
    the trailing cut) and a video segment shifted by frames times fps instead of frames / fps."""
    ep = map_episode(_episode())
    kept = np.arange(HEAD, NUM - TAIL)
    assert ep.num_frames == len(kept) == 15 and ep.trimmed_frames == HEAD + TAIL
    np.testing.assert_array_equal(ep.passthrough["observation.state"].values[:, 0], 2 * kept)
    assert ep.copied["observation.frame_id"].to_pylist() == (kept + 100).tolist()
    video = ep.videos["observation.images.cam"]
    assert video.path == "videos/cam/file-000.mp4"
    assert video.from_s == pytest.approx(10.0 + HEAD / FPS) and video.to_s == pytest.approx(10.0 + (NUM - TAIL) / FPS)
    assert ep.mask[:, :22].any(axis=1).all()  # every kept frame has the hand


def test_to_layout_adds_the_missing_side_as_an_absent_hand():
    """A right-hand-only episode in a (left, right) dataset: the left block is zeros with a False mask, the
    right block is unchanged, and the absent frames are counted. Catches an absent block marked present
    (mask filled with True) and a wrong absent-frame count."""
    ep = map_episode(_episode("right"))
    both = to_sides(ep, ("left", "right"))
    assert both.sides == ("left", "right") and both.hands == (ep.hands[0], ep.hands[0])
    assert not both.state_rad[:, :22].any() and not both.mask[:, :22].any()
    assert not both.action_rad[:, :22].any()
    np.testing.assert_array_equal(both.state_rad[:, 22:], ep.state_rad)
    np.testing.assert_array_equal(both.mask[:, 22:], ep.mask)
    assert both.absent_hand_frames == ep.absent_hand_frames + ep.num_frames
    assert both.hand_columns == ((None, None), ep.hand_columns[0])
    assert to_sides(ep, ("right",)) is ep
    with pytest.raises(EpisodeError, match=r"hand side\(s\) \['right'\] outside the dataset layout \('left',\)"):
        to_sides(ep, ("left",))
