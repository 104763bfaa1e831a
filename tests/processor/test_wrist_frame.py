"""`unidextok.wrist_frame`: the wrist position of state and action as each row's hand's grasp centre, and back."""

import numpy as np
import pytest
import torch
from lerobot.lerobot_types import TransitionKey
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.constants import OBS_HAND_IDS, OBS_STATE
from lerobot_unidextok.data.wrist_frame import WristFrame, WristFrameError, merge_frames
from lerobot_unidextok.processor import WristFrameStep
from lerobot_unidextok.processor.wrist_frame import rotation_rpy

WRIST = ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw"]
STATE = [*WRIST, "object_x", *(f"right_{j}" for j in range(22))]
ACT = [*WRIST, *(f"right_{j}" for j in range(22))]
CENTRES = {"inspire_rh56_unitree": [0.076, 0.002, -0.025], "allegro": [0.058, 0.0195, -0.082]}
VOCAB = ["inspire_rh56_unitree", "allegro"]


def _steps(**kw):
    common = dict(state_names=STATE, action_names=ACT, wrist_columns=WRIST, hand_vocabulary=VOCAB,
                  grasp_centres_m=CENTRES, **kw)  # fmt: skip
    pre = WristFrameStep(mode="to_centre", **common)
    return pre, WristFrameStep(mode="to_wrist", pair=pre, **common)


def _rz_ry_rx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def test_rotation_is_rz_ry_rx_of_roll_pitch_yaw():
    rpy = torch.tensor([[0.3, -0.7, 1.2], [-1.1, 0.2, -2.5]], dtype=torch.float64)
    for r, m in zip(rpy, rotation_rpy(rpy), strict=True):
        np.testing.assert_allclose(m.numpy(), _rz_ry_rx(*r.tolist()), atol=1e-12)


def test_two_hands_in_one_batch_are_moved_by_their_own_centres_and_the_action_restored_exactly():
    gen = torch.Generator().manual_seed(0)
    state = torch.randn(2, len(STATE), generator=gen)
    action = torch.randn(2, 5, len(ACT), generator=gen)  # (B, chunk, A)
    state[:, 3:6] = (torch.rand(2, 3, generator=gen) - 0.5) * 3  # roll, pitch, yaw in +-1.5 rad
    action[..., 3:6] = (torch.rand(2, 5, 3, generator=gen) - 0.5) * 3
    ids = torch.tensor([[0], [1]])  # row 0: the Inspire, row 1: the Allegro
    pre, post = _steps()
    out = pre({TransitionKey.OBSERVATION: {OBS_STATE: state, OBS_HAND_IDS: ids}, TransitionKey.ACTION: action})
    s, a = out[TransitionKey.OBSERVATION][OBS_STATE], out[TransitionKey.ACTION]
    for row, hand in enumerate(VOCAB):
        c = np.asarray(CENTRES[hand])
        want = state[row, :3].double().numpy() + _rz_ry_rx(*state[row, 3:6].double().tolist()) @ c
        np.testing.assert_allclose(s[row, :3].numpy(), want, atol=1e-6)
        for t in range(5):
            want = action[row, t, :3].double().numpy() + _rz_ry_rx(*action[row, t, 3:6].double().tolist()) @ c
            np.testing.assert_allclose(a[row, t, :3].numpy(), want, atol=1e-6)
    assert torch.equal(s[:, 3:], state[:, 3:]) and torch.equal(a[..., 3:], action[..., 3:])  # only x, y, z move
    back = post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: a})[TransitionKey.ACTION]  # the pair's ids
    torch.testing.assert_close(back, action, rtol=0, atol=1e-6)
    assert (a[0, :, :3] - action[0, :, :3]).norm(dim=-1).sub(np.linalg.norm(CENTRES[VOCAB[0]])).abs().max() < 1e-6


def test_with_relative_actions_the_pair_sits_inside_the_frame_and_the_action_comes_back_exactly():
    """pre: frame -> relative (action - state, both at the grasp centre); post: absolute -> frame back: the
    wrist action is restored exactly (the state and action here share their first columns, as relative needs)."""
    from lerobot.processor import AbsoluteActionsProcessorStep, RelativeActionsProcessorStep

    state_names = [*WRIST, *(f"right_{j}" for j in range(4))]
    common = dict(state_names=state_names, action_names=state_names, wrist_columns=WRIST, hand_vocabulary=VOCAB,
                  grasp_centres_m=CENTRES)  # fmt: skip
    to_centre = WristFrameStep(mode="to_centre", **common)
    relative = RelativeActionsProcessorStep(enabled=True, action_names=state_names)
    absolute = AbsoluteActionsProcessorStep(enabled=True, relative_step=relative)
    to_wrist = WristFrameStep(mode="to_wrist", pair=to_centre, **common)
    gen = torch.Generator().manual_seed(1)
    state, action = torch.randn(2, len(state_names), generator=gen), torch.randn(2, len(state_names), generator=gen)
    ids = torch.tensor([[1], [0]])
    out = relative(to_centre({TransitionKey.OBSERVATION: {OBS_STATE: state, OBS_HAND_IDS: ids},
                              TransitionKey.ACTION: action}))  # fmt: skip
    offset = out[TransitionKey.ACTION]
    c = torch.tensor([CENTRES[VOCAB[1]], CENTRES[VOCAB[0]]], dtype=torch.float64)
    at_centre = lambda x: x[:, :3] + (rotation_rpy(x[:, 3:6].double()) @ c[..., None])[..., 0].float()  # noqa: E731
    torch.testing.assert_close(offset[:, :3], at_centre(action) - at_centre(state), rtol=0, atol=1e-6)
    back = to_wrist(absolute({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: offset}))[TransitionKey.ACTION]
    torch.testing.assert_close(back, action, rtol=0, atol=1e-6)


