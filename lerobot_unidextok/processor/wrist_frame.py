"""The wrist position of state and action as the position of the hand's grasp centre (`unidextok.wrist_frame`).

Each hand's fingers close at another point relative to its wrist (`data/wrist_frame.py`). With the wrist pose
(x, y, z, roll, pitch, yaw) of the state and action and each hand's grasp centre `c_h` in the wrist frame, this
step replaces, per row and by that row's hand h,

    pre  (`to_centre`):  state xyz  -> xyz + R(state rpy) c_h;   action xyz -> xyz + R(action rpy) c_h
    post (`to_wrist`):   action xyz -> xyz - R(action rpy) c_h        (the exact inverse)

with R = Rz(yaw) Ry(pitch) Rx(roll) (the rotation the columns are recorded in). The rotations and the other
columns pass unchanged. The policy then learns where the grasp centre goes; each robot's own `c_h` gives its
wrist command back. It sits after the UniDexTok step (a robot's native state is in the converted layout there)
and before the relative step and every normaliser (pre), after the absolute step and the unnormalisers (post):
with relative actions the policy sees grasp-centre offsets, and the absolute step restores the grasp-centre
action before this step turns it into the wrist's.

A row's hand: the first state block that holds one in `observation.hand_ids` (a mix), else `fixed_hand_ids` (one
robot, or a checkpoint bound to one by `unidextok-deploy`); a row without a hand (every id -1) is left as it is.
The post step of an unbound mix reads the ids its paired pre step saw last (`pair`). The grasp centres are in the
step's config (`grasp_centres_m`), so the checkpoint's saved processors carry them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor import ProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE
from lerobot_unidextok.data.wrist_frame import NUM_COLUMNS, ROTATION, WristFrameError, check_centre
from lerobot_unidextok.processor.hand_rows import match_rows, row_hand_ids

WRIST_FRAME_STEP_NAME = "unidextok.wrist_frame"
MODES = ("to_centre", "to_wrist")


def rotation_rpy(rpy: torch.Tensor) -> torch.Tensor:
    """(..., 3) roll, pitch, yaw (rad) -> (..., 3, 3) rotation Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    roll, pitch, yaw = rpy.unbind(-1)
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (torch.cos, torch.sin))
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return torch.stack([torch.stack(r, -1) for r in rows], -2)


