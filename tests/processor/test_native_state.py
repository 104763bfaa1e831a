"""`unidextok.native_to_udhm`: the robot's native `observation.state` -> the converted layout, in LeRobot pipelines.

Logic on the synthetic G1-like fixture (tests/fixtures/robot_udhm.py: Unitree's Inspire convention written
independently of the hand specs); the real G1 + Inspire recording in ../shared is an extra check (skips
without it) that the step rebuilds the converter's frames bit for bit.
"""

import json
import logging

import numpy as np
import pytest
import torch
from lerobot.configs.types import FeatureType, PipelineFeatureType, PolicyFeature
from lerobot.processor import PolicyProcessorPipeline, ProcessorStepRegistry
from robot_udhm import HAND_NAMES, INSPIRE, NATIVE_NAMES, STATE_NAMES, native_layout, native_motion, to_converted

from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.processor import NATIVE_TO_UDHM_STEP_NAME, NativeLayout, NativeToUDHMStateStep


@pytest.fixture(scope="module")
def step():
    recorded = native_layout()[OBS_STATE]
    return NativeToUDHMStateStep(names=STATE_NAMES, native_names=recorded["names"], native_hands=recorded["hands"])


@pytest.fixture(scope="module")
def native():
    """(30, 26) float32 native G1-like states: 14 arm radians, then left and right Inspire values in [0, 1]."""
    return native_motion(30, seed=5).astype(np.float32)


def test_native_state_becomes_the_converted_state(step, native):
    """Arms copied bit for bit, each Inspire hand into its own side's UDHM block (Unitree's convention)."""
    out = step.observation({OBS_STATE: torch.from_numpy(native)})[OBS_STATE]
    want = to_converted(native.astype(np.float64))  # the fixture's own map, not the hand specs
    assert out.shape == (30, 58) and out.dtype == torch.float32
    torch.testing.assert_close(out[:, :14], torch.from_numpy(native[:, :14]), atol=0, rtol=0)
    np.testing.assert_allclose(out.numpy(), want, atol=1e-6)


def test_any_leading_shape_and_the_converted_state_passes_unchanged(step, native):
    x = torch.from_numpy(native)
    batched = step.observation({OBS_STATE: x})[OBS_STATE]
    assert torch.equal(step.observation({OBS_STATE: x[3]})[OBS_STATE], batched[3])  # (D,) as a robot sends
    assert torch.equal(step.observation({OBS_STATE: x.reshape(5, 6, 26)})[OBS_STATE], batched.reshape(5, 6, 58))
    converted = torch.from_numpy(to_converted(native)).float()  # what lerobot-train feeds from the dataset
    assert step.observation({OBS_STATE: converted})[OBS_STATE] is converted
    with pytest.raises(ValueError, match="not the native layout"):
        NativeToUDHMStateStep(**{**step.get_config(), "input_layout": "native"}).observation({OBS_STATE: converted})


def test_inverse_of_the_native_action_decoder(step, native):
    """native -> converted -> `NativeLayout.to_native` (the post-processor's map) gives the native back."""
    converted = step.observation({OBS_STATE: torch.from_numpy(native)})[OBS_STATE]
    np.testing.assert_allclose(step.layout.to_native(converted.numpy()), native, atol=1e-6)


def test_wrong_width_names_both_layouts_in_one_line(step):
    with pytest.raises(ValueError) as err:
        step.observation({OBS_STATE: torch.zeros(1, 30)})
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("observation.state has width 30, neither the native nor the converted layout")
    assert "native 26 columns: kLeftShoulderPitch, kLeftShoulderRoll, ..., kRightWristYaw (14 passthrough)" in msg
    assert "left inspire_rh56_unitree kLeftHandPinky, kLeftHandRing, ..., kLeftHandThumbRotation (6)" in msg
    assert "converted 58 columns: 14 passthrough + 2 UDHM blocks (left, right)" in msg


def test_hand_values_out_of_range_raise_or_clip(step, native):
    bad = torch.from_numpy(native[:2].copy())
    bad[1, NATIVE_NAMES.index("kRightHandIndex")] = 1.3  # a [0, 1] Inspire value
    with pytest.raises(ValueError, match=r"out of range: index in \[0, 1\].*on_out_of_range': 'clip'"):
        step.observation({OBS_STATE: bad})
    clip = NativeToUDHMStateStep(**{**step.get_config(), "on_out_of_range": "clip"})
    clipped = bad.clone()
    clipped[1, NATIVE_NAMES.index("kRightHandIndex")] = 1.0
    assert torch.equal(clip.observation({OBS_STATE: bad})[OBS_STATE], step.observation({OBS_STATE: clipped})[OBS_STATE])


