"""Bind a policy trained on a mix of robots and people to one robot of the mix (`unidextok-deploy`).

    unidextok-deploy --checkpoint=outputs/mix_act/checkpoints/last/pretrained_model \
        --robot=data/g1_udhm --output=outputs/mix_act_g1

A `<type>_udt` checkpoint trained on a dataset written by `unidextok-mix` reads the mix's layout (one UDHM block
per side any source has) and each row's hands (`observation.hand_ids`), and predicts actions in that layout. A
robot reports neither: its own `observation.state` (e.g. 14 G1 arm angles and 2 x 6 Inspire values) and it
takes its own action. Binding writes a checkpoint whose saved processors do that robot's part, with the model
and its normaliser statistics unchanged:

- `unidextok.native_to_udhm` maps the robot's native state (read from the robot's converted dataset, its
  `meta/unidextok_conversion.json` native layout) into the mix's layout: its hands into their blocks, a side the
  robot lacks zero, columns the mix does not carry (the arms of a hands-only mix) read past; the robot's
  converted state and the mix's own pass unchanged;
- the mixed tokenizer step gets the robot's hands per block (`fixed_hand_ids`), so the policy sees the hand
  identity it trained with, and so do the per-hand action scale steps (`unidextok.hand_action_scale`), so the
  predicted offsets are restored with the robot's own hands' scale;
- `unidextok.udhm_to_native` decodes the predicted action to the robot's native action: its hands in native
  units, its passthrough columns the mix carries; in the robot's order (columns the mix does not predict, such
  as the arms of a hands-only mix, are left out: `source_names` says where the rest sit).

The bound config says the same (`udt_fixed_hand_ids`, `udt_native_layout`, `udt_native_state_layout`), so
LeRobot's stock factory, `lerobot-rollout` and `--policy.path` fine-tuning rebuild the same processors. A robot
whose hands were never in the mix is refused unless `zero_shot`: its hands are then tokenised (by the
tokenizer's own embedding, or its unknown-hand one), told to the policy by their morphology vector (a one-hot
identity: all zero, a hand the policy never saw), and normalised with the pooled statistics of the mix's hands;
`zero_shot_slots="nearest"` has such a hand drive only the slots of the trained hand nearest it in morphology
(`driven_slots`). A checkpoint trained on one robot's dataset binds zero-shot to
another robot's hands too (`deploy_single.py`). A checkpoint that learned the wrist in each hand's grasp-centre
frame gets the robot's own grasp centre in its `unidextok.wrist_frame` steps (`deploy_frame.py`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import shutil
from pathlib import Path

import numpy as np
from lerobot.configs.policies import PreTrainedConfig
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import find_udhm_blocks, passthrough_indices
from lerobot_unidextok.constants import ACTION, OBS_STATE
from lerobot_unidextok.data.destination import Kind, claim, move_into_place, release
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.wrist_frame import check_centre
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.hands.morphology import nearest_hand
from lerobot_unidextok.layout import NativeLayout
from lerobot_unidextok.policies.checkpoint import POSTPROCESSOR, PREPROCESSOR, check_policy_checkpoint
from lerobot_unidextok.policies.deploy_frame import bound_frame_steps, bound_grasp_centres
from lerobot_unidextok.policies.deploy_single import (
    bind_single_robot,
    bound_single_steps,
    refuse_several_hand_sets,
    with_tokenizer_step,
)
from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.policies.udt_processor import row_hands
from lerobot_unidextok.processor import (
    HandActionScaleStep,
    HandNormalizerStep,
    SlotMaskStep,
    UDHMToNativeCommandStep,
    UniDexTokMixedTokenizerStep,
)
from lerobot_unidextok.udhm.joints import JOINT_NAMES
from lerobot_unidextok.utils.files import temp_sibling

logger = logging.getLogger(__name__)

KEPT_FILES = ("model.safetensors", "train_config.json", "README.md")
# what a zero-shot hand drives: every slot it has ("own"), or those of the trained hand nearest it ("nearest")
ZERO_SHOT_SLOTS = ("own", "nearest")


class DeployError(InvalidInputError):
    """The checkpoint cannot be bound to that robot; the message names why and the fix."""


@dataclasses.dataclass
class Binding:
    """What binding one robot into a mixed checkpoint's layout gives."""

    fixed_hand_ids: list[int]
    extra_hands: list[str]  # zero-shot hands appended after the mix's vocabulary (identity all zero)
    state_layout: NativeLayout  # the robot's native state -> the mix's state
    action_layout: NativeLayout  # the mix's action -> the robot's native action (what the mix predicts of it)
    robot_names: list[str]  # the robot's converted state columns (its dataset's), also taken by the bound step
    # per zero-shot hand, the UDHM slots it drives (`driven_slots`); absent: every slot it has
    extra_hand_slots: dict[str, list[int]] = dataclasses.field(default_factory=dict)


