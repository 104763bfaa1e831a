"""LeRobot processor steps around UniDexTok: hand states -> tokens (pre), UDHM -> native commands (post).

The only module of the package that imports `lerobot.processor`. Registry names contain no '/'
(a '/' breaks `save_pretrained` of stateful steps in lerobot 0.6).

Keys written by `UniDexTokStateTokenizerStep`:
- `observation.hand_tokens`: int64 `(H * N * K,)` codes, ordered (hand, token, group).
- `observation.environment_state`: float32 view for policies, `representation=`
  "dequantized" -> the decoded UDHM state, radians `(H * 22,)`;
  "embedding"   -> the unit-norm code vectors `(H * N * codebook_dim,)`.
Both keep the input's batch dimension (or its absence) and device.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from lerobot.configs.types import FeatureType, PipelineFeatureType, PolicyFeature
from lerobot.processor import (
    ObservationProcessorStep,
    PolicyActionProcessorStep,
    ProcessorStepRegistry,
)

from lerobot_unidextok import hands
from lerobot_unidextok.constants import (
    OBS_HAND_TOKEN_FEATURES,
    OBS_HAND_TOKENS,
    OBS_STATE,
    UDHM_DIM,
)
from lerobot_unidextok.processor.layout import HandLayout
from lerobot_unidextok.tokenizer import PRESETS, UniDexTok, UniDexTokConfig

logger = logging.getLogger(__name__)

STEP_NAME = "unidextok.state_tokenizer"
NATIVE_STEP_NAME = "unidextok.udhm_to_native"
REPRESENTATIONS = ("dequantized", "embedding")


# ---------------------------------------------------------------------------------------------
# tokenizer loading
# ---------------------------------------------------------------------------------------------
def load_tokenizer(pretrained: str) -> UniDexTok:
    """A UniDexTok checkpoint from a folder or a Hub repo id (the HF cache serves it offline)."""
    from huggingface_hub.errors import (
        HFValidationError,
        LocalEntryNotFoundError,
        OfflineModeIsEnabled,
    )

    try:
        return UniDexTok.from_pretrained(pretrained)
    except (LocalEntryNotFoundError, OfflineModeIsEnabled) as err:
        raise FileNotFoundError(
            f"UniDexTok checkpoint {pretrained!r} is not in the local HF cache and the Hub is unreachable "
            f"(HF_HUB_OFFLINE or no network): run `unidextok-pull --repo_id={pretrained}` first, "
            "or unset HF_HUB_OFFLINE"
        ) from err
    except HFValidationError as err:
        raise FileNotFoundError(
            f"{pretrained!r} is neither a checkpoint folder nor a Hub repo id (namespace/name)"
        ) from err


def tokenizer_output_dims(config: UniDexTokConfig, num_hands: int, representation: str) -> tuple[int, int]:
    """(token count, float feature width) the step adds for `num_hands` hands."""
    if representation not in REPRESENTATIONS:
        raise ValueError(f"representation must be one of {REPRESENTATIONS}, got {representation!r}")
    tokens = num_hands * config.num_tokens * config.num_groups
    width = UDHM_DIM if representation == "dequantized" else config.num_tokens * config.codebook_dim
    return tokens, num_hands * width


# ---------------------------------------------------------------------------------------------
# pre-processor step
# ---------------------------------------------------------------------------------------------
@ProcessorStepRegistry.register(STEP_NAME)
@dataclass
class UniDexTokStateTokenizerStep(ObservationProcessorStep):
    """Tokenise UDHM hand states in `observation.state` into int64 codes plus a float view.

    The tokenizer comes from `tokenizer_config` (+ weights through `load_state_dict`, as the
    pipeline does on reload), else from `pretrained` (folder or Hub repo id), else from `preset`
    with random weights (benchmarks, tests).
    """

    hand_layout: list[str] = field(default_factory=lambda: ["human"])  # hand spec name per 22-wide block
    pretrained: str | None = None  # checkpoint folder or Hub repo id
    embed_weights: bool = True  # save tokenizer weights with the pipeline; False = keep only `pretrained`
    tokenizer_config: dict[str, Any] | None = None  # UniDexTokConfig fields (written by get_config)
    preset: str = "small"  # used only without pretrained/tokenizer_config
    representation: str = "dequantized"  # "dequantized" | "embedding"
    allow_unknown: bool = True  # hands outside the tokenizer vocabulary use its "unknown hand" embedding
    input_key: str = OBS_STATE
    token_key: str = OBS_HAND_TOKENS
    features_key: str = OBS_HAND_TOKEN_FEATURES

    _tokenizer: UniDexTok | None = field(default=None, init=False, repr=False)
    _layout: HandLayout | None = field(default=None, init=False, repr=False)
    _hand_ids: torch.Tensor | None = field(default=None, init=False, repr=False)  # (H,) tokenizer hand ids
    _active: torch.Tensor | None = field(default=None, init=False, repr=False)  # (H, 22) bool

    def __post_init__(self) -> None:
        if self.representation not in REPRESENTATIONS:
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, got {self.representation!r}")
        self._layout = HandLayout(self.hand_layout)
        if self.tokenizer_config is not None and (self.embed_weights or self.pretrained is None):
            self._tokenizer = UniDexTok(UniDexTokConfig(**self.tokenizer_config)).eval()
        elif self.pretrained is not None:
            self._tokenizer = load_tokenizer(self.pretrained)
        else:
            if self.preset not in PRESETS:
                raise ValueError(f"unknown preset {self.preset!r}; choose one of {sorted(PRESETS)}")
            logger.warning(
                "UniDexTok step built from preset %r with untrained weights",
                self.preset,
            )
            self._tokenizer = UniDexTok(UniDexTokConfig.from_preset(self.preset)).eval()
        self.tokenizer_config = asdict(self._tokenizer.config)
        unknown = sorted(set(self.hand_layout) - set(self._tokenizer.config.hand_names))
        if unknown and not self.allow_unknown:
            raise ValueError(
                f"hands {unknown} are not in the tokenizer vocabulary {self._tokenizer.config.hand_names}; "
                "set allow_unknown=True (zero-shot 'unknown hand' embedding) or use a tokenizer trained on them"
            )
        if unknown:
            logger.warning(
                "hands %s are not in the tokenizer vocabulary: using its unknown-hand embedding",
                unknown,
            )
        self._hand_ids = torch.tensor([self._tokenizer._name_to_id(h, True) for h in self.hand_layout])
        # (H, 22) active-DoF masks: decoded values on slots a hand does not have are zeroed, as in the data.
        self._active = torch.as_tensor(np.stack([hands.get(h).active_mask for h in self.hand_layout]))

    @property
    def tokenizer(self) -> UniDexTok:
        assert self._tokenizer is not None
        return self._tokenizer

    @property
    def layout(self) -> HandLayout:
        assert self._layout is not None
        return self._layout

    # ----------------------------------------------------------------------------------------- core
    @torch.no_grad()
    def tokenize(self, states_rad: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, 22 * H) radians -> ((B, H*N*K) int64 tokens, (B, F) float32 view), on the input's device."""
        b, width = states_rad.shape
        self.layout.check_width(width, self.input_key)
        if not torch.isfinite(states_rad).all():
            bad = (~torch.isfinite(states_rad)).nonzero()[0].tolist()
            raise ValueError(
                f"{self.input_key} contains NaN/inf (first at [batch, dim] = {bad}); drop or fill those "
                "frames (e.g. mask untracked hands in the converter) before tokenising"
            )
        tok = self.tokenizer
        if tok.enc_pos.device != states_rad.device:
            tok.to(states_rad.device)
        h = self.layout.num_hands
        rows = states_rad.float().reshape(b * h, UDHM_DIM)  # (B*H, 22)
        if self._hand_ids.device != states_rad.device:
            self._hand_ids = self._hand_ids.to(states_rad.device)
        ids = self._hand_ids.repeat(b)  # (B*H,) one id per row, block order within each frame
        codes = tok.encode(rows, ids)  # (B*H, N, K)
        if self.representation == "dequantized":
            active = self._active.to(states_rad.device).repeat(b, 1)  # (B*H, 22)
            view = tok.decode(codes, ids) * active  # (B*H, 22) radians, inactive slots zero
        else:
            view = tok.quantizer.indices_to_codes(codes).flatten(1)  # (B*H, N*K*d)
        return codes.reshape(b, -1), view.reshape(b, -1).float()

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        if self.input_key not in observation:
            raise KeyError(f"{STEP_NAME} needs '{self.input_key}' in the observation, got {sorted(observation)}")
        state = torch.as_tensor(observation[self.input_key])
        if state.ndim not in (1, 2):
            raise ValueError(f"{self.input_key} must be (D,) or (B, D), got shape {tuple(state.shape)}")
        tokens, view = self.tokenize(state.reshape(-1, state.shape[-1]))  # (B, T), (B, F)
        if state.ndim == 1:
            tokens, view = tokens[0], view[0]
        observation[self.token_key] = tokens
        observation[self.features_key] = view
        return observation

    # ----------------------------------------------------------------------------------------- contract
    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        n_tokens, width = tokenizer_output_dims(self.tokenizer.config, self.layout.num_hands, self.representation)
        obs = dict(features.get(PipelineFeatureType.OBSERVATION, {}))
        obs[self.token_key] = PolicyFeature(type=FeatureType.STATE, shape=(n_tokens,))
        obs[self.features_key] = PolicyFeature(type=FeatureType.ENV, shape=(width,))
        return {**features, PipelineFeatureType.OBSERVATION: obs}

    def get_config(self) -> dict[str, Any]:
        return {
            "hand_layout": list(self.hand_layout),
            "pretrained": self.pretrained,
            "embed_weights": self.embed_weights,
            "tokenizer_config": self.tokenizer_config if self.embed_weights or self.pretrained is None else None,
            "preset": self.preset,
            "representation": self.representation,
            "allow_unknown": self.allow_unknown,
            "input_key": self.input_key,
            "token_key": self.token_key,
            "features_key": self.features_key,
        }

    def state_dict(self) -> dict[str, torch.Tensor]:
        if not self.embed_weights and self.pretrained is not None:
            return {}
        return {k: v.detach().cpu().contiguous() for k, v in self.tokenizer.state_dict().items()}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        if state:
            device = self.tokenizer.enc_pos.device
            self.tokenizer.load_state_dict({k: v.to(device) for k, v in state.items()}, strict=True)
            self.tokenizer.eval()


