"""`observation.state_is_native`: a robot or simulator says its state is native, so a hand with 22 native joints
(the Shadow: as wide as a UDHM block) is never read as the converted layout, and another hand's state is refused."""

import numpy as np
import pytest
import torch

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import OBS_STATE, OBS_STATE_IS_NATIVE
from lerobot_unidextok.processor import NativeToUDHMStateStep

PASS = ["wrist_x", "object_x"]


@pytest.fixture(scope="module")
def shadow_step():
    spec = hands.get("shadow")
    columns = [f"right_{j}" for j in spec.joint_names]
    return NativeToUDHMStateStep(names=[*PASS, *udhm_state_names(["right"])], native_names=[*PASS, *columns],
                                 native_hands=[{"side": "right", "hand": "shadow", "columns": columns}])  # fmt: skip


def test_a_state_marked_native_is_mapped_even_when_the_widths_coincide(shadow_step):
    spec = hands.get("shadow")
    raw = np.random.default_rng(0).uniform(*np.asarray(spec.raw_range("right"), dtype=float).T)
    state = torch.tensor([[0.1, 0.2, *raw]], dtype=torch.float32)
    unmarked = shadow_step.observation({OBS_STATE: state})[OBS_STATE]
    assert torch.equal(unmarked, state)  # by width alone: taken as converted (the training batches)
    marked = shadow_step.observation({OBS_STATE: state, OBS_STATE_IS_NATIVE: torch.ones(1, 1)})[OBS_STATE]
    np.testing.assert_allclose(marked[0, 2:].numpy(), spec.to_udhm(raw, "right"), atol=1e-5)
    assert marked[0, :2].tolist() == pytest.approx([0.1, 0.2])


def test_a_native_state_of_another_width_is_refused_naming_the_fix(shadow_step):
    with pytest.raises(ValueError, match="shadow.*trained on another robot or hand.*unidextok-deploy"):
        shadow_step.observation({OBS_STATE: torch.zeros(1, 8), OBS_STATE_IS_NATIVE: torch.ones(1, 1)})
    zero_flag = {OBS_STATE: torch.zeros(1, 24), OBS_STATE_IS_NATIVE: torch.zeros(1, 1)}
    assert torch.equal(shadow_step.observation(zero_flag)[OBS_STATE], torch.zeros(1, 24))
