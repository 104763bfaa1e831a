"""The two native steps, one per direction, between a robot's own vectors and the converted layout a
`<type>_udt` policy reads and predicts:

- `NativeToUDHMStateStep` (`unidextok.native_to_udhm`, pre-processor): the robot's native `observation.state`
  (e.g. 14 G1 arm radians and 2 x 6 Inspire values in [0, 1], 26 wide) -> the converted state (passthrough
  columns, then one 22-wide UDHM block per hand: 58 wide), through `NativeLayout.to_converted`: passthrough
  columns copied by name, each hand's native columns through `hands.get(hand).to_udhm(values, side)` into its
  block; bit-exact with the converter on float32 input.
- `UDHMToNativeCommandStep` (`unidextok.udhm_to_native`, post-processor): a predicted converted action -> the
  robot's native action, through `NativeLayout.to_native`.

Both take the layout the converter recorded (`meta/unidextok_conversion.json` "native_layout",
docs/architecture.md) and save it as their JSON config. `udhm_to_native` / `tokens_to_native` do the same
decoding outside a pipeline.

Which layout comes into `NativeToUDHMStateStep` is decided by the width (`input_layout="auto"`): the native
width is mapped, the converted width (what `lerobot-train` feeds from the converted dataset) passes unchanged,
any other width is refused naming both layouts. When both widths coincide (every hand has 22 native joints,
e.g. Shadow), auto treats the input as converted (training data) and logs it once; set
`input_layout="native"` for the robot then (`preprocessor_overrides={"unidextok.native_to_udhm":
{"input_layout": "native"}}`), or send `observation.state_is_native` = 1 beside the state, as the simulator does
(`lerobot_env_unidextok`): a state so marked is always taken as native and must have the native width.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from lerobot.configs.types import PipelineFeatureType, PolicyFeature
from lerobot.processor import ObservationProcessorStep, PolicyActionProcessorStep, ProcessorStepRegistry

from lerobot_unidextok.constants import OBS_STATE, OBS_STATE_IS_NATIVE
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.layout import HandLayout, NativeLayout
from lerobot_unidextok.tokenizer import UniDexTok

logger = logging.getLogger(__name__)

NATIVE_TO_UDHM_STEP_NAME = "unidextok.native_to_udhm"
UDHM_TO_NATIVE_STEP_NAME = "unidextok.udhm_to_native"
INPUT_LAYOUTS = ("auto", "native", "converted")
OUT_OF_RANGE = ("raise", "clip")


@ProcessorStepRegistry.register(NATIVE_TO_UDHM_STEP_NAME)
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
    # a robot bound into a mix (unidextok-deploy): blocks it has no hand for (zeros), native columns read past
    absent_sides: list[str] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    # ... and its own converted state (its converted dataset's columns), also accepted: columns taken by name
    robot_names: list[str] = field(default_factory=list)
    input_layout: str = "auto"  # "auto": decided by width | "native" | "converted" (pass unchanged)
    on_out_of_range: str = "raise"  # native hand values outside their range: "raise" (as the converter) | "clip"
    input_key: str = OBS_STATE

    _layout: NativeLayout | None = field(default=None, init=False, repr=False)
    _from_robot: tuple[list[int], list[int]] | None = field(default=None, init=False, repr=False)  # (dst, src)

    def __post_init__(self) -> None:
        if self.robot_names:  # the robot's converted columns -> the converted layout, by name (absent ones zero)
            where = {n: i for i, n in enumerate(self.robot_names)}
            pairs = [(i, where[n]) for i, n in enumerate(self.names) if n in where]
            self._from_robot = ([d for d, _ in pairs], [s for _, s in pairs])
        if self.input_layout not in INPUT_LAYOUTS:
            raise ValueError(f"input_layout must be one of {INPUT_LAYOUTS}, got {self.input_layout!r}")
        if self.on_out_of_range not in OUT_OF_RANGE:
            raise ValueError(f"on_out_of_range must be one of {OUT_OF_RANGE}, got {self.on_out_of_range!r}")
        if not self.names or not self.native_names:
            raise ValueError(
                f"{NATIVE_TO_UDHM_STEP_NAME} needs the converted state names and the native ones; build it with "
                "NativeToUDHMStateStep.from_layout(UdhmDatasetMeta(root).native_layout('observation.state'))"
            )
        self._layout = NativeLayout(self.names, self.native_names, self.native_hands, mapping=self.mapping,
                                    absent_sides=self.absent_sides, dropped=self.dropped)  # fmt: skip
        if not self._layout.invertible:
            self._layout.to_converted(torch.zeros(self._layout.native_dim))  # raises naming what is missing
        if self.input_layout == "auto" and self.ambiguous:
            logger.warning(
                "%s: the native and converted %s are both %d wide, so every input is taken as converted (the "
                "training data) unless observation.state_is_native says otherwise (the simulator does); on a robot "
                "set input_layout='native'",
                NATIVE_TO_UDHM_STEP_NAME, self.input_key, self._layout.native_dim,
            )  # fmt: skip

    @classmethod
    def from_layout(cls, layout: NativeLayout, **kwargs: Any) -> NativeToUDHMStateStep:
        return cls(
            names=layout.names,
            native_names=layout.native_names,
            native_hands=layout.hands,
            mapping=layout.mapping,
            absent_sides=layout.absent_sides,
            dropped=layout.dropped,
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
                f"{NATIVE_TO_UDHM_STEP_NAME} needs '{self.input_key}' in the observation, got {sorted(observation)}"
            )
        state = torch.as_tensor(observation[self.input_key])
        if state.ndim == 0:
            raise ValueError(f"{self.input_key} must be (D,), (B, D) or (B, T, D), got a scalar")
        if _says_native(observation.get(OBS_STATE_IS_NATIVE)):
            if state.shape[-1] != self.layout.native_dim:  # a user error: one `error:` line in LeRobot's CLIs
                raise InvalidInputError(
                    f"{self.input_key} is the native state of the robot or simulator ({state.shape[-1]} values), but "
                    f"this policy takes {self.layout.describe_native()}: it was trained on another robot or hand. "
                    "Bind it to this one with unidextok-deploy --checkpoint=<policy> --robot=<this robot's converted "
                    "dataset> (--zero_shot=true when its hand was not in the policy's training data)"
                )
            observation[self.input_key] = self.layout.to_converted(state, self.on_out_of_range)
        elif self._from_robot is not None and state.shape[-1] == len(self.robot_names) != self.layout.converted_dim:
            dst, src = self._from_robot
            out = state.new_zeros((*state.shape[:-1], self.layout.converted_dim))
            out[..., dst] = state[..., src]
            observation[self.input_key] = out
        elif self.is_native(state.shape[-1]):
            try:
                observation[self.input_key] = self.layout.to_converted(state, self.on_out_of_range)
            except ValueError as err:
                hint = (
                    f" (to clip hand values outside their range instead: preprocessor_overrides="
                    f"{{'{NATIVE_TO_UDHM_STEP_NAME}': {{'on_out_of_range': 'clip'}}}})"
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
        robot_width = len(self.robot_names) if self.robot_names else None
        if feat is not None and feat.shape and (feat.shape[-1] == robot_width or self.is_native(feat.shape[-1])):
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
            **({"absent_sides": list(self.absent_sides)} if self.absent_sides else {}),
            **({"dropped": list(self.dropped)} if self.dropped else {}),
            **({"robot_names": list(self.robot_names)} if self.robot_names else {}),
        }


def _says_native(flag: Any) -> bool:
    """Whether an `observation.state_is_native` value (absent, a number or a (B, 1) tensor) says native."""
    if flag is None:
        return False
    flag = torch.as_tensor(flag)
    return bool(flag.numel()) and bool((flag.reshape(-1) > 0.5).all())


# ---------------------------------------------------------------------------------------------
# decoding side: UDHM states / tokens -> a robot's native command units
# ---------------------------------------------------------------------------------------------
def udhm_to_native(states_rad: torch.Tensor | np.ndarray, layout: HandLayout | NativeLayout) -> np.ndarray:
    """(..., D) converted vectors -> the robot's native vectors (float64).

    With a `HandLayout` the input is its state (`state_names`, or the UDHM blocks only when it has none)
    and the output its passthrough columns, then each hand's native joints in block order; with a
    `NativeLayout` the input is the converted vector and the output the robot's native vector in the
    converter's recorded order (passthrough copied by name).
    """
    if isinstance(layout, HandLayout):
        sides = layout.sides or ["right"] * layout.num_hands
        layout = NativeLayout.from_hands(layout.hands, sides, layout.state_names or None)
    return layout.to_native(torch.as_tensor(states_rad).detach().cpu().numpy())


def tokens_to_native(tokens: torch.Tensor, tokenizer: UniDexTok, layout: HandLayout) -> np.ndarray:
    """(B, H*N*K) or (H*N*K,) codes -> decoded UDHM -> each hand's native commands (see `udhm_to_native`)."""
    tokens = torch.as_tensor(tokens)
    squeeze = tokens.ndim == 1
    b = 1 if squeeze else tokens.shape[0]
    cfg = tokenizer.config
    codes = tokens.reshape(b * layout.num_hands, cfg.num_tokens, cfg.num_groups)  # (B*H, N, K)
    states = tokenizer.decode(codes, layout.hands * b, allow_unknown=True).reshape(b, -1)  # (B, 22*H)
    native = udhm_to_native(states, HandLayout(layout.hands, layout.sides))
    return native[0] if squeeze else native