# ---------------------------------------------------------------------------------------------
# decoding side: UDHM states / tokens -> a robot hand's native command units
# ---------------------------------------------------------------------------------------------
def udhm_to_native(states_rad: torch.Tensor | np.ndarray, layout: HandLayout) -> np.ndarray:
    """(B, 22 * H) or (22 * H,) UDHM radians -> native commands of `layout`'s hands, blocks concatenated."""
    from lerobot_unidextok import hands as hand_registry

    x = torch.as_tensor(states_rad).detach().cpu().numpy().astype(np.float64)
    squeeze = x.ndim == 1
    x = x.reshape(-1, x.shape[-1])
    layout.check_width(x.shape[-1], "UDHM state")
    sides = layout.sides or ["right"] * layout.num_hands
    out = [
        np.asarray(hand_registry.get(name).from_udhm(x[:, i * UDHM_DIM : (i + 1) * UDHM_DIM], side))
        for i, (name, side) in enumerate(zip(layout.hands, sides, strict=True))
    ]
    native = np.concatenate([o.reshape(x.shape[0], -1) for o in out], axis=-1)  # (B, sum native dims)
    return native[0] if squeeze else native


def tokens_to_native(tokens: torch.Tensor, tokenizer: UniDexTok, layout: HandLayout) -> np.ndarray:
    """(B, H*N*K) or (H*N*K,) codes -> decoded UDHM -> native commands (see `udhm_to_native`)."""
    tokens = torch.as_tensor(tokens)
    squeeze = tokens.ndim == 1
    b = 1 if squeeze else tokens.shape[0]
    cfg = tokenizer.config
    codes = tokens.reshape(b * layout.num_hands, cfg.num_tokens, cfg.num_groups)  # (B*H, N, K)
    states = tokenizer.decode(codes, layout.hands * b, allow_unknown=True).reshape(b, -1)  # (B, 22*H)
    native = udhm_to_native(states, layout)
    return native[0] if squeeze else native


