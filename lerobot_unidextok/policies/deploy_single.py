"""Bind a `<type>_udt` policy trained on one robot's dataset to another robot's hands, zero-shot
(`unidextok-deploy --zero_shot=true`).

    unidextok-deploy --checkpoint=outputs/inspire_act/checkpoints/last/pretrained_model \
        --robot=data/shadow_udhm --zero_shot=true --output=outputs/inspire_act_on_shadow

A policy trained on one robot reads that robot's converted state (its passthrough columns, then one UDHM block per
side) and decodes to its native action. Another robot's hands fill the same UDHM blocks (semantic insertion), so
the policy can be tried on them without training: the bound checkpoint's saved processors take the new robot's
native state, map it into the trained layout (its hands into the trained blocks, its columns the policy does not
read left out), tokenise each block with the new robot's hand, normalise it with the pooled statistics of the
trained hands that have each slot (`processor/hand_normalizer.py`; slots no trained hand has pass unscaled), and
decode the predicted action to the new robot's native action. The model and its other statistics are unchanged.

A new robot must have a hand on every side the policy was trained with (a block the policy always saw filled
cannot be left empty) and report the trained passthrough columns (arms, task columns) under the same names.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from lerobot_unidextok.blocks import find_udhm_blocks, passthrough_indices
from lerobot_unidextok.constants import ACTION, OBS_STATE
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.layout import NativeLayout
from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.policies.udt_processor import row_hands
from lerobot_unidextok.processor import (
    NativeToUDHMStateStep,
    UDHMToNativeCommandStep,
    UniDexTokStateTokenizerStep,
)


class SingleBindError(InvalidInputError):
    """The one-robot checkpoint cannot be bound to that robot; the message names why and the fix."""


def refuse_several_hand_sets(robot: UdhmDatasetMeta, error: type[InvalidInputError]) -> None:
    """A robot has one set of hands: a dataset whose episodes hold different hands is refused with `error`, naming
    them and deploy's fix (the dataset's own check names lerobot-train's flags, which deploy does not have)."""
    if len(robot.hand_types) <= 1:
        return
    episodes: dict[str, list[int]] = {}
    for e in robot.record.episodes if robot.record is not None else []:
        episodes.setdefault(e.hand_type, []).append(e.episode_index)
    which = "; ".join(f"{t}: episodes {v[:6]}{' ...' if len(v) > 6 else ''}" for t, v in episodes.items())
    raise error(
        f"{robot.root} holds episodes of different hands ({which or ', '.join(robot.hand_types)}), but a robot "
        "has one set of hands: bind to a dataset of this robot alone (convert its own recordings into their "
        "own dataset and pass that as --robot)"
    )


def _refuse_missing_columns(config: UdtConfigMixin, layout: NativeLayout, names: list[str], what: str) -> None:
    """The columns besides the hands (arms, task columns) the policy read in every training frame must be among the
    robot's own, under the same names."""
    trained = [names[i] for i in passthrough_indices(names)]
    missing = [n for n in trained if n not in layout.native_names]
    if missing:
        raise SingleBindError(
            f"the policy was trained on a robot whose {what} has columns {missing[:4]}{' ...' if len(missing) > 4 else ''} "
            f"besides its hands ({len(trained)} in all: arms, task columns), which this robot does not report: a "
            "one-robot policy reads them in every frame. Bind it to a robot that reports them under the same names, "
            "or train on the hands only (unidextok-convert --keep=hands) and bind that"
        )


@dataclasses.dataclass
class SingleBinding:
    """What binding another robot's hands into a one-robot checkpoint gives (the fields `deploy.Binding` has)."""

    fixed_hand_ids: list[int]  # per block, an index into the trained hands + `extra_hands`
    extra_hands: list[str]  # the robot's hands the policy never trained on (pooled statistics)
    state_layout: NativeLayout  # the robot's native state -> the trained converted state
    action_layout: NativeLayout  # the trained action -> the robot's native action
    robot_names: list[str]  # the robot's own converted state columns
    # per zero-shot hand, the UDHM slots it drives (`deploy.driven_slots`); absent: every slot it has
    extra_hand_slots: dict[str, list[int]] = dataclasses.field(default_factory=dict)


