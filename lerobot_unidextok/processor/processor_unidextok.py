"""The UniDexTok processor step: hand states -> tokens (pre-processor).

With `native.py` (the robot's native vectors <-> the converted layout), the only modules of the package that
import `lerobot.processor`. Registry names contain no '/' (a '/' breaks `save_pretrained` of stateful steps in
lerobot 0.6).

The state may be a whole robot: only the UDHM blocks (found by name) are tokenised.
Keys written by `UniDexTokStateTokenizerStep`:
- `observation.hand_tokens`: int64 `(H * N * K * S,)` codes, ordered (hand, token, stage-group); S = the
  tokenizer's quantiser stages (1 unless it has residual stages).
- `observation.environment_state`: float32 view for policies, `representation=`
  "dequantized" -> the decoded UDHM state, radians `(H * 22,)`;
  "embedding"   -> the unit-norm code vectors `(H * N * codebook_dim * S,)`.
Both keep the input's leading shape ((), (B,), (B, T)) and device.
"""

from __future__ import annotations

import logging
from dataclasses import InitVar, asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from lerobot.configs.types import FeatureType, PipelineFeatureType, PolicyFeature
from lerobot.processor import (
    ObservationProcessorStep,
    ProcessorStepRegistry,
)

from lerobot_unidextok import hands
from lerobot_unidextok.constants import (
    OBS_HAND_TOKEN_FEATURES,
    OBS_HAND_TOKENS,
    OBS_STATE,
    UDHM_DIM,
)
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.layout import HandLayout
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, untrained_preset
from lerobot_unidextok.processor.guards import (
    RANGE_CHECKS,
    check_batch,
    check_ranges,
    check_registry,
    layout_bounds,
    untrained_hands,
)
from lerobot_unidextok.tokenizer import EncodingConfig, UniDexTok, UniDexTokConfig
from lerobot_unidextok.tokenizer.configuration_unidextok import upgrade_legacy_encoding

logger = logging.getLogger(__name__)

STEP_NAME = "unidextok.state_tokenizer"
REPRESENTATIONS = ("dequantized", "embedding")


# ---------------------------------------------------------------------------------------------
# tokenizer loading
# ---------------------------------------------------------------------------------------------
def tokenizer_output_dims(
    config: UniDexTokConfig, num_hands: int, representation: str, identity_width: int = 0
) -> tuple[int, int]:
    """(token count, float feature width) the step adds for `num_hands` hands; a mixed dataset's step also
    appends a hand identity `identity_width` wide per block (`processor/mixed.identity_width`)."""
    if representation not in REPRESENTATIONS:
        raise ValueError(f"representation must be one of {REPRESENTATIONS}, got {representation!r}")
    tokens = num_hands * config.symbols_per_hand()
    width = UDHM_DIM if representation == "dequantized" else config.num_tokens * config.codebook_dim * config.num_stages
    return tokens, num_hands * (width + identity_width)