@ProcessorStepRegistry.register(WRIST_FRAME_STEP_NAME)
@dataclass
class WristFrameStep(ProcessorStep):
    """`to_centre` (pre: state and action) or `to_wrist` (post: action) by each row's hand (module docstring)."""

    mode: str = "to_centre"
    state_names: list[str] = field(default_factory=list)  # the converted state's columns
    action_names: list[str] = field(default_factory=list)  # the action's columns
    wrist_columns: list[str] = field(default_factory=list)  # x, y, z, roll, pitch, yaw, by name
    rotation: str = ROTATION
    hand_vocabulary: list[str] = field(default_factory=list)  # what the hand ids index
    grasp_centres_m: dict[str, list[float]] = field(default_factory=dict)  # hand -> (3,) in the wrist frame
    fixed_hand_ids: list[int] = field(default_factory=list)  # the hand per state block ([] = per row)
    hand_ids_key: str = OBS_HAND_IDS
    pair: WristFrameStep | None = field(default=None, repr=False)  # post: the pre step whose hand ids it reuses

    _last_ids: torch.Tensor | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        name = WRIST_FRAME_STEP_NAME
        if self.mode not in MODES:
            raise WristFrameError(f"{name}: mode must be one of {MODES}, got {self.mode!r}")
        if self.rotation != ROTATION:
            raise WristFrameError(f"{name}: rotation {self.rotation!r} is not supported; only {ROTATION!r}")
        if len(self.wrist_columns) != NUM_COLUMNS:
            raise WristFrameError(
                f"{name}: wrist_columns must name x, y, z, roll, pitch, yaw, got {self.wrist_columns}"
            )
        for what, names in (("state", self.state_names), ("action", self.action_names)):
            missing = [c for c in self.wrist_columns if c not in names]
            if missing:
                raise WristFrameError(
                    f"{name}: the {what} has no wrist columns {missing}; set --policy.udt_wrist_frame=robot to "
                    "train without the grasp-centre frame"
                )
        if not self.hand_vocabulary:
            raise WristFrameError(f"{name} needs the hand_vocabulary its hand ids index")
        lacking = [h for h in self.hand_vocabulary if h not in self.grasp_centres_m]
        if lacking:
            raise WristFrameError(f"{name}: no grasp centre for hands {lacking}; give one per hand "
                                  "(unidextok-deploy --grasp_centre_m='[x, y, z]' for the bound robot's)")  # fmt: skip
        self.grasp_centres_m = {h: check_centre(h, v, name) for h, v in self.grasp_centres_m.items()}
        self.fixed_hand_ids = [int(i) for i in self.fixed_hand_ids]
        self._num_blocks = max(1, len(find_udhm_blocks(self.state_names)))  # hand ids per row
        if self.fixed_hand_ids and len(self.fixed_hand_ids) != self._num_blocks:
            raise WristFrameError(f"{name}: fixed_hand_ids {self.fixed_hand_ids} must give one hand per state block "
                                  f"({self._num_blocks})")  # fmt: skip
        table = [self.grasp_centres_m[h] for h in self.hand_vocabulary] + [[0.0, 0.0, 0.0]]  # last: no hand
        self._table = torch.tensor(table, dtype=torch.float64)
        self._columns = {k: [n.index(c) for c in self.wrist_columns]
                         for k, n in ((OBS_STATE, self.state_names), (ACTION, self.action_names))}  # fmt: skip

    # ----------------------------------------------------------------------------------------- hands per row
    def _ids(self, observation: dict[str, Any] | None) -> torch.Tensor:
        last = self.pair._last_ids if self.mode == "to_wrist" and self.pair is not None else None
        return row_hand_ids(observation, self.hand_ids_key, self.fixed_hand_ids, last, self._num_blocks,
            f"{WRIST_FRAME_STEP_NAME} ({self.mode}) needs each row's hand ('{self.hand_ids_key}'): this policy "
            "was trained on a mix of hands in the grasp-centre frame. Bind it to your robot with "
            "`unidextok-deploy --checkpoint=... --robot=<its converted dataset> --output=...`")  # fmt: skip

    def _offsets(self, ids: torch.Tensor) -> torch.Tensor:
        """(R, H) hand ids -> (R, 3) grasp centre of each row's first hand (zero for a row without one)."""
        none = len(self.hand_vocabulary)
        if bool(((ids < -1) | (ids >= none)).any()):
            raise ValueError(f"{self.hand_ids_key} holds {sorted(set(ids.unique().tolist()))}, outside -1 .. "
                             f"{none - 1} (hands {self.hand_vocabulary})")  # fmt: skip
        present = ids >= 0
        first = torch.where(present.any(-1), present.float().argmax(-1), torch.zeros(len(ids), dtype=torch.long))
        hand = ids.gather(-1, first[:, None])[:, 0]
        return self._table[torch.where(hand < 0, none, hand)]

    @staticmethod
    def _broadcast(offsets: torch.Tensor, lead: tuple[int, ...]) -> torch.Tensor:
        """(R, 3) per-row offsets against a value of leading dims `lead` (batch, then time)."""
        offsets, view = match_rows(offsets, lead, WRIST_FRAME_STEP_NAME)
        return offsets.reshape(*view, 3) if lead else offsets.reshape(3)

    def _apply(self, key: str, x: torch.Tensor, offsets: torch.Tensor, sign: float) -> torch.Tensor:
        width = len(self.state_names if key == OBS_STATE else self.action_names)
        if x.shape[-1] != width:
            raise ValueError(f"{WRIST_FRAME_STEP_NAME}: {key} is {x.shape[-1]} wide, expected {width}")
        cols = self._columns[key]
        pose = x[..., cols].double()
        centre = self._broadcast(offsets.to(x.device), tuple(x.shape[:-1]))
        shift = (rotation_rpy(pose[..., 3:]) @ centre.expand(*pose.shape[:-1], 3)[..., None])[..., 0]
        out = x.clone()
        out[..., cols[:3]] = (pose[..., :3] + sign * shift).to(x.dtype)
        return out

    # ----------------------------------------------------------------------------------------- the step
    def __call__(self, transition: EnvTransition) -> EnvTransition:
        observation = transition.get(TransitionKey.OBSERVATION) or {}
        action = transition.get(TransitionKey.ACTION)
        new = transition.copy()
        if self.mode == "to_centre":
            state = observation.get(OBS_STATE)
            if state is None and action is None:
                return new
            offsets = self._offsets(ids := self._ids(observation))
            self._last_ids = ids
            if state is not None:
                observation = dict(observation)
                observation[OBS_STATE] = self._apply(OBS_STATE, torch.as_tensor(state), offsets, 1.0)
                new[TransitionKey.OBSERVATION] = observation
            if action is not None:
                new[TransitionKey.ACTION] = self._apply(ACTION, torch.as_tensor(action), offsets, 1.0)
        elif action is not None:
            offsets = self._offsets(self._ids(observation))
            new[TransitionKey.ACTION] = self._apply(ACTION, torch.as_tensor(action), offsets, -1.0)
        return new

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "state_names": list(self.state_names),
            "action_names": list(self.action_names),
            "wrist_columns": list(self.wrist_columns),
            "rotation": self.rotation,
            "hand_vocabulary": list(self.hand_vocabulary),
            "grasp_centres_m": {h: list(v) for h, v in self.grasp_centres_m.items()},
            "fixed_hand_ids": list(self.fixed_hand_ids),
            "hand_ids_key": self.hand_ids_key,
        }


__all__ = ["WRIST_FRAME_STEP_NAME", "WristFrameStep", "rotation_rpy"]
