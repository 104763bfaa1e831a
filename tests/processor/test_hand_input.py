"""`unidextok.hand_input`: the model reads the hands as their UDHM state, their tokens, or both."""

import pytest
import torch

from lerobot_unidextok.constants import OBS_HAND_TOKEN_FEATURES, OBS_STATE, UDHM_JOINT_NAMES
from lerobot_unidextok.processor import HandInputStep

NAMES = ["wrist_x", "object_x", *(f"right_{j}" for j in UDHM_JOINT_NAMES)]


def _obs() -> dict:
    return {OBS_STATE: torch.arange(1, 25, dtype=torch.float32).repeat(3, 1),
            OBS_HAND_TOKEN_FEATURES: torch.ones(3, 22)}  # fmt: skip


def test_state_zeroes_the_token_view_and_tokens_zero_the_udhm_block():
    state = HandInputStep(mode="state", state_names=NAMES).observation(_obs())
    assert state[OBS_HAND_TOKEN_FEATURES].abs().sum() == 0 and state[OBS_STATE][0, -1] == 24
    tokens = HandInputStep(mode="tokens", state_names=NAMES).observation(_obs())
    assert tokens[OBS_STATE][:, :2].tolist() == [[1.0, 2.0]] * 3  # passthrough kept
    assert tokens[OBS_STATE][:, 2:].abs().sum() == 0 and tokens[OBS_HAND_TOKEN_FEATURES].sum() == 66
    both = HandInputStep(mode="both", state_names=NAMES).observation(_obs())
    assert torch.equal(both[OBS_STATE], _obs()[OBS_STATE])


def test_a_mixs_hand_identity_stays_when_the_token_view_is_zeroed():
    """The mixed tokenizer step appends a one-hot hand identity to the view: it is not a view of the state."""
    obs = _obs()
    obs[OBS_HAND_TOKEN_FEATURES] = torch.cat([torch.ones(3, 22), torch.tensor([[0.0, 1.0, 0.0]] * 3)], dim=1)
    out = HandInputStep(mode="state", state_names=NAMES, identity_width=3).observation(obs)
    assert out[OBS_HAND_TOKEN_FEATURES][:, :22].abs().sum() == 0
    assert out[OBS_HAND_TOKEN_FEATURES][:, 22:].tolist() == [[0.0, 1.0, 0.0]] * 3


def test_bad_modes_and_layouts_are_refused():
    with pytest.raises(ValueError, match="udt_hand_input must be one of"):
        HandInputStep(mode="neither")
    with pytest.raises(ValueError, match="needs the state's column names"):
        HandInputStep(mode="tokens", state_names=["wrist_x"])