# ---------------------------------------------------------------------------------------------
# pre-processor step
# ---------------------------------------------------------------------------------------------
@ProcessorStepRegistry.register(STEP_NAME)
@dataclass
class UniDexTokStateTokenizerStep(ObservationProcessorStep):
    """Tokenise the UDHM hand blocks of `observation.state` into int64 codes plus a float view.

    The state may be hands only (22 * H) or a whole robot (arms, grippers... then the blocks, `state_names`
    says which columns are which); only the blocks are tokenised, the state itself passes unchanged. Any
    leading shape works: (D,), (B, D), temporal stacks (B, T, D).

    The tokenizer comes from `tokenizer_config` (+ weights through `load_state_dict`, as the
    pipeline does on reload), else from `pretrained` (folder, shipped id or Hub repo id; default
    `DEFAULT_TOKENIZER`, the shipped `unidextok/universal-small-residual`, trained on every registered hand and
    encoding with its nearest codes), else, only when asked for with
    `preset=` (and `pretrained` left at its default) or `pretrained=None`, an untrained preset with random
    weights (benchmarks, tests).
    """

    hand_layout: list[str] = field(default_factory=lambda: ["human"])  # hand spec name per UDHM block
    state_names: list[str] = field(default_factory=list)  # names of the whole state; [] = blocks only
    pretrained: str | None = DEFAULT_TOKENIZER  # checkpoint folder, shipped id or Hub repo id
    embed_weights: bool = True  # save tokenizer weights with the pipeline; False = keep only `pretrained`
    tokenizer_config: dict[str, Any] | None = None  # UniDexTokConfig fields (written by get_config)
    # An untrained preset (tiny | small | paper) instead of the default `pretrained`; None = no preset
    # (`pretrained=None` without a preset: untrained `small`).
    preset: str | None = None
    representation: str = "dequantized"  # "dequantized" | "embedding"
    # Hands the tokenizer has no trained embedding for: False = refuse (ValueError naming them);
    # True = tokenise them zero-shot with the tokenizer's "unknown hand" embedding (logged once).
    allow_unknown: bool = False
    range_check: str = "raise"  # states outside the hands' ranges (degrees, normalised): raise | warn | off
    # How codes are picked instead of the tokenizer's own encoding (an EncodingConfig, or its dict as saved):
    # None = the tokenizer's (the shipped tokenizer's config searches: docs/tokenizer.md "Code search", its cost
    # per frame and per row); EncodingConfig(rounds=0) = each group's nearest code, the paper's and the cheapest.
    encoding: EncodingConfig | None = None
    # Legacy (steps saved before EncodingConfig): rounds of the tokenizer's own search, upgraded on load into
    # `encoding` (the tokenizer's encoding with that many rounds); not saved.
    search_rounds: InitVar[int | None] = None
    # False: the tokenizer is not run; the tokens are -1 (no code) and the token view zero, the widths unchanged.
    # A `<type>_udt` policy that reads the state alone (`udt_hand_input=state`) never reads them: the step then
    # still converts, checks and (on a mix) gives each row's hand identity, without paying for the encoding.
    encode: bool = True
    input_key: str = OBS_STATE
    token_key: str = OBS_HAND_TOKENS
    features_key: str = OBS_HAND_TOKEN_FEATURES

    _tokenizer: UniDexTok | None = field(default=None, init=False, repr=False)
    _layout: HandLayout | None = field(default=None, init=False, repr=False)
    _hand_ids: torch.Tensor | None = field(default=None, init=False, repr=False)  # (H,) tokenizer hand ids
    _active: torch.Tensor | None = field(default=None, init=False, repr=False)  # (H, 22) bool
    _columns: torch.Tensor | None = field(default=None, init=False, repr=False)  # (22*H,) block columns
    _bounds: tuple[torch.Tensor, torch.Tensor] | None = field(default=None, init=False, repr=False)  # (H, 22) x2

    def __post_init__(self, search_rounds: int | None = None) -> None:
        self._check_settings()
        self.hand_layout, self.state_names = list(self.hand_layout), list(self.state_names)
        check_registry(self.hand_layout)  # before any weights are loaded or anything is logged
        self._layout = HandLayout(self.hand_layout, state_names=self.state_names)
        self._load_tokenizer()
        self._upgrade_legacy_rounds(search_rounds)
        self._hand_ids = torch.tensor(self._tokenizer_hand_ids(self.hand_layout))
        # (H, 22) active-DoF masks: decoded values on slots a hand does not have are zeroed, as in the data.
        self._active = torch.as_tensor(np.stack([hands.get(h).active_mask for h in self.hand_layout]))
        columns = self._layout.block_columns
        self._columns = None if np.array_equal(columns, np.arange(self._layout.state_dim)) else torch.as_tensor(columns)
        self._bounds = layout_bounds(self.hand_layout, self._layout.sides)

    def _check_settings(self) -> None:
        if self.representation not in REPRESENTATIONS:
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, got {self.representation!r}")
        if self.range_check not in RANGE_CHECKS:
            raise ValueError(f"range_check must be one of {RANGE_CHECKS}, got {self.range_check!r}")
        if self.encoding is not None:
            self.encoding = EncodingConfig.from_dict(self.encoding)  # a dict when loaded from a saved pipeline

    def _load_tokenizer(self) -> None:
        """The tokenizer from `tokenizer_config` (weights follow through `load_state_dict`), `pretrained`, or an
        untrained preset when one is asked for (`pretrained.untrained_preset`)."""
        preset = untrained_preset(self.pretrained, self.preset)
        if self.tokenizer_config is not None and (self.embed_weights or self.pretrained is None):
            # a step saved before EncodingConfig has the flat legacy keys; without `search_method` it loaded with
            # the default method, and still does
            config = upgrade_legacy_encoding(self.tokenizer_config, method_when_absent=None)
            self._tokenizer = UniDexTok(UniDexTokConfig(**config)).eval()
        elif preset is None:
            self._tokenizer = UniDexTok.from_pretrained(self.pretrained)
        else:
            logger.warning("UniDexTok step built from preset %r with untrained weights", preset)
            self.pretrained = None  # the weights are this preset's, not the default checkpoint's
            self._tokenizer = UniDexTok(UniDexTokConfig.from_preset(preset)).eval()
        self.tokenizer_config = asdict(self._tokenizer.config)
        stages = self._tokenizer.config.num_stages
        if self.encoding is not None and self.encoding.rounds and stages > 1:
            raise ValueError(f"the code search picks one stage's codes and this tokenizer has {stages}: give the step "
                             "the nearest codes (encoding=NEAREST_CODES, --policy.udt_encoding.rounds=0) or none")  # fmt: skip

    def _upgrade_legacy_rounds(self, search_rounds: int | None) -> None:
        """A step saved before EncodingConfig (`search_rounds`=R): the tokenizer's own encoding with R rounds, as it
        encoded then."""
        if search_rounds is None:
            return
        if self.encoding is not None:
            raise ValueError("give `encoding` only: `search_rounds` is its legacy form (steps saved before it)")
        self.encoding = replace(self.tokenizer.config.encoding, rounds=search_rounds)  # checked by EncodingConfig

    def _tokenizer_hand_ids(self, hand_names: list[str]) -> list[int]:
        """The tokenizer's hand id of each name: refused (or, with `allow_unknown`, its unknown-hand id) for a
        hand the tokenizer was not trained on."""
        cfg = self._tokenizer.config
        unseen = untrained_hands(hand_names, cfg.hand_names, cfg.trained_hands)
        if unseen and not self.allow_unknown:
            seen = cfg.trained_hands or cfg.hand_names
            raise ValueError(
                f"the tokenizer was not trained on hands {unseen} (it knows {seen}), so their tokens would be "
                "meaningless. Use a tokenizer trained or few-shot adapted on them (unidextok-train --init_from), "
                "or set allow_unknown=True (--policy.udt_allow_unknown=true) to tokenise them zero-shot with the "
                "tokenizer's unknown-hand embedding"
            )
        if unseen:
            logger.warning(
                "hands %s were never trained in this tokenizer: tokenising them zero-shot with its unknown-hand "
                "embedding (allow_unknown=True)",
                unseen,
            )
        return [cfg.hand_names.index(h) if h not in unseen else self._tokenizer.unknown_hand_id for h in hand_names]

    @classmethod
    def from_dataset(cls, root: str | Path, **kwargs: Any) -> UniDexTokStateTokenizerStep:
        """A step for a converted dataset folder: hands, sides and state columns read from it."""
        layout = UdhmDatasetMeta(root).hand_layout()
        return cls(hand_layout=layout.hands, state_names=layout.state_names, **kwargs)

    @property
    def tokenizer(self) -> UniDexTok:
        assert self._tokenizer is not None
        return self._tokenizer

    @property
    def layout(self) -> HandLayout:
        assert self._layout is not None
        return self._layout

    @property
    def hand_ids(self) -> torch.Tensor:
        """(H,) the tokenizer's hand id of each block (the unknown-hand id for hands it was not trained on)."""
        return self._hand_ids

    @property
    def active_masks(self) -> torch.Tensor:
        """(H, 22) bool: the active DoFs of each block's hand (decoded values elsewhere are zeroed)."""
        return self._active

    # ----------------------------------------------------------------------------------------- core
    def hand_blocks(self, states: torch.Tensor) -> torch.Tensor:
        """(B, D) whole states -> (B, H, 22) UDHM blocks, radians; checks width, NaN and ranges."""
        b, width = states.shape
        self.layout.check_width(width, self.input_key)
        check_batch(states, self.state_names, self.input_key)
        if self._columns is not None:
            if self._columns.device != states.device:
                self._columns = self._columns.to(states.device)
            states = states.index_select(1, self._columns)  # (B, 22*H)
        rows = states.float().reshape(b, self.layout.num_hands, UDHM_DIM)  # (B, H, 22)
        if self.range_check != "off":
            lo, hi = self._bounds
            if lo.device != rows.device:
                self._bounds = lo, hi = lo.to(rows.device), hi.to(rows.device)
            check_ranges(rows, lo, hi, self.hand_layout, self.input_key, self.range_check)
        return rows

    @torch.no_grad()
    def tokenize(self, states: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, D) states -> ((B, H*N*K) int64 tokens, (B, F) float32 view), on the input's device."""
        rows = self.hand_blocks(states)  # (B, H, 22)
        b, h = rows.shape[:2]
        tok = self.tokenizer
        if not self.encode:
            n_tokens, width = tokenizer_output_dims(tok.config, h, self.representation)
            return (torch.full((b, n_tokens), -1, dtype=torch.long, device=rows.device),
                    torch.zeros(b, width, device=rows.device))  # fmt: skip
        if tok.enc_pos.device != rows.device:
            tok.to(rows.device)
        if self._hand_ids.device != rows.device:
            self._hand_ids = self._hand_ids.to(rows.device)
        ids = self._hand_ids if b == 1 else self._hand_ids.repeat(b)  # (B*H,) one id per row, block order
        if self._active.device != rows.device:
            self._active = self._active.to(rows.device)
        mask = self._active.repeat(b, 1) if self.searches else None  # (B*H, 22)
        if self.representation == "dequantized":
            codes, decoded = tok.encode_decode(rows.reshape(b * h, UDHM_DIM), ids, mask=mask, encoding=self.encoding)
            view = decoded.reshape(b, h, UDHM_DIM) * self._active  # (B, H, 22), slots a hand lacks set to zero
        else:
            codes = tok.encode(rows.reshape(b * h, UDHM_DIM), ids, mask=mask, encoding=self.encoding)
            view = tok.code_vectors(codes).flatten(1)  # (B*H, N*K*S*d)
        return codes.reshape(b, -1), view.reshape(b, -1).float()

    @property
    def searches(self) -> bool:
        """Whether this step's encoding (its override, else the tokenizer's own) runs the code search."""
        return (self.encoding or self.tokenizer.config.encoding).rounds > 0

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        if self.input_key not in observation:
            raise KeyError(f"{STEP_NAME} needs '{self.input_key}' in the observation, got {sorted(observation)}")
        state = torch.as_tensor(observation[self.input_key])
        if state.ndim == 0:
            raise ValueError(f"{self.input_key} must be (D,), (B, D) or (B, T, D), got a scalar")
        lead = state.shape[:-1]  # () | (B,) | (B, T): kept on both outputs
        tokens, view = self.tokenize(state.reshape(-1, state.shape[-1]))  # (prod(lead), T), (prod(lead), F)
        observation[self.token_key] = tokens.reshape(*lead, tokens.shape[-1])
        observation[self.features_key] = view.reshape(*lead, view.shape[-1])
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
            "state_names": list(self.state_names),
            "pretrained": self.pretrained,
            "embed_weights": self.embed_weights,
            "tokenizer_config": self.tokenizer_config if self.embed_weights or self.pretrained is None else None,
            "preset": self.preset,
            "representation": self.representation,
            "allow_unknown": self.allow_unknown,
            "range_check": self.range_check,
            "encoding": asdict(self.encoding) if self.encoding is not None else None,
            "encode": self.encode,
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
