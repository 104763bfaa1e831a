"""The bound robot's grasp centre for a checkpoint that learned the wrist in the grasp-centre frame
(`unidextok-deploy`, `processor/wrist_frame.py`).

A `<type>_udt` policy trained with `udt_grasp_centres_m` predicts where each hand's grasp centre goes; the bound
checkpoint's `unidextok.wrist_frame` steps turn that into the robot's wrist command with the robot's own grasp
centre, taken, per robot hand, from (first that has it):

1. `--grasp_centre_m='[x, y, z]'` (m, in the wrist frame of the wrist columns, within 0.3 m of the wrist), for
   every hand of the robot; a centre the robot's dataset records that it overrides is named in a one-line note;
2. the robot's converted dataset (its record's `wrist_frame`: the simulator's recordings have it);
3. the checkpoint (a hand it trained on).

A hand none of these gives (a zero-shot hand whose dataset records no frame) is refused, naming the flag: a
guessed centre would put its fingers where another hand's close, the error the frame exists to remove.
"""

from __future__ import annotations

import logging

import numpy as np

from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.wrist_frame import WristFrame, check_centre
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.policies.udt_config import UdtConfigMixin
from lerobot_unidextok.policies.udt_processor import row_hands
from lerobot_unidextok.processor import WristFrameStep

logger = logging.getLogger(__name__)


class FrameBindError(InvalidInputError):
    """The robot's grasp centre cannot be fixed; the message names why and the flag that gives it."""


def bound_grasp_centres(config: UdtConfigMixin, robot: UdhmDatasetMeta,
                        grasp_centre_m: list[float] | None = None) -> dict[str, list[float]]:  # fmt: skip
    """The checkpoint's grasp centres with the robot's hands' fixed (module docstring); {} without a frame."""
    if not config.uses_wrist_frame:
        if grasp_centre_m is not None:
            raise FrameBindError(
                "--grasp_centre_m is given, but this checkpoint did not learn the wrist in the grasp-centre frame "
                "(its config has no udt_grasp_centres_m): leave the flag out"
            )
        return {}
    centres = {h: list(v) for h, v in config.udt_grasp_centres_m.items()}
    recorded: dict[str, list[float]] = {}
    if robot.record is not None and robot.record.wrist_frame:
        frame = WristFrame.from_dict(robot.record.wrist_frame, f"{robot.root} conversion record, wrist_frame")
        columns = frame.renamed(config.udt_name_map).columns
        if columns != list(config.udt_wrist_columns):
            raise FrameBindError(
                f"{robot.root} records its wrist in columns {columns}, the policy in "
                f"{list(config.udt_wrist_columns)}: bind a robot with the policy's wrist columns"
            )
        recorded = frame.grasp_centre_in_wrist_m
    hands = list(dict.fromkeys(robot.block_hands()))
    flag = None if grasp_centre_m is None else check_centre(" + ".join(hands), grasp_centre_m, "--grasp_centre_m")
    for hand in hands:
        if flag is not None:
            known, whose = (recorded, f"{robot.root} records") if hand in recorded else (centres, "the checkpoint has")
            if hand in known and not np.allclose(known[hand], flag, rtol=0, atol=1e-6):
                logger.warning("note: --grasp_centre_m=%s overrides the grasp centre %s m of %r that %s", flag,
                               list(known[hand]), hand, whose)  # fmt: skip
            centres[hand] = list(flag)
        elif hand in recorded:
            if hand in centres and not np.allclose(centres[hand], recorded[hand], rtol=0, atol=1e-6):
                logger.warning("note: %s records the grasp centre %s m of %r, the checkpoint learned %s m (recorded "
                               "with another hand model?); the robot's is used: pass --grasp_centre_m=%s to keep the "
                               "checkpoint's", robot.root, list(recorded[hand]), hand, centres[hand],
                               list(centres[hand]))  # fmt: skip
            centres[hand] = list(recorded[hand])
        elif hand not in centres:
            raise FrameBindError(
                f"the policy learned the wrist in each hand's grasp-centre frame, and nothing gives the grasp centre "
                f"of {hand!r} ({robot.root} records no wrist frame for it): pass --grasp_centre_m='[x, y, z]' (m, "
                "where its fingers close in its wrist frame)"
            )
    return centres


def bound_frame_steps(steps: list, config: UdtConfigMixin) -> list:
    """`steps` with each `unidextok.wrist_frame` step on the bound config's hands (fixed per block) and centres."""
    known, extra, fixed = row_hands(config)
    vocabulary = [*known, *extra]
    out = []
    for s in steps:
        if isinstance(s, WristFrameStep):
            centres = {h: config.udt_grasp_centres_m[h] for h in vocabulary}
            s = WristFrameStep(**{**s.get_config(), "hand_vocabulary": vocabulary, "fixed_hand_ids": fixed,
                                  "grasp_centres_m": centres})  # fmt: skip
        out.append(s)
    return out


__all__ = ["FrameBindError", "bound_frame_steps", "bound_grasp_centres"]
