"""Pre-processor step: the robot's native `observation.state` -> the converted layout the policy was trained on.

A robot (LeRobot's `Robot.get_observation`, `lerobot-rollout`, the stock factory in Python) hands the policy
its own state, e.g. 14 G1 arm radians and 2 x 6 Inspire values in [0, 1] (26 wide). A `<type>_udt` policy
trained on a dataset converted by `unidextok-convert` reads the converted state (passthrough columns, then
one 22-wide UDHM block per hand: 58 wide). This step maps the first to the second with the native layout
the converter recorded (`meta/unidextok_conversion.json` "native_layout", docs/architecture.md): passthrough
columns copied by name, each hand's native columns through `hands.get(hand).to_udhm(values, side)` into its
block; it is the inverse of `unidextok.udhm_to_native` (processor_unidextok.py) and bit-exact with the
converter on float32 input.

Which layout comes in is decided by the width (`input_layout="auto"`): the native width is mapped, the
converted width (what `lerobot-train` feeds from the converted dataset) passes unchanged, any other width
is refused naming both layouts. When both widths coincide (every hand has 22 native joints, e.g. Shadow),
auto treats the input as converted (training data) and logs it once; set `input_layout="native"` for the
robot then (`preprocessor_overrides={"unidextok.native_to_udhm": {"input_layout": "native"}}`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.processor import ObservationProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.constants import OBS_STATE
from lerobot_unidextok.processor.layout import NativeLayout

logger = logging.getLogger(__name__)

NATIVE_STATE_STEP_NAME = "unidextok.native_to_udhm"
INPUT_LAYOUTS = ("auto", "native", "converted")
OUT_OF_RANGE = ("raise", "clip")


@ProcessorStepRegistry.register(NATIVE_STATE_STEP_NAME)
@dataclass
class NativeToUDHMStateStep(ObservationProcessorStep):
    """`observation.state` in the robot's native layout (..., native width) -> the converted layout (..., width).

    `names` are the converted state's names, `native_names` the robot's, in its order; `native_hands` one
    `{"side", "hand", "columns"}` per UDHM block (as in `meta/unidextok_conversion.json` "native_layout").
    Any leading shape works ((D,), (B, D), (B, T, D)); dtype and device are kept. Stateless: the whole
    layout is its JSON config, saved with the pipeline.
    """

    names: list[str] = field(default_factory=list)  # converted state names (passthrough + UDHM blocks)
    native_names: list[str] = field(default_factory=list)  # the robot's state names, in its order
    native_hands: list[dict[str, Any]] = field(default_factory=list)  # {"side", "hand", "columns"} per block
    mapping: str = "semantic"  # the converter's native -> UDHM mapping (meta/unidextok_conversion.json)
    input_layout: str = "auto"  # "auto": decided by width | "native" | "converted" (pass unchanged)
    on_out_of_range: str = "raise"  # native hand values outside their range: "raise" (as the converter) | "clip"
    input_key: str = OBS_STATE

    _layout: NativeLayout | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.input_layout not in INPUT_LAYOUTS:
            raise ValueError(f"input_layout must be one of {INPUT_LAYOUTS}, got {self.input_layout!r}")
        if self.on_out_of_range not in OUT_OF_RANGE:
            raise ValueError(f"on_out_of_range must be one of {OUT_OF_RANGE}, got {self.on_out_of_range!r}")
        if not self.names or not self.native_names:
            raise ValueError(
                f"{NATIVE_STATE_STEP_NAME} needs the converted state names and the native ones; build it with "
                "NativeToUDHMStateStep.from_layout(NativeLayout.from_dataset(root, 'observation.state'))"
            )
        self._layout = NativeLayout(self.names, self.native_names, self.native_hands, mapping=self.mapping)
        if not self._layout.invertible:
            self._layout.to_converted(torch.zeros(self._layout.native_dim))  # raises naming what is missing
        if self.input_layout == "auto" and self.ambiguous:
            logger.warning(
                "%s: the native and converted %s are both %d wide, so every input is taken as converted (the "
                "training data); on the robot set input_layout='native'",
                NATIVE_STATE_STEP_NAME, self.input_key, self._layout.native_dim,
            )  # fmt: skip

    @classmethod
    def from_layout(cls, layout: NativeLayout, **kwargs: Any) -> NativeToUDHMStateStep:
        return cls(
            names=layout.names,
            native_names=layout.native_names,
            native_hands=layout.hands,
            mapping=layout.mapping,
            **kwargs,
        )

    @property
    def layout(self) -> NativeLayout:
        assert self._layout is not None
        return self._layout

    @property
    def ambiguous(self) -> bool:
        """Whether the native and converted widths coincide (the width cannot tell them apart)."""
        return self.layout.native_dim == self.layout.converted_dim

    def is_native(self, width: int) -> bool:
        """Whether a `width`-wide state is the robot's native layout; a ValueError naming both layouts when
        it is neither (or not the one `input_layout` allows)."""
        native, converted = self.layout.native_dim, self.layout.converted_dim
        if self.input_layout == "native" and width == native:
            return True
        if self.input_layout == "converted" and width == converted:
            return False
        if self.input_layout == "auto" and width in (native, converted):
            return width != converted
        which = {"auto": "neither the native nor the converted layout", "native": "not the native layout",
                 "converted": "not the converted layout"}[self.input_layout]  # fmt: skip
        raise ValueError(
            f"{self.input_key} has width {width}, {which} this policy takes (input_layout={self.input_layout!r}): "
            f"native {self.layout.describe_native()}; converted {self.layout.describe_converted()}. Send the "
            "robot's state with exactly the native columns in this order (the training dataset's "
            "meta/unidextok_conversion.json native_layout)"
        )

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        if self.input_key not in observation:
            raise KeyError(
                f"{NATIVE_STATE_STEP_NAME} needs '{self.input_key}' in the observation, got {sorted(observation)}"
            )
        state = torch.as_tensor(observation[self.input_key])
        if state.ndim == 0:
            raise ValueError(f"{self.input_key} must be (D,), (B, D) or (B, T, D), got a scalar")
        if self.is_native(state.shape[-1]):
            try:
                observation[self.input_key] = self.layout.to_converted(state, self.on_out_of_range)
            except ValueError as err:
                hint = (
                    f" (to clip hand values outside their range instead: preprocessor_overrides="
                    f"{{'{NATIVE_STATE_STEP_NAME}': {{'on_out_of_range': 'clip'}}}})"
                    if "out of range" in str(err)
                    else ""
                )
                raise ValueError(f"native {self.input_key}: {err}{hint}") from err
        return observation

    # ----------------------------------------------------------------------------------------- contract
    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        """A native-width state (what the robot reports) becomes the converted width the policy reads."""
        obs = dict(features.get(PipelineFeatureType.OBSERVATION, {}))
        feat = obs.get(self.input_key)
        if feat is not None and feat.shape and self.is_native(feat.shape[-1]):
            obs[self.input_key] = PolicyFeature(type=feat.type, shape=(*feat.shape[:-1], self.layout.converted_dim))
        return {**features, PipelineFeatureType.OBSERVATION: obs}

    def get_config(self) -> dict[str, Any]:
        return {
            "names": list(self.names),
            "native_names": list(self.native_names),
            "native_hands": [dict(h) for h in self.native_hands],
            "mapping": self.mapping,
            "input_layout": self.input_layout,
            "on_out_of_range": self.on_out_of_range,
            "input_key": self.input_key,
        }


__all__ = ["INPUT_LAYOUTS", "NATIVE_STATE_STEP_NAME", "NativeToUDHMStateStep"]
