"""experiments/cross_embodiment.py on the synthetic G1 sample and a synthetic second hand (no ../shared): every arm
trains the same ACT, predictions come back in the target's own layout, and the reference is copying the state."""

import numpy as np
import pytest

from experiments import cross_embodiment as ce
from experiments.policy_data import load_frames


@pytest.fixture(scope="module")
def result(converted_g1, tmp_path_factory):
    out = tmp_path_factory.mktemp("ce")
    argv = [f"--target={converted_g1}", "--others=[xhand_gestures]", "--target_episodes=[2]", "--seeds=[0]",
            "--other_episodes=2", "--other_frames=40", "--act.steps=3", "--act.batch_size=8", f"--output_root={out}"]  # fmt: skip
    return ce.run(ce.runtime.parse(ce.CrossEmbodimentConfig, argv))


def test_every_arm_is_scored_next_to_copying_the_state(result):
    s = result["summary"]
    assert set(s) == {"copy_state", *(f"2/{arm}" for arm in ce.ARMS)}
    for key, v in s.items():
        for metric in ce.METRICS:
            assert np.isfinite(v[metric]["mean"]) and v[metric]["mean"] >= 0, (key, metric)
    assert [x["name"] for x in result["sources"]] == ["target", "xhand_gestures"]
    assert "| 2 | udhm_mix |" in ce.markdown(result)


def test_the_mixed_layout_puts_each_side_in_its_block_and_back(converted_g1):
    """The target's blocks go to the mixed (left, right) layout and a prediction comes back into its own
    columns unchanged; the packed-native view of the target is its native hand values, zero-padded."""
    frames = load_frames(converted_g1)
    src = ce.target_source(frames)
    assert src.udhm.shape == (len(frames.state), 44) and src.packed.shape[1] == ce.PACKED_WIDTH
    rows = np.arange(5)
    pred = np.repeat(src.udhm[rows][:, None, :], 3, axis=1)
    back = ce.to_target_layout(pred, "udhm_mix", frames, rows)
    np.testing.assert_allclose(back[:, 0][:, frames.block_columns], frames.state[rows][:, frames.block_columns])
    native = frames.native_layout("action").to_native(frames.state)[:, frames.native_hand_columns("action")]
    np.testing.assert_allclose(src.packed[:, : native.shape[1]], native)
    assert not src.packed[:, native.shape[1] :].any()


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="unknown arms"):
        ce.CrossEmbodimentConfig(arms=["target_only", "magic"])
    with pytest.raises(ValueError, match="normalise must be"):
        ce.CrossEmbodimentConfig(normalise="zscore")


def test_a_nested_flag_keeps_the_experiments_step_budget():
    """`--act.chunk_size=30` rebuilt the nested config from SmallACT's class defaults: 5000 steps instead of the
    experiment's 600 (and policy_tokens' 800), silently ~8x the CPU budget."""
    from experiments import policy_tokens

    cfg = ce.runtime.parse(ce.CrossEmbodimentConfig, ["--act.chunk_size=30"])
    assert (cfg.act.steps, cfg.act.chunk_size) == (600, 30)
    assert ce.runtime.parse(policy_tokens.PolicyTokensConfig, ["--act.lr=0.002"]).act.steps == 800