@ProcessorStepRegistry.register(NATIVE_STEP_NAME)
@dataclass
class UDHMToNativeCommandStep(PolicyActionProcessorStep):
    """Post-processor: a predicted UDHM action (B, 22 * H) -> the robot hands' native command units."""

    hand_layout: list[str] = field(default_factory=lambda: ["inspire_rh56"])  # hand spec per block
    sides: list[str] = field(default_factory=list)  # side per block; [] = all right

    def __post_init__(self) -> None:
        self._layout = HandLayout(self.hand_layout, self.sides)

    def action(self, action: torch.Tensor) -> torch.Tensor:
        native = udhm_to_native(action, self._layout)
        return torch.as_tensor(native, dtype=torch.float32, device=torch.as_tensor(action).device)

    def native_dim(self) -> int:
        from lerobot_unidextok import hands as hand_registry

        return sum(len(hand_registry.get(h).joint_names) for h in self.hand_layout)

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        acts = dict(features.get(PipelineFeatureType.ACTION, {}))
        for key, feat in acts.items():
            acts[key] = PolicyFeature(type=feat.type, shape=(self.native_dim(),))
        return {**features, PipelineFeatureType.ACTION: acts}

    def get_config(self) -> dict[str, Any]:
        return {"hand_layout": list(self.hand_layout), "sides": list(self.sides)}
