"""Which view of the hands a `<type>_udt` model reads (`udt_hand_input`): the UDHM state, the tokens, or both.

A `<type>_udt` pre-processor gives the model the converted `observation.state` (passthrough columns, then each
hand's UDHM block) and the tokenizer's view of the hands as `observation.environment_state`. To ask what the
tokens are worth against the state they encode, one of the two is held at zero before the normaliser, so the
model gets the same inputs with the other view constant:

- `both` (the default): nothing changes;
- `state`: the token view is zero; the hands reach the model as their UDHM state only (a mix's hand identity, the
  view's last `identity_width` columns, stays: it is not a view of the state). A `<type>_udt` policy's tokenizer
  step then does not encode at all (`encode=False`: the view comes zero from it); checkpoints saved before
  that encode and are zeroed here, the same inputs;
- `tokens`: the UDHM blocks of `observation.state` are zero (the passthrough columns stay); the hands reach the
  model only through the token view. The relative-action step before it has already read the real state.

Widths never change, so LeRobot's normaliser and the model are built as usual. (`experiments/closed_loop.py`
compares the views in closed loop.)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.processor import ObservationProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import OBS_HAND_TOKEN_FEATURES, OBS_STATE, UDHM_DIM

HAND_INPUT_STEP_NAME = "unidextok.hand_input"
HAND_INPUTS = ("both", "state", "tokens")


@ProcessorStepRegistry.register(HAND_INPUT_STEP_NAME)
@dataclass
class HandInputStep(ObservationProcessorStep):
    """Zero the token view (`mode="state"`) or the state's UDHM blocks (`mode="tokens"`); `both` passes."""

    mode: str = "both"
    state_names: list[str] = field(default_factory=list)  # observation.state's columns (they locate the blocks)
    identity_width: int = 0  # a mix's one-hot hand identity at the end of the token view (kept): blocks x vocabulary

    _columns: torch.Tensor | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.mode not in HAND_INPUTS:
            raise ValueError(f"udt_hand_input must be one of {HAND_INPUTS}, got {self.mode!r}")
        if self.mode == "tokens":
            blocks = find_udhm_blocks(self.state_names)
            if not blocks:
                raise ValueError("udt_hand_input='tokens' needs the state's column names, with UDHM blocks among them")
            self._columns = torch.cat([torch.arange(b.start, b.start + UDHM_DIM) for b in blocks])

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        if self.mode == "state" and OBS_HAND_TOKEN_FEATURES in observation:
            view = observation[OBS_HAND_TOKEN_FEATURES].clone()
            view[..., : view.shape[-1] - self.identity_width] = 0
            observation[OBS_HAND_TOKEN_FEATURES] = view
        elif self.mode == "tokens":
            state = observation[OBS_STATE].clone()
            state[..., self._columns.to(state.device)] = 0
            observation[OBS_STATE] = state
        return observation

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

    def get_config(self) -> dict[str, Any]:
        return {"mode": self.mode, "state_names": list(self.state_names), "identity_width": self.identity_width}


__all__ = ["HAND_INPUTS", "HAND_INPUT_STEP_NAME", "HandInputStep"]
