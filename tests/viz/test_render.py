"""The viewer's frames: each side drawn as that side, full joint names inside the figure, hands framed to
their extent at one scale, and frames blitted onto a fixed background equal to a fresh render."""

import numpy as np
import pytest
from robot_udhm import INSPIRE

from lerobot_unidextok import udhm
from lerobot_unidextok.constants import KEYPOINT_NAMES, UDHM_JOINT_NAMES
from lerobot_unidextok.udhm.frames import MIRROR_Y
from lerobot_unidextok.viz.episode import load_episode, view_states
from lerobot_unidextok.viz.render import VIEWS, EpisodeRenderer, camera_axes

THUMB_TIP, PINKY_TIP = KEYPOINT_NAMES.index("thumb_tip"), KEYPOINT_NAMES.index("pinky_tip")


@pytest.fixture(scope="module")
def g1_view(g1_like):
    return load_episode(g1_like["root"], episode=0, stride=2)  # two Inspire hands, left and right


def test_the_left_hand_is_drawn_as_the_mirror_image_of_the_right(g1_view):
    """Facing the palm, a right thumb is on the image's right of its little finger and a left thumb on its
    left, on every frame of a real left/right pair; and from every camera the left hand's picture is the
    right hand's mirrored, read from the joint markers the renderer draws. Catches one camera for both sides
    (the left hand seen from its little-finger side, its thumb pointing the same way as the right's)."""
    renderer = EpisodeRenderer(g1_view, camera="palm")
    for t in range(g1_view.num_frames):
        renderer.render(t)
        for k, side in enumerate(g1_view.sides):
            pts = renderer.drawn_points_mm(k)  # (21, 2)
            assert np.sign(pts[THUMB_TIP, 0] - pts[PINKY_TIP, 0]) == (1 if side == "right" else -1), (t, side)

    states = np.repeat(udhm.sample_angles(np.random.default_rng(0), (5, 1)), 2, axis=1)  # same state, both sides
    pair = view_states(states, ["human", "human"], ["left", "right"])
    for camera in VIEWS:
        renderer = EpisodeRenderer(pair, camera=camera)
        for t in range(pair.num_frames):
            renderer.render(t)
            left, right = renderer.drawn_points_mm(0), renderer.drawn_points_mm(1)  # the wrist is at (0, 0)
            np.testing.assert_allclose(left, right * [-1, 1], atol=1e-9, err_msg=camera)
            assert abs(right[THUMB_TIP, 0] - right[PINKY_TIP, 0]) > 5 or camera == "side"  # not a degenerate view


def test_camera_axes_are_orthonormal_and_mirrored_for_the_left_hand():
    for camera in VIEWS:
        right, left = camera_axes(camera, "right"), camera_axes(camera, "left")
        np.testing.assert_allclose(right @ right.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(left @ MIRROR_Y, right * [[-1], [1], [1]], atol=1e-12)  # image x flips
    with pytest.raises(ValueError, match="unknown camera view 'top'"):
        camera_axes("top", "right")


@pytest.mark.parametrize("hands", [[INSPIRE, INSPIRE], ["linkerhand_l25"], ["human", "xhand1"]])
def test_every_bar_label_is_the_full_joint_name_inside_the_figure(hands):
    """Catches names cut to 8 characters ("thumb_be") and labels pushed off the figure or onto another
    panel: 25 LinkerHand joints, the 22 UDHM names of a human hand, XHand's 17-character names."""
    sides = ["left", "right"][: len(hands)] if len(hands) == 2 else ["right"]
    states = np.zeros((3, len(hands), 22))
    view = view_states(states, hands, sides)
    renderer = EpisodeRenderer(view)
    renderer.render(0)
    fig_box = renderer.figure.bbox
    canvas_renderer = renderer.canvas.get_renderer()
    for k, ax in enumerate(renderer.bar_axes):
        want = view.native_names[k] or list(UDHM_JOINT_NAMES)
        labels = ax.get_yticklabels()
        assert [label.get_text() for label in labels] == want
        boxes = [label.get_window_extent(canvas_renderer) for label in labels]
        for box in boxes:
            assert fig_box.x0 <= box.x0 and box.x1 <= fig_box.x1 and fig_box.y0 <= box.y0 and box.y1 <= fig_box.y1
            for other in renderer.bar_axes[:k] + renderer.hand_axes:
                assert not box.overlaps(other.get_window_extent(canvas_renderer))
        assert all(a.y0 >= b.y1 - 0.5 for a, b in zip(boxes, boxes[1:], strict=False))  # top to bottom, apart


def test_hands_fill_their_panels_at_one_scale_over_the_episode(g1_view):
    """Every frame's hand lies inside its panel, the panel's limits never change, both hands share one
    scale and the larger hand spans at least 80 % of its panel; catches per-frame rescaling and a hand
    left small in a box sized for every possible pose."""
    renderer = EpisodeRenderer(g1_view)
    limits = [(ax.get_xlim(), ax.get_ylim()) for ax in renderer.hand_axes]
    spans = np.zeros((len(renderer.hand_axes), 2))
    lo, hi = np.full_like(spans, np.inf), np.full_like(spans, -np.inf)
    for t in range(g1_view.num_frames):
        renderer.render(t)
        for k, ax in enumerate(renderer.hand_axes):
            assert (ax.get_xlim(), ax.get_ylim()) == limits[k]
            pts = renderer.drawn_points_mm(k)
            lo[k], hi[k] = np.minimum(lo[k], pts.min(0)), np.maximum(hi[k], pts.max(0))
    for k, ((x0, x1), (y0, y1)) in enumerate(limits):
        assert x0 < lo[k, 0] and hi[k, 0] < x1 and y0 < lo[k, 1] and hi[k, 1] < y1
        spans[k] = (hi[k] - lo[k]) / [x1 - x0, y1 - y0]
    mm_per_inch = [(x1 - x0) / ax.get_position().width / renderer.figure.get_figwidth()
                   for ax, ((x0, x1), _) in zip(renderer.hand_axes, limits, strict=True)]  # fmt: skip
    assert mm_per_inch[0] == pytest.approx(mm_per_inch[1])
    assert spans.max() >= 0.8, spans


def test_a_blitted_frame_equals_a_fresh_render(g1_view):
    """Frames drawn one after another onto the saved background equal the same frame of a new renderer,
    and consecutive frames differ: catches moving artists left out of the blit or stale ones kept."""
    renderer = EpisodeRenderer(g1_view)
    images = [renderer.render(t) for t in range(6)]
    np.testing.assert_array_equal(images[5], EpisodeRenderer(g1_view).render(5))
    assert images[5].shape[0] % 2 == 0 and images[5].shape[1] % 2 == 0
    assert all((a != b).any() for a, b in zip(images, images[1:], strict=False))