def test_features_a_robot_reports_become_those_the_policy_reads(step):
    def state(width):
        return {PipelineFeatureType.OBSERVATION: {OBS_STATE: PolicyFeature(FeatureType.STATE, (width,))}}

    assert step.transform_features(state(26)) == state(58)
    assert step.transform_features(state(58)) == state(58)


def test_saved_with_the_pipeline_and_reloaded_by_name(step, native, tmp_path):
    """The whole layout is the step's JSON config: `save_pretrained` / `from_pretrained` bring it back, and
    overrides reach it by registry name (what `preprocessor_overrides` of the stock factory does)."""
    assert "/" not in NATIVE_TO_UDHM_STEP_NAME
    assert ProcessorStepRegistry.get(NATIVE_TO_UDHM_STEP_NAME) is NativeToUDHMStateStep
    pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
    pipe.save_pretrained(tmp_path)
    saved = json.loads((tmp_path / "policy_preprocessor.json").read_text())["steps"][0]
    assert saved["registry_name"] == NATIVE_TO_UDHM_STEP_NAME and saved["config"]["native_names"] == NATIVE_NAMES
    again = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json")
    x = torch.from_numpy(native[:4])
    assert torch.equal(again({OBS_STATE: x})[OBS_STATE], pipe({OBS_STATE: x})[OBS_STATE])
    clip = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="policy_preprocessor.json",
                                                   overrides={NATIVE_TO_UDHM_STEP_NAME: {"on_out_of_range": "clip"}})  # fmt: skip
    assert clip.steps[0].on_out_of_range == "clip"


def test_hands_only_layout(native):
    recorded = native_layout(arms=False)[OBS_STATE]
    step = NativeToUDHMStateStep(names=STATE_NAMES[14:], native_names=recorded["names"], native_hands=recorded["hands"])
    out = step.observation({OBS_STATE: torch.from_numpy(native[:, 14:])})[OBS_STATE]
    np.testing.assert_allclose(out.numpy(), to_converted(native.astype(np.float64))[:, 14:], atol=1e-6)


def test_equal_widths_are_taken_as_converted_unless_told_native(caplog):
    """A Shadow hand has 22 native joints: its native and converted states are both 22 wide."""
    layout = NativeLayout.from_hands(["shadow"], ["right"])
    assert layout.native_dim == layout.converted_dim == 22
    with caplog.at_level(logging.WARNING):
        auto = NativeToUDHMStateStep.from_layout(layout)
    assert "both 22 wide" in caplog.text and "input_layout='native'" in caplog.text
    x = torch.zeros(2, 22)
    assert auto.observation({OBS_STATE: x})[OBS_STATE] is x
    on_robot = NativeToUDHMStateStep.from_layout(layout, input_layout="native")
    torch.testing.assert_close(on_robot.observation({OBS_STATE: x})[OBS_STATE], torch.as_tensor(layout.to_converted(x)))


def test_layout_that_cannot_rebuild_the_converted_state_is_refused():
    names = ["arm0", *udhm_state_names(["left", "right"])]
    hands = [{"side": "left", "hand": INSPIRE, "columns": HAND_NAMES["left"]}]  # no right hand, no arm column
    with pytest.raises(ValueError, match="the right UDHM block has no hand entry; passthrough column 'arm0'"):
        NativeToUDHMStateStep(names=names, native_names=HAND_NAMES["left"], native_hands=hands)
    with pytest.raises(ValueError, match="input_layout must be one of"):
        NativeToUDHMStateStep(names=STATE_NAMES, native_names=NATIVE_NAMES, native_hands=[], input_layout="robot")


def test_real_g1_native_frames_give_the_converters_frames(real_data_dir, tmp_path):
    """Real G1 + Inspire: the robot's recorded native states through the step equal the converted dataset's
    states bit for bit (float32, as the converter computes)."""
    from g1_real import convert_g1, native_states
    from lerobot.datasets import LeRobotDataset

    root = convert_g1(real_data_dir, tmp_path / "g1", max_episodes=1)
    layout = UdhmDatasetMeta(root).native_layout(OBS_STATE)
    assert layout.native_dim == 26 and layout.converted_dim == 58
    step = NativeToUDHMStateStep.from_layout(layout)
    native = torch.from_numpy(native_states(real_data_dir, 0))
    ds = LeRobotDataset("test/g1_udhm", root=root)
    converted = torch.stack([ds[i][OBS_STATE] for i in range(len(ds))])
    assert native.shape == (len(ds), 26)
    assert torch.equal(step.observation({OBS_STATE: native})[OBS_STATE], converted)
