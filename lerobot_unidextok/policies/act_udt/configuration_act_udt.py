"""ACT whose pre-processor tokenises UDHM hand states with UniDexTok (policy type `act_udt`).

The step adds `observation.hand_tokens` (int64, kept out of `input_features` so the normalizer
never sees integers) and a float view under `observation.environment_state` (ENV: not normalized),
which ACT consumes as its environment-state input next to `observation.state`.
"""

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

from lerobot.configs.policies import PreTrainedConfig
from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.policies.act.configuration_act import ACTConfig

from lerobot_unidextok.constants import (
    OBS_HAND_TOKEN_FEATURES,
    OBS_HAND_TOKENS,
    OBS_STATE,
    UDHM_DIM,
)

logger = logging.getLogger(__name__)


@PreTrainedConfig.register_subclass("act_udt")
@dataclass
class ACTUdtConfig(ACTConfig):
    # --- UniDexTok step ---------------------------------------------------------------------------
    # Hand spec name per 22-wide block of observation.state (one name = all blocks). Empty: read from
    # the training dataset (`hand_type` column + `<side>_<joint>` state names) when lerobot-train builds it.
    udt_hand_layout: list[str] = field(default_factory=list)
    udt_sides: list[str] = field(default_factory=list)  # filled from the dataset's state names
    # UniDexTok checkpoint folder or Hub repo id (resolved offline from the HF cache once pulled).
    # None: an untrained `udt_preset` tokenizer (smoke tests only).
    udt_pretrained: str | None = None
    udt_preset: str = "small"
    udt_representation: str = "dequantized"  # "dequantized" (H*22 rad) | "embedding" (H*N*codebook_dim)
    # Optional post-processor: convert predicted UDHM actions to these hands' native command units.
    udt_command_hands: list[str] = field(default_factory=list)

    def tokenizer_config(self):
        """The UniDexTokConfig the step will use (config.json of udt_pretrained, else the preset)."""
        from lerobot_unidextok.tokenizer import UniDexTokConfig

        if self.udt_pretrained is None:
            return UniDexTokConfig.from_preset(self.udt_preset)
        local = Path(self.udt_pretrained) / "config.json"
        if local.is_file():
            path = local
        else:
            from lerobot_unidextok.processor import load_tokenizer

            return load_tokenizer(self.udt_pretrained).config
        return UniDexTokConfig(**json.loads(path.read_text()))

    def _fill_layout_from_dataset(self) -> None:
        meta = getattr(self, "_runtime_dataset_meta", None)
        if meta is None or self.udt_hand_layout and self.udt_sides:
            return
        from lerobot_unidextok.processor import hand_layout_from_dataset

        layout = hand_layout_from_dataset(meta.root)
        if not self.udt_hand_layout:
            self.udt_hand_layout = layout.hands
        self.udt_sides = layout.sides
        logger.info(
            "act_udt: hand layout %s (sides %s) from %s",
            self.udt_hand_layout,
            self.udt_sides,
            meta.root,
        )

    def validate_features(self) -> None:
        from lerobot_unidextok.processor import tokenizer_output_dims

        self._fill_layout_from_dataset()
        state = self.input_features.get(OBS_STATE)
        if state is None:
            raise ValueError(f"act_udt needs '{OBS_STATE}' (UDHM hand states) among the dataset features")
        width = state.shape[0]
        if width % UDHM_DIM:
            raise ValueError(
                f"{OBS_STATE} has width {width}, which matches no UDHM layout (22 per hand); "
                "train on a dataset converted with unidextok-convert"
            )
        num_hands = width // UDHM_DIM
        if not self.udt_hand_layout:
            raise ValueError(
                "act_udt: set --policy.udt_hand_layout='[\"<hand>\", ...]' (one hand spec per 22-wide block), "
                "or train on a converted dataset whose hand_type column names the hands"
            )
        if len(self.udt_hand_layout) == 1 and num_hands > 1:
            self.udt_hand_layout = self.udt_hand_layout * num_hands
        if len(self.udt_hand_layout) != num_hands:
            raise ValueError(
                f"udt_hand_layout {self.udt_hand_layout} names {len(self.udt_hand_layout)} hands but "
                f"{OBS_STATE} (width {width}) holds {num_hands}"
            )
        self.input_features.pop(OBS_HAND_TOKENS, None)  # int64 ids must not reach the normalizer
        if OBS_HAND_TOKEN_FEATURES in self.input_features:  # reloaded config: already sized
            return super().validate_features()
        _, env_width = tokenizer_output_dims(self.tokenizer_config(), num_hands, self.udt_representation)
        self.input_features[OBS_HAND_TOKEN_FEATURES] = PolicyFeature(type=FeatureType.ENV, shape=(env_width,))
        super().validate_features()
