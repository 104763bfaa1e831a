"""`udt_relative_actions` on a layout it cannot subtract column by column is refused with the column that differs
and the fix that applies. Before, the message showed the first four names of both lists (`['wrist_x', 'wrist_y',
'wrist_z', 'wrist_roll']... vs ['wrist_x', 'wrist_y', 'wrist_z', 'wrist_roll']...`: the same) and always said
"reorder the dataset's action", which cannot help when the state has other columns in between."""

import pytest
from lerobot.configs.types import FeatureType, PolicyFeature

from lerobot_env_unidextok.columns import TASK_COLUMNS, WRIST_NAMES
from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.policies import ACTUdtConfig
from lerobot_unidextok.policies.relative_layout import relative_layout_problem

HAND = udhm_state_names(["right"])
SIM_STATE = [*WRIST_NAMES, *TASK_COLUMNS["GraspLift-v0"], *HAND]  # a converted simulator dataset's state
SIM_ACTION = [*WRIST_NAMES, *HAND]


def _config(action_names: list[str], state_names: list[str], action_width: int) -> ACTUdtConfig:
    cfg = ACTUdtConfig(udt_relative_actions=True, udt_action_names=action_names, udt_state_names=state_names)
    cfg.output_features = {ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(action_width,))}
    return cfg


def test_the_simulators_task_columns_between_wrist_and_hand_are_named_with_the_fix_that_works():
    with pytest.raises(InvalidInputError) as err:
        _config(SIM_ACTION, SIM_STATE, len(SIM_ACTION))._check_relative_layout(len(SIM_STATE))
    said = str(err.value)
    assert "action column 6 is 'right_thumb_cmc_flex' where the state has 'object_x'" in said
    assert "the state has 8 column(s) the action lacks among them (object_x, object_y" in said
    assert "reordering the action cannot fix that: set --policy.udt_relative_actions=false" in said
    assert "reorder the dataset's action" not in said


def test_a_policy_run_on_an_action_of_another_width_is_told_to_bind():
    """At evaluation the env's action replaces the checkpoint's (LeRobot's make_policy): a mix, or a policy of
    another robot, predicts another layout than the simulator takes."""
    mix_action = [*WRIST_NAMES, *HAND, *udhm_state_names(["left"])]
    said = relative_layout_problem(mix_action, [*mix_action, "extra"], 28, len(mix_action) + 1, trained=False)
    assert "this policy predicts 50 action columns" in said and "takes a 28-wide action" in said
    assert "unidextok-deploy --checkpoint=<policy> --robot=<this robot's converted dataset>" in said


def test_the_same_columns_in_another_order_keep_the_reorder_hint_and_name_the_column():
    state = ["a", "b", "c", "d"]
    said = relative_layout_problem(["b", "a"], state, 2, 4)
    assert "action column 0 is 'b' where the state has 'a'" in said and "reorder the dataset's action" in said


def test_columns_the_state_lacks_are_listed():
    said = relative_layout_problem(["left_x", "left_y"], ["right_x", "right_y", "z"], 2, 3)
    assert "the action has 2 column(s) the state lacks (left_x, left_y): set --policy.udt_relative_actions=false" in said


def test_an_aligned_layout_passes():
    assert relative_layout_problem(SIM_ACTION, [*SIM_ACTION, "object_x"], len(SIM_ACTION), len(SIM_ACTION) + 1) is None
    assert relative_layout_problem([], [], 4, 6) is None
    assert "the action is 8 wide and the state 6" in relative_layout_problem([], [], 8, 6)