def bind_layouts(config: UdtConfigMixin, robot: UdhmDatasetMeta, zero_shot: bool = False) -> Binding:
    """The robot's place in the mix: its hands per block and its native layouts against the mix's columns."""
    vocab, mix_sides = list(config.udt_hand_vocabulary), list(config.udt_sides)
    if robot.record is not None and robot.record.hand_vocabulary:
        raise DeployError(f"{robot.root} is a mix; pass one robot's converted dataset (one of the mix's inputs)")
    refuse_several_hand_sets(robot, DeployError)
    hands, sides = robot.block_hands(), [b.side for b in find_udhm_blocks(robot.names(OBS_STATE))]
    lacking = [s for s in sides if s not in mix_sides]
    if lacking:
        raise DeployError(f"the robot has a {lacking[0]} hand but the mix has no {lacking[0]} block ({mix_sides})")
    unseen = sorted({h for h in hands if h not in vocab})
    if unseen and not zero_shot:
        raise DeployError(
            f"the robot's hands {unseen} were never in the mix ({vocab}): the policy has never controlled them. "
            "Mix a dataset of this robot in and train again, or pass --zero_shot=true to try it anyway"
        )
    extra = unseen
    names = vocab + extra
    fixed = [names.index(hands[sides.index(s)]) if s in sides else -1 for s in mix_sides]
    state = robot.native_layout(OBS_STATE)
    action = robot.native_layout(ACTION)
    if state is None or action is None:
        raise DeployError(
            f"{robot.root} records no native state and action layout (a human dataset, or one converted without "
            "actions): there is no robot to bind to"
        )
    rename = config.udt_name_map
    state, action = _renamed(state, rename), _renamed(action, rename)
    return Binding(fixed, extra, _into_mix(state, config.udt_state_names, mix_sides, "state"),
                   _into_mix(action, config.udt_action_names, mix_sides, "action"),
                   [rename.get(n, n) for n in robot.names(OBS_STATE)])  # fmt: skip


def _renamed(layout: NativeLayout, rename: dict[str, str]) -> NativeLayout:
    """`layout` with its passthrough columns under the mix's common names (`unidextok-mix --name_map`): the
    robot's vector keeps its order and count, its columns their mix names."""
    if not rename:
        return layout
    hand_columns = {c for h in layout.hands for c in h["columns"]}

    def new(names: list[str]) -> list[str]:
        return [n if n in hand_columns else rename.get(n, n) for n in names]

    return dataclasses.replace(layout, names=new(layout.names), native_names=new(layout.native_names))


