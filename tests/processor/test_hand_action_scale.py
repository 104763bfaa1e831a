"""unidextok.hand_action_scale: each UDHM block of a relative action scaled by the hand that row's block holds,
restored after the policy, saved and reloaded as a LeRobot pipeline step, bound to one robot's hands."""

import numpy as np
import pytest
import torch
from lerobot.lerobot_types import TransitionKey
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.converters import identity_transition

from lerobot_unidextok.constants import OBS_HAND_IDS, UDHM_DIM
from lerobot_unidextok.processor import HandActionScaleStep

VOCAB = ["hand_a", "hand_b"]


def _stats(seed: int = 0) -> dict:
    """Two hands at scales 30x apart; slot 3 never moves (std 0)."""
    rng = np.random.default_rng(seed)

    def entry(scale: float) -> dict:
        std = rng.uniform(0.5, 2, UDHM_DIM) * scale
        std[3] = 0.0
        return {"mean": rng.normal(0, scale, UDHM_DIM).tolist(), "std": std.tolist()}

    return {"left": {"hand_a": entry(0.01)}, "right": {"hand_a": entry(0.01), "hand_b": entry(0.3)}}


def _step(mode: str, **kwargs) -> HandActionScaleStep:
    return HandActionScaleStep(mode=mode, sides=["left", "right"], hand_vocabulary=VOCAB, stats=_stats(),
                               action_offset=2, **kwargs)  # fmt: skip


def _transition(action: torch.Tensor, ids: list[list[int]] | None) -> dict:
    obs = {} if ids is None else {OBS_HAND_IDS: torch.tensor(ids)}
    return {TransitionKey.OBSERVATION: obs, TransitionKey.ACTION: action}


def test_each_row_and_block_is_scaled_by_its_own_hand_and_restored():
    stats = _stats()
    action = torch.randn(3, 5, 2 + 2 * UDHM_DIM)  # (B, chunk, 2 passthrough + 2 blocks)
    ids = [[0, 0], [-1, 1], [0, 1]]  # a G1-like row (both hands a), a right-only row (hand b), a mixed row
    pre, post = _step("normalize"), None
    post = _step("unnormalize", pair=pre)
    z = pre(_transition(action, ids))[TransitionKey.ACTION]
    for row, (left, right) in enumerate(ids):
        for k, (side, v) in enumerate((("left", left), ("right", right))):
            block = slice(2 + k * UDHM_DIM, 2 + (k + 1) * UDHM_DIM)
            if v < 0:  # no hand in the block: unchanged
                torch.testing.assert_close(z[row, :, block], action[row, :, block])
                continue
            mean, std = np.asarray(stats[side][VOCAB[v]]["mean"]), np.asarray(stats[side][VOCAB[v]]["std"])
            std = np.where(std > 1e-6, std, 1.0)  # the slot never moved: std 1
            want = (action[row, :, block].numpy() - mean) / std
            np.testing.assert_allclose(z[row, :, block].numpy(), want, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(z[..., :2], action[..., :2])  # passthrough columns are not scaled
    # the post step restores what the policy predicts with the hands its paired pre step saw
    back = post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: z})[TransitionKey.ACTION]
    torch.testing.assert_close(back, action, rtol=1e-5, atol=1e-5)


def test_a_bound_step_uses_the_robots_hands_and_an_unknown_hand_the_blocks_typical_scale():
    action = torch.randn(4, 2 + 2 * UDHM_DIM)
    bound = _step("unnormalize", fixed_hand_ids=[-1, 1])
    out = bound({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: action})[TransitionKey.ACTION]
    per_row = _step("unnormalize")(_transition(action, [[-1, 1]] * 4))[TransitionKey.ACTION]
    torch.testing.assert_close(out, per_row)
    # a zero-shot hand (index after the vocabulary): scaled by the mean std of the block's known hands
    zero_shot = _step("unnormalize", fixed_hand_ids=[-1, 2])
    out = zero_shot({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: action})[TransitionKey.ACTION]
    stds = [np.where(np.asarray(_stats()["right"][h]["std"]) > 1e-6, _stats()["right"][h]["std"], 1.0) for h in VOCAB]
    np.testing.assert_allclose(out[:, 2 + UDHM_DIM :].numpy(), action[:, 2 + UDHM_DIM :].numpy() * np.mean(stds, 0),
                               rtol=1e-5, atol=1e-6)  # fmt: skip


def test_an_unbound_reloaded_post_step_says_to_bind_the_checkpoint():
    post = _step("unnormalize")
    with pytest.raises(KeyError, match="unidextok-deploy"):
        post({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: torch.zeros(1, 2 + 2 * UDHM_DIM)})


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="mode"):
        _step("z-score")
    with pytest.raises(ValueError, match="one hand per block"):
        _step("normalize", fixed_hand_ids=[0])
    with pytest.raises(ValueError, match="at least"):
        _step("normalize")(_transition(torch.zeros(1, UDHM_DIM), [[0, 0]]))


def test_saved_and_reloaded_as_a_pipeline_step(tmp_path):
    pipeline = PolicyProcessorPipeline(steps=[_step("normalize", fixed_hand_ids=[0, 1])], name="pre",
                                       to_transition=identity_transition, to_output=identity_transition)  # fmt: skip
    pipeline.save_pretrained(tmp_path)
    loaded = PolicyProcessorPipeline.from_pretrained(tmp_path, config_filename="pre.json",
                                                     to_transition=identity_transition, to_output=identity_transition)  # fmt: skip
    (step,) = loaded.steps
    assert isinstance(step, HandActionScaleStep) and step.get_config() == pipeline.steps[0].get_config()
    action = torch.randn(2, 2 + 2 * UDHM_DIM)
    torch.testing.assert_close(
        step({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: action})[TransitionKey.ACTION],
        pipeline.steps[0]({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: action})[TransitionKey.ACTION],
    )