@ProcessorStepRegistry.register(UDHM_TO_NATIVE_STEP_NAME)
@dataclass
class UDHMToNativeCommandStep(PolicyActionProcessorStep):
    """Post-processor: a predicted converted action (..., D) -> the robot's native action (..., D_native).

    Whole robot: `names` (the converted action's names), `native_names` and `native_hands` (one
    `{"side", "hand", "columns"}` per block) as in `meta/unidextok_conversion.json` "native_layout";
    passthrough columns (arms...) are copied unchanged, hands go to native units via the hand registry.
    Hands only (`names` empty): the action is the UDHM blocks of `hand_layout` / `sides`, the output each
    hand's native joints in block order.
    """

    hand_layout: list[str] = field(default_factory=lambda: ["inspire_rh56"])  # hand spec per block
    sides: list[str] = field(default_factory=list)  # side per block; [] = all right
    names: list[str] = field(default_factory=list)  # converted action names (whole robot)
    native_names: list[str] = field(default_factory=list)  # native action names, in the robot's order
    native_hands: list[dict[str, Any]] = field(default_factory=list)  # {"side", "hand", "columns"} per block
    mapping: str = "semantic"  # the converter's native -> UDHM mapping (meta/unidextok_conversion.json)
    absent_sides: list[str] = field(default_factory=list)  # blocks of a mix this robot has no hand for

    _native: NativeLayout | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.names:
            self._native = NativeLayout(self.names, self.native_names, self.native_hands, mapping=self.mapping,
                                        absent_sides=self.absent_sides)  # fmt: skip
        else:
            sides = list(self.sides) or ["right"] * len(self.hand_layout)
            self._native = NativeLayout.from_hands(list(self.hand_layout), sides)

    @classmethod
    def from_layout(cls, layout: NativeLayout) -> UDHMToNativeCommandStep:
        return cls(
            hand_layout=[h["hand"] for h in layout.hands],
            sides=[h["side"] for h in layout.hands],
            names=layout.names,
            native_names=layout.native_names,
            native_hands=layout.hands,
            mapping=layout.mapping,
            absent_sides=layout.absent_sides,
        )

    @property
    def layout(self) -> NativeLayout:
        assert self._native is not None
        return self._native

    def action(self, action: torch.Tensor) -> torch.Tensor:
        action = torch.as_tensor(action)
        native = self.layout.to_native(action.detach().cpu().numpy())
        return torch.as_tensor(native, dtype=torch.float32, device=action.device)

    def native_dim(self) -> int:
        return self.layout.native_dim

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        acts = dict(features.get(PipelineFeatureType.ACTION, {}))
        for key, feat in acts.items():
            acts[key] = PolicyFeature(type=feat.type, shape=(self.native_dim(),))
        return {**features, PipelineFeatureType.ACTION: acts}

    def get_config(self) -> dict[str, Any]:
        return {
            "hand_layout": list(self.hand_layout),
            "sides": list(self.sides),
            "names": list(self.names),
            "native_names": list(self.native_names),
            "native_hands": [dict(h) for h in self.native_hands],
            **({"mapping": self.mapping} if self.mapping != "semantic" else {}),
            **({"absent_sides": list(self.absent_sides)} if self.absent_sides else {}),
        }


__all__ = [
    "INPUT_LAYOUTS",
    "NATIVE_TO_UDHM_STEP_NAME",
    "UDHM_TO_NATIVE_STEP_NAME",
    "NativeToUDHMStateStep",
    "UDHMToNativeCommandStep",
    "tokens_to_native",
    "udhm_to_native",
]