def test_a_bound_step_uses_its_fixed_hand_and_a_row_without_a_hand_is_left_as_it_is():
    pre, post = _steps(fixed_hand_ids=[1])
    action = torch.zeros(1, len(ACT))
    out = pre({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: action})[TransitionKey.ACTION]
    np.testing.assert_allclose(out[0, :3].numpy(), CENTRES["allegro"], atol=1e-7)
    back = post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: out})[TransitionKey.ACTION]
    torch.testing.assert_close(back, action, rtol=0, atol=1e-7)
    free, _ = _steps()
    state = torch.randn(1, len(STATE))
    same = free({TransitionKey.OBSERVATION: {OBS_STATE: state, OBS_HAND_IDS: torch.tensor([[-1]])}})
    assert torch.equal(same[TransitionKey.OBSERVATION][OBS_STATE], state)


def test_saved_and_reloaded_it_carries_its_centres_and_an_unbound_post_step_says_to_bind(tmp_path):
    pre, post = _steps()
    PolicyProcessorPipeline(steps=[pre], name="pre").save_pretrained(tmp_path, config_filename="pre.json")
    PolicyProcessorPipeline(steps=[post], name="post").save_pretrained(tmp_path, config_filename="post.json")
    loaded = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="post.json").steps[0]
    assert isinstance(loaded, WristFrameStep) and loaded.grasp_centres_m == CENTRES and loaded.mode == "to_wrist"
    with pytest.raises(KeyError, match="unidextok-deploy"):
        loaded({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: torch.zeros(1, len(ACT))})


@pytest.mark.parametrize(
    "kw, said",
    [
        (dict(grasp_centres_m={**CENTRES, "allegro": [0.1, 0.2]}), "must be 3 numbers in m"),
        (dict(grasp_centres_m={"allegro": [0.1, 0.2, 0.0]}), "no grasp centre for hands ['inspire_rh56_unitree']"),
        (dict(action_names=ACT[3:]), "the action has no wrist columns ['wrist_x', 'wrist_y', 'wrist_z']"),
        (dict(wrist_columns=WRIST[:3]), "wrist_columns must name x, y, z, roll, pitch, yaw"),
        (dict(rotation="Rx Ry Rz"), "is not supported"),
    ],
)
def test_bad_settings_are_one_named_error(kw, said):
    args = dict(state_names=STATE, action_names=ACT, wrist_columns=WRIST, hand_vocabulary=VOCAB,
                grasp_centres_m=CENTRES) | kw  # fmt: skip
    with pytest.raises(WristFrameError) as err:
        WristFrameStep(**args)
    assert said in str(err.value) and "\n" not in str(err.value)


def test_a_frame_record_is_checked_and_inputs_merge_by_hand():
    frame = WristFrame.from_dict({"columns": WRIST, "grasp_centre_in_wrist_m": {"allegro": CENTRES["allegro"]}}, "x")
    other = WristFrame(WRIST, grasp_centre_in_wrist_m={"inspire_rh56_unitree": CENTRES["inspire_rh56_unitree"]})
    assert merge_frames([frame, other], "mix").grasp_centre_in_wrist_m == CENTRES
    with pytest.raises(WristFrameError, match="two grasp centres"):
        merge_frames([frame, WristFrame(WRIST, grasp_centre_in_wrist_m={"allegro": [0, 0, 0]})], "mix")
    with pytest.raises(WristFrameError, match="name their wrist columns differently.*--name_map"):
        merge_frames([frame, WristFrame([f"{c}_2" for c in WRIST])], "mix")
    with pytest.raises(WristFrameError, match="'columns' must name the 6"):
        WristFrame.from_dict({"columns": WRIST[:5]}, "x")
    with pytest.raises(WristFrameError, match="must be 3 numbers in m"):
        WristFrame.from_dict({"columns": WRIST, "grasp_centre_in_wrist_m": {"allegro": [1, "a", 2]}}, "x")