def _into_mix(robot: NativeLayout, mix_names: list[str], mix_sides: list[str], what: str) -> NativeLayout:
    """The robot's native layout against the mix's converted columns (its blocks at the mix's sides)."""
    mix_pass = {mix_names[i] for i in passthrough_indices(mix_names)}
    robot_pass = [robot.names[i] for i in passthrough_indices(robot.names)]
    hand_columns = {c for h in robot.hands for c in h["columns"]}
    carried = [n for n in robot_pass if n in mix_pass]
    missing = sorted(mix_pass - set(robot.native_names))
    if missing:
        raise DeployError(
            f"the mix's {what} has columns {missing[:4]} this robot does not report (--keep=all with other "
            "robots' columns): bind a hands-only mix (unidextok-mix --keep=hands), or give the robot those columns"
        )
    robot_sides = {h["side"] for h in robot.hands}
    if what == "state":
        dropped = [n for n in robot.native_names if n not in hand_columns and n not in carried]
        return NativeLayout(names=mix_names, native_names=robot.native_names, hands=robot.hands,
                            mapping=robot.mapping, absent_sides=[s for s in mix_sides if s not in robot_sides],
                            dropped=dropped)  # fmt: skip
    native = [n for n in robot.native_names if n in hand_columns or n in carried]  # what the mix predicts of it
    return NativeLayout(names=mix_names, native_names=native, hands=robot.hands, mapping=robot.mapping,
                        source_names=robot.source_names or (robot.native_names if native != robot.native_names else []),
                        absent_sides=[s for s in mix_sides if s not in robot_sides])  # fmt: skip


def deploy(checkpoint: str | Path, robot: str | Path, output: str | Path, zero_shot: bool = False,
           overwrite: bool = False, grasp_centre_m: list[float] | None = None, zero_shot_slots: str = "own") -> Path:
    """Write the checkpoint at `checkpoint`, bound to the robot of the converted dataset `robot`, to `output`
    (`overwrite`: replace a policy checkpoint there, once the new one is whole; `data.destination.claim`);
    `grasp_centre_m`: the robot's grasp centre for a checkpoint in the grasp-centre frame (`deploy_frame.py`);
    `zero_shot_slots`: what a zero-shot hand drives (`ZERO_SHOT_SLOTS`, `driven_slots`)."""
    checkpoint, robot = Path(checkpoint), Path(robot)
    check_zero_shot_slots(zero_shot, zero_shot_slots)
    if grasp_centre_m is not None:  # before anything is read: 3 numbers in m within 0.3 m of the wrist
        check_centre("the robot's hands", grasp_centre_m, "--grasp_centre_m")
    if not (checkpoint / "config.json").is_file() or not (checkpoint / PREPROCESSOR).is_file():
        raise DeployError(
            f"{checkpoint} is not a LeRobot policy checkpoint (config.json + {PREPROCESSOR}): pass the "
            "pretrained_model folder of a lerobot-train run, e.g. outputs/<run>/checkpoints/last/pretrained_model"
        )
    output = claim(output, Kind.POLICY, inputs=[checkpoint, robot], overwrite=overwrite, flag="--output")
    try:
        return _deploy_into(checkpoint, robot, output, zero_shot, overwrite, grasp_centre_m, zero_shot_slots)
    finally:
        release(output)  # the destination's lock (data/destination.py), however the binding ended


def check_zero_shot_slots(zero_shot: bool, zero_shot_slots: str) -> None:
    """Refuse an unknown `zero_shot_slots`, or one that narrows without `zero_shot` (before any file is read)."""
    if zero_shot_slots not in ZERO_SHOT_SLOTS:
        raise DeployError(f"--zero_shot_slots must be one of {ZERO_SHOT_SLOTS}, got {zero_shot_slots!r}")
    if zero_shot_slots != "own" and not zero_shot:
        raise DeployError(f"--zero_shot_slots={zero_shot_slots} narrows what a zero-shot hand drives: pass it "
                          "with --zero_shot=true")  # fmt: skip


def driven_slots(known: list[str], extra: list[str], how: str = "own") -> dict[str, list[int]]:
    """{zero-shot hand: the UDHM slots it drives} for `how` = "nearest": the slots it shares with the trained hand
    of `known` nearest it in morphology (`hands/morphology.nearest_hand`), so the policy sees and drives it as it
    saw that hand, which lacks the others (they are held at 0 in its state and commanded 0); "own": {} (every slot
    it has, those no trained hand has held at 0 in its state: `processor/slot_mask.py`)."""
    if how == "own" or not extra:
        return {}
    out = {}
    for hand in extra:
        near = nearest_hand(hand, known)
        shared = hands.get(hand).active_mask & hands.get(near).active_mask
        out[hand] = [int(i) for i in np.flatnonzero(shared)]
        dropped = [JOINT_NAMES[i] for i in np.flatnonzero(hands.get(hand).active_mask & ~shared)]
        logger.info("zero-shot %s drives the %d slots it shares with %s, the trained hand nearest it in morphology; "
                    "not driven: %s", hand, len(out[hand]), near, ", ".join(dropped) or "none")  # fmt: skip
    return out