def bind_single_robot(
    config: UdtConfigMixin, robot: UdhmDatasetMeta, place: Callable[[NativeLayout, list[str], list[str], str], NativeLayout]
) -> tuple[UdtConfigMixin, SingleBinding]:
    """The bound config and binding of a one-robot checkpoint's `config` on `robot`'s hands; `place(layout, names,
    sides, "state" | "action")` puts the robot's native layout against the trained columns (`deploy._into_mix`)."""
    if robot.record is not None and robot.record.hand_vocabulary:
        raise SingleBindError(f"{robot.root} is a mix; pass one robot's converted dataset")
    refuse_several_hand_sets(robot, SingleBindError)
    sides = list(config.udt_sides)
    robot_hands = robot.block_hands()
    robot_sides = [b.side for b in find_udhm_blocks(robot.names(OBS_STATE))]
    extra_sides = [s for s in robot_sides if s not in sides]
    if extra_sides:
        raise SingleBindError(f"the robot has a {extra_sides[0]} hand but the policy was trained with blocks {sides} "
                              "only: bind it to a robot with those sides")  # fmt: skip
    missing = [s for s in sides if s not in robot_sides]
    if missing:
        raise SingleBindError(
            f"the policy was trained with a hand on the {missing[0]} side, which this robot lacks (its sides "
            f"{robot_sides}): a one-robot policy always saw that block filled; bind it to a robot with hands on "
            f"{sides}, or train on a mix (unidextok-mix) that has rows without that hand"
        )
    layout = [robot_hands[robot_sides.index(s)] for s in sides]
    state, action = robot.native_layout(OBS_STATE), robot.native_layout(ACTION)
    if state is None or action is None:
        raise SingleBindError(
            f"{robot.root} records no native state and action layout (a human dataset, or one converted without "
            "actions): there is no robot to bind to"
        )
    _refuse_missing_columns(config, state, list(config.udt_state_names), "state")
    _refuse_missing_columns(config, action, list(config.udt_action_names), "action")
    state_layout = place(state, list(config.udt_state_names), sides, "state")
    action_layout = place(action, list(config.udt_action_names), sides, "action")
    bound = dataclasses.replace(
        config,
        udt_hand_layout=layout,
        udt_allow_unknown=config.udt_allow_unknown or not set(layout) <= set(config.udt_hand_layout),
        udt_native_state_layout=state_layout.to_dict() if config.udt_native_state else {},
        udt_native_layout=action_layout.to_dict() if config.udt_native_action else {},
    )
    _, extra, fixed = row_hands(bound)
    return bound, SingleBinding(fixed, extra, state_layout, action_layout, robot.names(OBS_STATE))


def bound_single_steps(pre_steps: list, post_steps: list, config: UdtConfigMixin, binding: SingleBinding) -> tuple[list, list]:
    """The checkpoint's processor steps with the tokenizer on the new hands and the new robot's native steps."""
    at = next((i for i, s in enumerate(pre_steps) if isinstance(s, UniDexTokStateTokenizerStep)), None)
    if at is None:
        raise SingleBindError("the checkpoint's pre-processor has no unidextok.state_tokenizer step: not a <type>_udt policy")
    old = pre_steps[at]
    step = UniDexTokStateTokenizerStep(**{**old.get_config(), "hand_layout": list(config.udt_hand_layout),
                                          "allow_unknown": config.udt_allow_unknown})  # fmt: skip
    step.load_state_dict(old.state_dict())
    pre = with_tokenizer_step(pre_steps, step, config, binding)
    post = [s for s in post_steps if not isinstance(s, UDHMToNativeCommandStep)]
    if config.udt_native_layout:
        post.append(UDHMToNativeCommandStep.from_layout(binding.action_layout))
    return pre, post



def with_tokenizer_step(steps: list, step, config: UdtConfigMixin, binding) -> list:
    """`steps` with their tokenizer step (of `step`'s type) replaced by the bound `step` and, for a policy on a
    native state, the new robot's native-to-UDHM step just before it (the old robot's removed)."""
    out = [s for s in steps if not isinstance(s, NativeToUDHMStateStep)]
    at = next(i for i, s in enumerate(out) if isinstance(s, type(step)))
    out[at] = step
    if config.udt_native_state_layout:
        robot = binding.robot_names if binding.robot_names != binding.state_layout.names else []
        out.insert(at, NativeToUDHMStateStep.from_layout(binding.state_layout, robot_names=robot))
    return out

__all__ = ["SingleBindError", "SingleBinding", "bind_single_robot", "bound_single_steps", "refuse_several_hand_sets",
           "with_tokenizer_step"]
