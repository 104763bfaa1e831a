"""One hand, one UDHM: the same synthetic hand laid out as MANO, MediaPipe, WebXR/OpenXR and ARKit define their
joints (tests/fixtures/tracker_layouts.py) reads the same MCP abductions, whatever the tracker's wrist point.

With z = wrist -> middle MCP (the frame before the knuckle row set it), the OpenXR/ARKit layouts, whose wrist
sits on the forearm's twist axis beside the ulna, read every finger 11.2 deg (13.7 deg with the hand turned
toward the little finger) toward the little finger, and the thumb's CMC spread 11-14 deg smaller.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from tracker_layouts import LAYOUTS, mano21_keypoints_m

from lerobot_unidextok import udhm
from lerobot_unidextok.udhm.joints import joint_index

ABD = [joint_index(f"{f}_mcp_abd") for f in ("index", "middle", "ring", "pinky")]
SPREAD_DEG = {"index": 12.0, "middle": 0.0, "ring": -8.0, "little": -15.0}
# MediaPipe's wrist sits on the palmar skin, which tilts the fitted palm plane by 8 deg: abductions are then
# read in a slightly tilted plane (0.16 deg at 15 deg of spread), the thumb's CMC spread 1.9 deg apart.
SAME_DEG = 0.3
THUMB_SAME_DEG = 2.5


@pytest.mark.parametrize("deviation_deg", [0.0, 15.0])
@pytest.mark.parametrize("spread", [None, SPREAD_DEG], ids=["together", "spread"])
def test_every_tracker_layout_reads_the_same_abductions(deviation_deg, spread):
    expected = np.array([0.0, 0.0, 0.0, 0.0]) if spread is None else np.array(list(spread.values()))
    readings = {}
    for layout in LAYOUTS:
        res = udhm.inverse_kinematics(mano21_keypoints_m(layout, spread, deviation_deg))
        assert res.residual_m < 1e-4, layout  # straight fingers: UDHM fits the layout to 0.05 mm
        readings[layout] = np.degrees(res.angles_rad)
        np.testing.assert_allclose(readings[layout][ABD], expected, atol=SAME_DEG, err_msg=layout)
    thumb = [r[joint_index("thumb_cmc_spread")] for r in readings.values()]
    assert max(thumb) - min(thumb) < THUMB_SAME_DEG


def test_layouts_differ_only_in_the_wrist_point():
    """The fixture's layouts share every knuckle and finger joint, so the test above is about the wrist alone."""
    kp = {layout: mano21_keypoints_m(layout, SPREAD_DEG, 15.0) for layout in LAYOUTS}
    for layout in LAYOUTS:
        np.testing.assert_array_equal(kp[layout][1:], kp["mano"][1:])
    wrists = np.stack([kp[layout][0] for layout in LAYOUTS])
    assert np.linalg.norm(wrists - wrists[0], axis=-1).max() > 0.02  # the wrist points are centimetres apart


def test_the_reading_does_not_move_with_the_wrist_in_the_palm_plane(rng):
    """Any wrist point in the palm plane, in any camera frame and for either side: the same abductions."""
    base = mano21_keypoints_m("mano", SPREAD_DEG)
    offsets = np.concatenate([np.zeros((40, 1)), rng.uniform(-0.03, 0.03, size=(40, 2))], axis=1)  # (0, y, z) m
    kp = np.repeat(base[None], 40, axis=0)
    kp[:, 0] += offsets
    rot = Rotation.random(40, random_state=3).as_matrix()
    world = kp @ np.swapaxes(rot, -1, -2) + rng.normal(scale=0.5, size=(40, 1, 3))
    right = np.degrees(udhm.inverse_kinematics(world).angles_rad[:, ABD])
    np.testing.assert_allclose(right, np.broadcast_to(list(SPREAD_DEG.values()), right.shape), atol=0.2)
    left = np.degrees(udhm.inverse_kinematics(world * np.array([-1.0, 1.0, 1.0]), side="left").angles_rad[:, ABD])
    np.testing.assert_allclose(left, right, atol=1e-9)
