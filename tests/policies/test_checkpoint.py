"""What push and deploy ship must load whole and strictly (policies/checkpoint.py): LeRobot's own load warns
"Missing key(s)" and goes on with random weights, and ends in a draccus or import traceback on a config of
another policy type or an unknown processor step. Each is one `PolicyCheckpointError` naming what is wrong.
The checkpoint is a tiny stock ACT policy saved by LeRobot (tests/fixtures/tiny_policy.py)."""

import shutil
from pathlib import Path

import pytest
from safetensors.torch import load_file, save_file
from tiny_policy import edited_copy, write_tiny_act

from lerobot_unidextok.policies.checkpoint import PolicyCheckpointError, check_policy_checkpoint


@pytest.fixture(scope="module")
def tiny_act(tmp_path_factory) -> Path:
    return write_tiny_act(tmp_path_factory.mktemp("tiny_act") / "pretrained_model")


# what the one error line must say for each defect
EXPECTED = {
    "missing_tensor": r"model.safetensors does not hold the tensors of the act policy its config.json builds "
    r"\(missing model.action_head.bias\): LeRobot would load it anyway, with the missing ones left random",
    "extra_tensor": r"\(extra model.spare.weight\): LeRobot would load it anyway, with the extra ones ignored",
    "other_type": r"config.json says type 'diffusion' but does not decode as one \(the fields chunk_size, "
    r"replace_final_stride_with_dilation, pre_norm, dim_model and \d+ more are not valid for DiffusionConfig\): "
    r".*known types: act, .*diffusion",
    "unknown_type": r"config.json names the policy type 'act_plus', which is not registered here \(known: act, "
    r".*act_udt.*\): install the package that registers it",
    "no_type": r"config.json names no policy type \(known: act, ",
    "unknown_step": r"policy_preprocessor.json has the processor step 1 'unidextok.no_such_step', which is not "
    r"known here: steps come from LeRobot's registry",
    "unknown_class": r"policy_preprocessor.json has the processor step 1 'no_such_package.steps.Step'",
    "nan_weight": r"model.safetensors: tensor model.action_head.weight holds 1 NaN/inf of 32 values: a policy with "
    r"them acts on NaN; .*use an earlier checkpoint of the run",
    "nan_stats": r"policy_preprocessor_step_3_normalizer_processor.safetensors: tensor action.std holds 1 NaN/inf "
    r"of 4 values",
}


def test_a_whole_checkpoint_passes(tiny_act):
    check_policy_checkpoint(tiny_act)


@pytest.mark.parametrize("edit", list(EXPECTED))
def test_each_defect_is_one_error_naming_it(tiny_act, tmp_path, edit):
    folder = edited_copy(tiny_act, tmp_path / edit, edit)
    with pytest.raises(PolicyCheckpointError, match=EXPECTED[edit]) as info:
        check_policy_checkpoint(folder)
    assert "\n" not in str(info.value)


def test_many_missing_tensors_are_counted_not_listed(tiny_act, tmp_path):
    folder = tmp_path / "half"
    shutil.copytree(tiny_act, folder)
    weights = load_file(folder / "model.safetensors")
    kept = dict(sorted(weights.items())[: len(weights) // 2])
    save_file(kept, folder / "model.safetensors", metadata={"format": "pt"})
    gone = len(weights) - len(kept)
    with pytest.raises(PolicyCheckpointError, match=rf"\(missing [^;]*, [^;]*, [^;]*, [^;]* and {gone - 4} more\)"):
        check_policy_checkpoint(folder)