def _deploy_into(checkpoint: Path, robot: Path, output: Path, zero_shot: bool, overwrite: bool,
                 grasp_centre_m: list[float] | None, how: str = "own") -> Path:  # fmt: skip
    """`deploy` into the claimed `output`."""
    check_policy_checkpoint(checkpoint)
    config = PreTrainedConfig.from_pretrained(checkpoint)
    if not isinstance(config, UdtConfigMixin):
        raise DeployError(
            f"{checkpoint} is a stock `{config.type}` policy, not a <type>_udt one: there is nothing to bind "
            "(train a <type>_udt policy, e.g. --policy.type=act_udt)"
        )
    single = not config.udt_hand_vocabulary  # trained on one robot's dataset: zero-shot only (deploy_single.py)
    if single and not zero_shot:
        raise DeployError(
            f"{checkpoint} is a {config.type} policy trained on one robot's dataset, not on a mix (unidextok-mix): "
            "it already takes that robot's own state. To try it on another robot's hands, pass --zero_shot=true"
        )
    if single:
        bound, binding = bind_single_robot(config, UdhmDatasetMeta(Path(robot)), _into_mix)
    else:
        binding = bind_layouts(config, UdhmDatasetMeta(Path(robot)), zero_shot)
        bound = dataclasses.replace(
            config,
            udt_fixed_hand_ids=binding.fixed_hand_ids,
            udt_extra_hands=binding.extra_hands,
            udt_allow_unknown=config.udt_allow_unknown or bool(binding.extra_hands),
            udt_native_state_layout=binding.state_layout.to_dict() if config.udt_native_state else {},
            udt_native_layout=binding.action_layout.to_dict() if config.udt_native_action else {},
        )
    known, extra, _ = row_hands(bound)
    binding.extra_hand_slots = driven_slots(known, extra, how)
    centres = bound_grasp_centres(config, UdhmDatasetMeta(Path(robot)), grasp_centre_m)
    if centres:  # the robot's own grasp centre turns the predicted grasp centre into its wrist command
        bound = dataclasses.replace(bound, udt_grasp_centres_m=centres)
    pre = PolicyProcessorPipeline.from_pretrained(checkpoint, config_filename=PREPROCESSOR)
    post = PolicyProcessorPipeline.from_pretrained(checkpoint, config_filename=POSTPROCESSOR)
    if single:
        pre.steps, post.steps = bound_single_steps(pre.steps, post.steps, bound, binding)
    else:
        pre.steps = _bound_pre_steps(pre.steps, bound, binding)
    pre.steps, post.steps = (_bound_scale(steps, binding) for steps in (pre.steps, post.steps))
    if binding.extra_hand_slots:
        _check_slots_bound(pre.steps, post.steps)
    if centres:
        pre.steps, post.steps = (bound_frame_steps(steps, bound) for steps in (pre.steps, post.steps))
    if bound.udt_native_layout and not single:
        post.steps = [*post.steps, UDHMToNativeCommandStep.from_layout(binding.action_layout)]
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_sibling(output)
    try:
        tmp.mkdir()
        for name in KEPT_FILES:
            if (checkpoint / name).is_file():
                shutil.copyfile(checkpoint / name, tmp / name)
        bound.save_pretrained(tmp)
        pre.save_pretrained(tmp, config_filename=PREPROCESSOR)
        post.save_pretrained(tmp, config_filename=POSTPROCESSOR)
        (tmp / "unidextok_deploy.json").write_text(json.dumps(
            {"checkpoint": str(checkpoint), "robot": str(robot), "robot_type": UdhmDatasetMeta(robot).robot_type,
             "fixed_hand_ids": binding.fixed_hand_ids, "zero_shot_hands": binding.extra_hands,
             "zero_shot_slots": {h: binding.extra_hand_slots.get(h, "own") for h in binding.extra_hands},
             "grasp_centres_m": {h: centres[h] for h in UdhmDatasetMeta(robot).block_hands() if h in centres}},
            indent=2))  # fmt: skip
        check_policy_checkpoint(tmp)  # what is shipped loads, before it is called bound
        move_into_place(tmp, output, Kind.POLICY, overwrite=overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return output


def _bound_pre_steps(steps: list, config: UdtConfigMixin, binding: Binding) -> list:
    """The pre-processor's steps with the mixed step bound to the robot and the native state step before it."""
    at = next((i for i, s in enumerate(steps) if isinstance(s, UniDexTokMixedTokenizerStep)), None)
    if at is None:
        raise DeployError(
            "the checkpoint's pre-processor has no unidextok.mixed_state_tokenizer step: not a mix policy"
        )
    old = steps[at]
    mixed = UniDexTokMixedTokenizerStep(**{**old.get_config(), "fixed_hand_ids": binding.fixed_hand_ids,
                                           "extra_hands": binding.extra_hands,
                                           "allow_unknown": config.udt_allow_unknown})  # fmt: skip
    mixed.load_state_dict(old.state_dict())
    return with_tokenizer_step(steps, mixed, config, binding)


def _bound_scale(steps: list, binding: Binding) -> list:
    """The per-hand steps (action scale, normaliser, slot mask; if any) with the robot's hands per block (a
    zero-shot hand: the normaliser's pooled statistics, `processor/hand_normalizer.py`)."""
    out = []
    for s in steps:
        if isinstance(s, HandActionScaleStep):
            s = HandActionScaleStep(**{**s.get_config(), "fixed_hand_ids": binding.fixed_hand_ids})
        elif isinstance(s, HandNormalizerStep):
            bound = HandNormalizerStep(**{**s.get_config(), "fixed_hand_ids": binding.fixed_hand_ids,
                                          "extra_hands": binding.extra_hands,
                                          "extra_hand_slots": binding.extra_hand_slots})  # fmt: skip
            bound.load_state_dict(s.state_dict())
            s = bound
        elif isinstance(s, SlotMaskStep):
            known = [h for h in s.hand_vocabulary if h not in binding.extra_hands]
            s = SlotMaskStep(**{**s.get_config(), "fixed_hand_ids": binding.fixed_hand_ids,
                                "hand_vocabulary": [*known, *binding.extra_hands],
                                "extra_hands": list(binding.extra_hands),
                                "extra_hand_slots": binding.extra_hand_slots})  # fmt: skip
        out.append(s)
    return out


def _check_slots_bound(pre_steps: list, post_steps: list) -> None:
    """A narrowed zero-shot hand needs the slot mask (its state held) and the hand normaliser's unnormalize (its
    action zeroed): refuse a checkpoint trained without them rather than bind half of it."""
    has_mask = any(isinstance(s, SlotMaskStep) for s in pre_steps)
    has_norm = any(isinstance(s, HandNormalizerStep) and s.mode == "unnormalize" and ACTION in s.modes
                   for s in post_steps)  # fmt: skip
    if not (has_mask and has_norm):
        raise DeployError(
            "--zero_shot_slots=nearest holds a zero-shot hand's other slots in the slot mask and zeroes their "
            "action in the hand normaliser; this checkpoint was trained without "
            f"{'the slot mask (udt_mask_slots)' if not has_mask else 'per-hand normalisation (udt_hand_norm)'}: "
            "bind it with --zero_shot_slots=own"
        )


__all__ = ["ZERO_SHOT_SLOTS", "Binding", "DeployError", "bind_layouts", "check_zero_shot_slots", "deploy", "driven_slots"]
