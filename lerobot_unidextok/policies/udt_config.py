"""The `udt_*` fields and checks every `<type>_udt` config adds to its stock LeRobot config (one mixin).

    lerobot-train --policy.type=diffusion_udt --policy.udt_pretrained=lab/unidextok-small \
        --dataset.repo_id=lab/g1_udhm --dataset.root=data/g1_udhm

Why a policy type per wrapped policy and not a token-writing command or an injecting entry point (lerobot
0.6.1): a policy *type* is the only thing `lerobot-train` flags and config files can select that also
decides the processors (`make_<type>_pre_post_processors`), and its processors are saved into every
checkpoint, so `--policy.path` resume, `lerobot-eval` and the stock factory reload all get the step back
without any code of ours in the loop. Features written into the dataset would leave inference without the
step; an injecting entry point would not be `lerobot-train`. So each `<type>_udt` is LeRobot's trio
(`policies/<type>_udt/`): the stock config class plus `UdtConfigMixin`, the stock policy class unchanged
under that config, and the stock processors with the UniDexTok step inserted after batching
(`udt_processor.insert_udt_steps`).

What the mixin adds to the stock config, in `validate_features` (run when the policy is built):
- the hand layout, sides and state column names from the training dataset (`hand_type` + state names),
  so a whole-robot state (arms + hands) works: only the UDHM blocks are tokenised;
- `observation.environment_state` (ENV, not normalised) sized for the token view, which ACT / Diffusion /
  VQ-BeT take as their environment state next to `observation.state`;
- the native action layout, so `select_action` (through the post-processor) returns the robot's own action;
- the native state layout, so the pre-processor also takes the robot's own `observation.state` (a step maps it
  to the converted layout; `config.input_features` stays what the model reads, the converted state);
- with `udt_relative_actions`, the action column names, checked to be the first columns of the state (the
  policy learns `action - state` per column), and IDENTITY action normalisation (the dataset's action
  statistics are of absolute actions, not of the offsets the policy predicts);
- unless `udt_hand_norm=off`, the per-hand statistics of the action blocks, and of the state's with
  `udt_hand_norm_state` (`udt_hand_stats`: a mix's record, or one robot's training episodes,
  `conversion/hand_stats.py`; with a prior, `udt_hand_stats_prior[_per_hand]`, each hand's shrunk toward the
  pool's) and IDENTITY for those keys in LeRobot's normaliser, whose work `unidextok.hand_normalizer` does then
  (docs/pooling.md);
- unless `udt_wrist_frame=robot`, the wrist columns and each hand's grasp centre (`udt_wrist_columns`,
  `udt_grasp_centres_m`: the dataset record's `wrist_frame`), for `unidextok.wrist_frame`.
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature

from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import (
    ACTION,
    OBS_HAND_IDS,
    OBS_HAND_TOKEN_FEATURES,
    OBS_HAND_TOKENS,
    OBS_STATE,
    UDHM_DIM,
)
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.share_sampler import episode_inputs, episode_map_key
from lerobot_unidextok.data.wrist_frame import NUM_COLUMNS as NUM_WRIST_COLUMNS
from lerobot_unidextok.data.wrist_frame import WristFrame, check_centre
from lerobot_unidextok.errors import ConfigError, InvalidInputError, UserError
from lerobot_unidextok.policies.relative_layout import relative_layout_problem
from lerobot_unidextok.policies.train_output import refuse_training_into_a_unit
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, untrained_preset
from lerobot_unidextok.processor import (
    HAND_INPUTS,
    IDENTITIES,
    RANGE_CHECKS,
    REPRESENTATIONS,
    STATS_OF_MODE,
    HandLayout,
    identity_width,
    tokenizer_output_dims,
)
from lerobot_unidextok.tokenizer import EncodingConfig, UniDexTokConfig
from lerobot_unidextok.utils.number_checks import NumberError, checked_hand_stats

logger = logging.getLogger(__name__)

UDT_SUFFIX = "_udt"
# udt_hand_norm -> LeRobot's normalisation mode of the per-hand statistics (None: the stock policy's; off: none)
WRIST_FRAMES = ("auto", "grasp_centre", "robot")  # udt_wrist_frame
HAND_NORMS = {"auto": None, "mean_std": "MEAN_STD", "min_max": "MIN_MAX", "quantiles": "QUANTILES",
              "quantile10": "QUANTILE10", "off": None}  # fmt: skip


def _mode_name(mode) -> str:
    return mode.value if isinstance(mode, NormalizationMode) else str(mode)


@dataclass
class UdtConfigMixin:
    """The `udt_*` fields of a `<type>_udt` config; put it before the stock config class among the bases
    (`class ACTUdtConfig(UdtConfigMixin, ACTConfig)`). Each field's comment is its `--help` text."""

    supports_hand_heads: ClassVar[bool] = False  # whether the policy builds udt_hand_heads (act_udt: true)

    # UniDexTok checkpoint folder, shipped id or Hub repo id (offline from the HF cache once pulled). Default:
    # the shipped `unidextok/universal-small-residual`, trained on every registered hand (no network needed);
    # `unidextok/universal-small`, the default until 2026-12-06, loads and encodes as before by its id.
    udt_pretrained: str | None = DEFAULT_TOKENIZER
    # An untrained tokenizer of this preset (tiny | small | paper; smoke tests only) instead of the default
    # udt_pretrained; `udt_pretrained=null` without a preset is an untrained `small`.
    udt_preset: str | None = None
    # What the policy reads as observation.environment_state: dequantized (decoded UDHM, H*22 radians) or
    # embedding (unit-norm code vectors, H*N*codebook_dim).
    udt_representation: str = "dequantized"
    # Hand spec name per UDHM block of observation.state, one name for all blocks; empty: read from the
    # training dataset's hand_type column when lerobot-train builds the policy.
    udt_hand_layout: list[str] = field(default_factory=list)
    # Side (left/right) of each UDHM block; filled from the dataset's state names.
    udt_sides: list[str] = field(default_factory=list)
    # Column names of observation.state, which locate the UDHM blocks; filled from the dataset.
    udt_state_names: list[str] = field(default_factory=list)
    # Hands the tokenizer was not trained on: false refuses them, true tokenises them zero-shot with the
    # tokenizer's unknown-hand embedding. Asked only when the policy reads a trained tokenizer's tokens
    # (udt_hand_input both or tokens): with udt_hand_input=state or an untrained preset any registered hand trains.
    udt_allow_unknown: bool = False
    # States outside their hands' ranges (degrees fed as radians, normalised values): raise | warn | off.
    udt_range_check: str = "raise"
    # How the step picks codes instead of the tokenizer's own encoding (docs/tokenizer.md "Code search"): null =
    # the tokenizer's (the default: the default tokenizer's nearest codes, `unidextok/universal-small`'s code search);
    # --policy.udt_encoding.rounds=0 = the nearest codes (cheapest); an override replaces the tokenizer's whole
    # encoding (rounds, method, changes, tolerance_deg).
    udt_encoding: EncodingConfig | None = None
    # Legacy (policy checkpoints saved before udt_encoding): rounds of the tokenizer's own search; upgraded into
    # udt_encoding when the config is built, then null. Set udt_encoding instead.
    udt_search_rounds: int | None = None
    # Decode predicted actions to the robot's native action vector (arms copied, hands in native units) when
    # the dataset's hands have native joints; false keeps UDHM radians.
    udt_native_action: bool = True
    # The native action layout {"names", "native_names", "hands", "mapping"}; filled from the dataset.
    udt_native_layout: dict[str, Any] = field(default_factory=dict)
    # Accept the robot's native observation.state (e.g. 14 arm radians + 2 x 6 Inspire values) and map it to
    # the converted layout in the pre-processor (step unidextok.native_to_udhm); the converted state is
    # accepted too. false: the converted state only.
    udt_native_state: bool = True
    # The native state layout {"names", "native_names", "hands", "mapping"}; filled from the dataset.
    udt_native_state_layout: dict[str, Any] = field(default_factory=dict)
    # Predict actions relative to the current state (action - state per column, LeRobot's
    # RelativeActionsProcessorStep before the normaliser, AbsoluteActionsProcessorStep after the unnormaliser, as
    # LeRobot's pi0 use_relative_actions); the action columns must be the first columns of the converted state
    # (true for unidextok-convert datasets). Actions are then not normalised (ACTION: IDENTITY). LeRobot 0.6.1's
    # lerobot-rollout refuses relative-action policies; the stock factory and select_action run them.
    udt_relative_actions: bool = False
    # With relative actions: start training from a policy that copies the current state (the action head's
    # weights and bias zero, so every predicted offset is 0 until the data say otherwise). ACT only.
    udt_copy_start: bool = False
    # Column names of the action (converted layout); filled from the dataset.
    udt_action_names: list[str] = field(default_factory=list)
    # A dataset mixing robots and people (unidextok-mix): the hands its observation.hand_ids index; each row is
    # tokenised with its own hands and the policy sees a one-hot hand identity per block. Filled from the dataset.
    udt_hand_vocabulary: list[str] = field(default_factory=list)
    # A mixed checkpoint bound to one robot (unidextok-deploy): that robot's hand per block (an index into
    # udt_hand_vocabulary, -1 = the block holds no hand of it), used when the observation has no hand ids.
    udt_fixed_hand_ids: list[int] = field(default_factory=list)
    # Its hands the mix never had (unidextok-deploy --zero_shot=true): ids after udt_hand_vocabulary, no identity.
    udt_extra_hands: list[str] = field(default_factory=list)
    # What tells a policy trained on a mix each row's hand, after the token view: onehot over the mix's vocabulary
    # (a zero-shot hand: all zero) or morphology (the hand's slot presence and UDHM ranges from its spec,
    # hands/morphology.py: an unseen hand is described in the terms the trained ones were). The ACT recipes
    # (act_udt_cpu.yaml, act_udt.yaml) set morphology; onehot stays the default of a config without it (and of
    # checkpoints saved before the field).
    udt_hand_identity: str = "onehot"
    # The mix's column renames (unidextok-mix --keep=all --name_map); filled from the dataset.
    udt_name_map: dict[str, str] = field(default_factory=dict)
    # Normalise each UDHM block of action (and observation.state: udt_hand_norm_state) with the statistics of the
    # hand it holds in that row (step unidextok.hand_normalizer; relative actions: their offsets), the passthrough
    # columns with their own:
    # auto (the stock policy's modes: ACT mean/std, Diffusion min/max) | mean_std | min_max | quantiles (q01/q99) |
    # quantile10 (q10/q90) | off (LeRobot's one set of statistics per column, as before 2026-12-05).
    udt_hand_norm: str = "auto"
    # With udt_hand_norm: normalise the state's UDHM blocks per hand too (the default, false: only the actions per
    # hand, the state with LeRobot's one set of statistics per column; a target with few episodes has narrow
    # statistics of its own, which held-out states leave far behind: experiments/cross_embodiment.py, unless
    # udt_hand_stats_prior shrinks them; in closed loop with 10 target demonstrations it pooled better but its
    # zero-shot transferred worse, docs/pooling.md). A checkpoint keeps what it trained with (the
    # halves it normalises per hand are in udt_hand_stats), so a fine-tune keeps them too.
    udt_hand_norm_state: bool = False
    # With udt_hand_norm on a mix: lend each hand's per-hand statistics this many episodes' worth of frames (the
    # dataset's mean episode length) of the pool's statistics (conversion/hand_stats.shrunk_hand_stats: weight
    # n / (n + prior) on its own), so a target with 10 demonstrations among hands with 50 is not normalised by
    # the narrow spread of its few. The pool spans both sides (a slot is the same joint on either hand). 0 (the
    # default) = udt_hand_stats_prior_per_hand decides; > 0 = this prior whatever the pool (a two-handed robot's
    # own dataset: each side shrunk toward the two).
    udt_hand_stats_prior: float = 0.0
    # When udt_hand_stats_prior is 0: the prior grows with the pool, this many episodes for each other hand of a
    # mix of four hands or more (conversion/hand_stats.pool_prior_episodes; fewer hands, one robot's dataset
    # included: no prior). Among six hands 2 per other hand (10) gained +15.7 points over the hand alone in closed
    # loop against +11.4 with each hand's own statistics, on every seed, and transferred better; beside one or two
    # other hands it did not help (12 pairs outside the pool rule: own statistics within 3 points of alone on all,
    # the prior on 9; docs/pooling.md), so the ACT recipes set 2 and the rule starts at four hands.
    # The policy's own default, without a config, is 0 (each hand's own statistics).
    udt_hand_stats_prior_per_hand: float = 0.0
    # The per-hand statistics and their modes {"modes": {key: mode}, key: {side: {hand: {lo, hi, "frames"}}}}; filled
    # from the dataset (a mix's record, or one robot's training episodes) and saved with the checkpoint.
    udt_hand_stats: dict[str, Any] = field(default_factory=dict)
    # No loss on the action slots a row's hand lacks (step unidextok.slot_mask; ACT and Diffusion): the policy is not
    # taught to predict zeros for joints the hand does not have.
    udt_mask_slots: bool = True
    # On a mix that records each input's share of the training frames (unidextok-mix's default share rule,
    # frames^0.43, or its --weights with the default --weights_by=sampling): weight each row's loss by its input's share over its fraction of the rows trained on
    # (step unidextok.share_weights; lerobot-train takes no sampler from a plugin). ACT and Diffusion.
    udt_share_weights: bool = True
    # Each episode's input in the mix (by episode index; -1 none), filled from the mix's record.
    udt_episode_inputs: list[int] = field(default_factory=list)
    # Each input's share of the training loss (the mix's rule or normalised --weights), filled from its record.
    udt_input_shares: list[float] = field(default_factory=list)
    # The dataset udt_episode_inputs and udt_input_shares were made for ("<N> episodes <fingerprint>"); a checkpoint
    # trained further on another dataset (fine-tuning: --policy.path=<checkpoint> --dataset.root=<other>) gets
    # both made anew for it. Filled from the dataset.
    udt_episode_map_of: str = ""
    # Checkpoints saved before udt_episode_inputs: a fixed loss weight per episode (by index), kept as saved.
    udt_episode_weights: list[float] = field(default_factory=list)
    # Checkpoints saved before udt_hand_norm (and udt_hand_norm=off): on a mix with relative actions, z-score each
    # block's offsets by its hand (step unidextok.hand_action_scale).
    udt_hand_action_scale: bool = True
    # Per block side and hand, the mean and std of action - state (the mix's action_delta_stats), for
    # udt_hand_action_scale; filled from the dataset when udt_hand_norm=off.
    udt_action_delta_stats: dict[str, dict[str, dict[str, Any]]] = field(default_factory=dict)
    # Which view of the hands the model reads: both (the UDHM state in observation.state and the token view in
    # observation.environment_state), state (the token view held at zero) or tokens (the state's UDHM blocks held
    # at zero); step unidextok.hand_input, before the normaliser.
    udt_hand_input: str = "both"
    # The wrist position of state and action as the position of the hand's grasp centre (step unidextok.wrist_frame,
    # docs/pooling.md): auto = when the dataset records a wrist frame with a grasp centre for every
    # hand (the simulator's recordings), grasp_centre = the same but refused without one, robot = the wrist as
    # recorded (the ablation; what every dataset without a frame gets).
    udt_wrist_frame: str = "auto"
    # The 6 wrist-pose columns (x, y, z, roll, pitch, yaw) of the frame; filled from the dataset's record.
    udt_wrist_columns: list[str] = field(default_factory=list)
    # Per hand, its grasp centre in the wrist frame (x, y, z m); filled from the dataset's record (unidextok-deploy:
    # the bound robot's), saved with the checkpoint; empty = no frame.
    udt_grasp_centres_m: dict[str, list[float]] = field(default_factory=dict)
    # Per-hand output heads around the shared trunk (act_udt on a mix; policies/hand_heads.py): the action head
    # plus a residual Linear per hand of udt_hand_vocabulary, zero at the start, each row through its own hand's
    # (its first block's hand; a zero-shot hand: the mean of the trained hands' heads; no hand: the shared head
    # only). Saved in model.safetensors and kept by unidextok-deploy. On one robot's dataset there is one hand and
    # no heads are built. On in the ACT recipes (act_udt_cpu.yaml, act_udt.yaml); off without a config (and in
    # checkpoints saved before the field).
    udt_hand_heads: bool = False
    # Accepted and ignored, so --policy.discover_packages_path=lerobot_unidextok also works with
    # --policy.path=<checkpoint> (LeRobot passes every --policy.* flag to the loaded config).
    discover_packages_path: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            self._check_fields()
        except (ValueError, UserError) as exc:
            # lerobot-train's parser (draccus) reports a config whose __post_init__ raises only as "Couldn't
            # instantiate class ACTUdtConfig using the given arguments": say what is wrong before it does
            print(f"{self.type}: {exc}", file=sys.stderr)
            raise
        self._stock_normalization = dict(self.normalization_mapping)  # before the relative override
        if self.udt_relative_actions:  # offsets around the state: the absolute action stats do not describe them
            self.normalization_mapping = {**self.normalization_mapping, "ACTION": NormalizationMode.IDENTITY}

    def _check_fields(self) -> None:
        """Each udt_* field validated once, as given (flags, a config file or a checkpoint's config.json)."""
        if self.udt_representation not in REPRESENTATIONS:
            raise ValueError(f"udt_representation must be one of {REPRESENTATIONS}, got {self.udt_representation!r}")
        if self.udt_encoding is not None:
            self.udt_encoding = EncodingConfig.from_dict(self.udt_encoding)  # checked once, by EncodingConfig
        self._upgrade_legacy_encoding()
        if self.udt_hand_input not in HAND_INPUTS:
            raise ValueError(f"udt_hand_input must be one of {HAND_INPUTS}, got {self.udt_hand_input!r}")
        if not (self.udt_hand_stats_prior >= 0):  # also NaN
            raise ValueError(f"udt_hand_stats_prior is in episodes and must be >= 0 (0: each hand's own statistics), "
                             f"got {self.udt_hand_stats_prior!r}")  # fmt: skip
        if not (self.udt_hand_stats_prior_per_hand >= 0):
            raise ValueError(f"udt_hand_stats_prior_per_hand is in episodes per other hand of the mix and must be >= 0 "
                             f"(0: no prior), got {self.udt_hand_stats_prior_per_hand!r}")  # fmt: skip
        if self.udt_hand_identity not in IDENTITIES:
            raise ValueError(f"udt_hand_identity must be one of {IDENTITIES}, got {self.udt_hand_identity!r}")
        if self.udt_range_check not in RANGE_CHECKS:
            raise ValueError(f"udt_range_check must be one of {RANGE_CHECKS}, got {self.udt_range_check!r}")
        if str(self.udt_hand_norm).lower() == "false":  # YAML reads a bare `off` as false (draccus config files)
            self.udt_hand_norm = "off"
        if self.udt_hand_norm not in HAND_NORMS:
            raise ValueError(f"udt_hand_norm must be one of {tuple(HAND_NORMS)}, got {self.udt_hand_norm!r}")
        self._check_wrist_frame()
        self._check_hand_stats()
        self._check_hand_heads()

    # ----------------------------------------------------------------------------------------------
    def _check_hand_heads(self) -> None:
        """udt_hand_heads: a bool, on a policy type whose model has per-hand heads (`supports_hand_heads`)."""
        if not isinstance(self.udt_hand_heads, bool):
            raise ConfigError(f"udt_hand_heads must be true or false, got {self.udt_hand_heads!r}")
        if self.udt_hand_heads and not self.supports_hand_heads:
            raise ConfigError(f"udt_hand_heads: per-hand output heads exist for act_udt only ({self.type} has no single "
                              "linear action head to give one per hand); set --policy.udt_hand_heads=false")  # fmt: skip

    def _check_wrist_frame(self) -> None:
        """udt_wrist_frame's value, and the filled frame's shape (a checkpoint's, or flags given by hand)."""
        if self.udt_wrist_frame not in WRIST_FRAMES:
            raise ConfigError(f"udt_wrist_frame must be one of {WRIST_FRAMES}, got {self.udt_wrist_frame!r}")
        if self.udt_grasp_centres_m and len(self.udt_wrist_columns) != NUM_WRIST_COLUMNS:
            raise ConfigError(f"udt_wrist_columns must name the {NUM_WRIST_COLUMNS} wrist-pose columns (x, y, z, "
                              f"roll, pitch, yaw) of udt_grasp_centres_m, got {self.udt_wrist_columns}")  # fmt: skip
        self.udt_grasp_centres_m = {h: check_centre(h, v, "udt_grasp_centres_m")
                                    for h, v in self.udt_grasp_centres_m.items()}  # fmt: skip

    def _check_hand_stats(self) -> None:
        """udt_hand_stats as filled from the dataset or read from a checkpoint's config.json: a mode per key, and per
        key the mode's two statistics of every hand it normalises (a mix's vocabulary; one robot's layout, unless
        bound zero-shot), finite and of the right sign and length (`utils/number_checks.py`)."""
        if not self.udt_hand_stats:
            return
        fix = ("use the config.json lerobot-train wrote with this checkpoint, or train again (lerobot-train fills "
               "udt_hand_stats from the dataset)")  # fmt: skip
        stats = dict(self.udt_hand_stats)
        modes = stats.pop("modes", None)
        if not isinstance(modes, dict) or not modes or any(m not in STATS_OF_MODE for m in modes.values()):
            raise NumberError(f"udt_hand_stats['modes'] must map {OBS_STATE} / {ACTION} to one of "
                              f"{tuple(STATS_OF_MODE)}, got {modes!r}; {fix}")  # fmt: skip
        if sorted(stats) != sorted(modes):
            raise NumberError(f"udt_hand_stats has statistics for {sorted(stats)} but modes for {sorted(modes)}; {fix}")
        # a mix: exactly its vocabulary; one robot: its layout's hands (a checkpoint bound zero-shot to another
        # robot's hands keeps the statistics of the hands it trained on, `udt_processor.row_hands`)
        mix = bool(self.udt_hand_vocabulary)
        hands = self.udt_hand_vocabulary if mix else [] if self.udt_allow_unknown else sorted(set(self.udt_hand_layout))
        for key, mode in modes.items():
            checked = checked_hand_stats({key: stats[key]}, "udt_hand_stats", hands=list(hands) or None,
                                         others=not mix, sides=list(self.udt_sides) or None,
                                         required=STATS_OF_MODE[mode], fix=fix)  # fmt: skip
            self.udt_hand_stats[key] = checked[key]

    @property
    def uses_wrist_frame(self) -> bool:
        """Whether the processors put the wrist in the grasp-centre frame (unidextok.wrist_frame)."""
        return self.udt_wrist_frame != "robot" and bool(self.udt_grasp_centres_m) and bool(self.udt_wrist_columns)

    def _fill_wrist_frame(self, meta: UdhmDatasetMeta) -> None:
        """The dataset's wrist columns and grasp centres (its record's `wrist_frame`), when udt_wrist_frame asks
        and the record has them for every hand; `grasp_centre` refuses a dataset without them."""
        if self.udt_wrist_frame == "robot":
            return
        record = meta.record
        hands = list(self.udt_hand_vocabulary) or sorted(set(self.udt_hand_layout))
        problem = ""
        if record is None or not record.wrist_frame:
            problem = f"{meta.root} records no wrist frame (its conversion record has no wrist_frame)"
        else:
            frame = WristFrame.from_dict(record.wrist_frame, f"{meta.root} conversion record, wrist_frame")
            missing = frame.missing_columns(meta.names(OBS_STATE), self.udt_action_names)
            lacking = [h for h in hands if h not in frame.grasp_centre_in_wrist_m]
            if missing:
                problem = f"{meta.root} has no wrist columns {missing} in its state and action"
            elif lacking:
                problem = f"{meta.root} records no grasp centre for hands {lacking}"
        if problem and self.udt_wrist_frame == "grasp_centre":
            raise ConfigError(f"udt_wrist_frame=grasp_centre: {problem}; record the data with its wrist frame "
                              "(unidextok-sim-record), or set --policy.udt_wrist_frame=robot")  # fmt: skip
        if problem:
            logger.info("%s: wrist as recorded (no grasp-centre frame): %s", self.type, problem)
            return
        self.udt_wrist_columns = list(frame.columns)
        self.udt_grasp_centres_m = {h: list(frame.grasp_centre_in_wrist_m[h]) for h in hands}
        logger.info("%s: wrist columns %s in each hand's grasp-centre frame %s", self.type, frame.columns,
                    self.udt_grasp_centres_m)  # fmt: skip

    def _upgrade_legacy_encoding(self) -> None:
        """A checkpoint saved before udt_encoding (`udt_search_rounds`=R): the tokenizer's own encoding with R
        rounds, what its step encoded with (R = 0: the nearest codes, without reading the tokenizer's config). A
        saved pipeline's step upgrades its own legacy `search_rounds` from its own tokenizer."""
        if self.udt_search_rounds is None:
            return
        if self.udt_encoding is not None:
            raise ValueError("set udt_encoding only: udt_search_rounds is its legacy form (checkpoints saved before it)")
        rounds, self.udt_search_rounds = self.udt_search_rounds, None
        own = self.tokenizer_config().encoding if rounds else EncodingConfig()
        self.udt_encoding = replace(own, rounds=rounds)  # checked by EncodingConfig

    def tokenizer_config(self):
        """The UniDexTokConfig the step will use (config.json of udt_pretrained, else the preset)."""
        preset = self.untrained_preset()
        return UniDexTokConfig.from_preset(preset) if preset else UniDexTokConfig.from_pretrained(self.udt_pretrained)

    @property
    def reads_tokens(self) -> bool:
        """Whether the token view is one of the policy's inputs (udt_hand_input both or tokens); with the state
        alone the tokenizer step does not encode (`encode=False`)."""
        return self.udt_hand_input != "state"

    @property
    def reads_trained_tokens(self) -> bool:
        """Whether what the policy reads depends on the tokenizer knowing each hand: the token view is an input
        (`reads_tokens`) and comes from a trained tokenizer (not an untrained preset, which knows no hand).
        Otherwise the tokenizer is never asked about the hands: a hand it was not trained on trains as any."""
        return self.reads_tokens and self.untrained_preset() is None

    def untrained_preset(self) -> str | None:
        """The preset of an untrained tokenizer when one was asked for (as `UniDexTokStateTokenizerStep`
        decides: `udt_preset` with the default udt_pretrained, or udt_pretrained=None), else None."""
        return untrained_preset(self.udt_pretrained, self.udt_preset)

    def _fill_from_dataset(self) -> None:
        """Hand layout, state names and native action layout from the dataset lerobot-train loaded; for a checkpoint
        loaded to train further (its layout filled already), the episode map of that dataset."""
        lerobot_meta = getattr(self, "_runtime_dataset_meta", None)
        if lerobot_meta is None:
            return
        refuse_training_into_a_unit()  # lerobot-train's --output_dir inside a dataset or a checkpoint
        meta = UdhmDatasetMeta.from_lerobot(lerobot_meta)
        if self.udt_state_names:  # a checkpoint loaded to train further (fine-tuning, resuming)
            self._check_same_layout(meta)
            self._refit_episode_map(meta)
            return
        self._fill_layout(meta)
        self._fill_episode_map(meta)
        self._fill_wrist_frame(meta)
        if self.udt_hand_norm != "off":
            self._fill_hand_stats(meta)

    def _fill_layout(self, meta: UdhmDatasetMeta) -> None:
        if OBS_HAND_TOKEN_FEATURES in meta.features:
            raise ValueError(
                f"the dataset already has '{OBS_HAND_TOKEN_FEATURES}', which the UniDexTok step writes; drop or "
                f"rename it (lerobot-edit-dataset), or train the stock --policy.type={self.type.removesuffix(UDT_SUFFIX)}"
            )
        names = meta.names(OBS_STATE)
        self.udt_action_names = meta.names(ACTION)
        if OBS_HAND_IDS in meta.features:  # a mix of robots and people: hands per row, no one native layout
            self._fill_from_mix(meta, names)
            return
        hands = self.udt_hand_layout or meta.block_hands()
        if len(hands) == 1:
            hands = hands * max(1, len(find_udhm_blocks(names)))
        layout = HandLayout.from_state_names(names, hands)
        self.udt_hand_layout, self.udt_sides, self.udt_state_names = layout.hands, layout.sides, layout.state_names
        native = meta.native_layout(ACTION) if self.udt_native_action else None
        self.udt_native_layout = native.to_dict() if native is not None else {}
        state = meta.native_layout(OBS_STATE) if self.udt_native_state else None
        self.udt_native_state_layout = state.to_dict() if state is not None and state.invertible else {}
        logger.info(
            "%s: hands %s (sides %s), %d passthrough state columns, native state %s, native action %s, from %s",
            self.type, layout.hands, layout.sides, len(layout.passthrough_names),
            f"{state.native_dim} wide accepted" if self.udt_native_state_layout else "not accepted",
            f"{native.native_dim} wide" if native else "not decoded", meta.root,
        )  # fmt: skip

    def _fill_from_mix(self, meta: UdhmDatasetMeta, names: list[str]) -> None:
        """A dataset written by unidextok-mix: its hand vocabulary and blocks; actions stay in the mix's layout
        (each robot's own comes back when `unidextok-deploy` binds the checkpoint to it)."""
        if meta.record is None or not meta.record.hand_vocabulary:
            raise ValueError(
                f"{meta.root} has '{OBS_HAND_IDS}' but its conversion record names no hand_vocabulary: it was not "
                "written by unidextok-mix (or its meta/unidextok_conversion.json was dropped); mix it again"
            )
        self.udt_hand_vocabulary = list(meta.record.hand_vocabulary)
        self.udt_name_map = dict(meta.record.name_map)
        self.udt_sides = [b.side for b in find_udhm_blocks(names)]
        self.udt_state_names = names
        self.udt_native_layout, self.udt_native_state_layout = {}, {}
        if self.udt_relative_actions and self.udt_hand_action_scale and self.udt_hand_norm == "off":
            if not meta.record.action_delta_stats:
                raise ValueError(
                    f"{meta.root} records no action_delta_stats (mixed by an older unidextok-mix): mix it again, or "
                    "set --policy.udt_hand_action_scale=false to leave the relative actions unscaled"
                )
            self.udt_action_delta_stats = dict(meta.record.action_delta_stats)
        logger.info(
            "%s: a mix of hands %s (blocks %s, hands per row from %s), from %s",
            self.type, self.udt_hand_vocabulary, self.udt_sides, OBS_HAND_IDS, meta.root,
        )  # fmt: skip

    def _fill_episode_map(self, meta: UdhmDatasetMeta) -> None:
        """Each episode's input and each input's share (a mix that records shares; none otherwise), for the dataset
        `meta` (`udt_episode_map_of`)."""
        inputs, shares = self._dataset_map(meta)
        self.udt_episode_inputs, self.udt_input_shares, self.udt_episode_weights = inputs, shares, []
        self.udt_episode_map_of = episode_map_key(meta)
        if shares:
            logger.info("%s: each input's share of every batch's loss %s (unidextok.share_weights)", self.type,
                        {s.dataset: round(w, 3) for s, w in zip(meta.record.sources, shares, strict=True)})  # fmt: skip

    def _dataset_map(self, meta: UdhmDatasetMeta) -> tuple[list[int], list[float]]:
        """(each episode's input, each input's share) of `meta`'s dataset: a mix's record with shares, else none."""
        mixed = meta.record is not None and bool(meta.record.hand_vocabulary)
        return episode_inputs(meta.record) if self.udt_share_weights and mixed else ([], [])

    def _check_same_layout(self, meta: UdhmDatasetMeta) -> None:
        """A checkpoint trains further only on a dataset whose state has its columns (LeRobot's shape error
        otherwise, after loading everything)."""
        names = meta.names(OBS_STATE)
        if names != list(self.udt_state_names):
            def sides(n):
                return [b.side for b in find_udhm_blocks(n)]
            raise InvalidInputError(
                f"{meta.root}: its {OBS_STATE} has {len(names)} columns (hand blocks {sides(names)}), the checkpoint "
                f"was trained on {len(self.udt_state_names)} (hand blocks {sides(self.udt_state_names)}): it trains "
                "further only on a dataset of its layout. Run it on this robot as it is with unidextok-deploy, or "
                "fine-tune on a dataset with those columns (a mix of this robot's dataset with one that has the other "
                "blocks, unidextok-mix)"
            )

    def _refit_episode_map(self, meta: UdhmDatasetMeta) -> None:
        """A checkpoint loaded to train on `meta`'s dataset: the same dataset keeps its map (resuming); another one
        (fine-tuning a pooled or bound checkpoint on one robot's data) gets its own, said in one line. The saved
        pre-processor's step keeps the old map; the policy weighs by this one (`policies/udt_loss.py`)."""
        key = episode_map_key(meta)
        if key == self.udt_episode_map_of or (not self.udt_episode_map_of and self._map_fits(meta)):
            return  # the same dataset (a checkpoint saved before the key: its map fits the dataset), as saved
        before = len(self.udt_episode_inputs or self.udt_episode_weights)
        self._fill_episode_map(meta)
        if before or self.udt_input_shares:
            logger.warning(
                "%s: the checkpoint's episode map (%d episodes) was made for another dataset; trained on %s (%s) each "
                "row is weighted by %s", self.type, before, meta.root, key,
                f"the shares {self.udt_input_shares} of its own inputs" if self.udt_input_shares else "1 (one dataset, "
                "no shares)",
            )  # fmt: skip

    def _map_fits(self, meta: UdhmDatasetMeta) -> bool:
        """Whether a map saved without `udt_episode_map_of` is the one `meta`'s dataset gives (legacy fixed weights:
        one per episode of it)."""
        if self.udt_episode_weights:
            return len(self.udt_episode_weights) == meta.total_episodes
        return (list(self.udt_episode_inputs), list(self.udt_input_shares)) == self._dataset_map(meta)

    def _fill_hand_stats(self, meta: UdhmDatasetMeta) -> None:
        """Per-hand statistics of the action blocks (and the state's, `udt_hand_norm_state`) in the modes
        `udt_hand_norm` asks (a mix's record, else computed from the dataset's training episodes), and LeRobot's
        normaliser set to IDENTITY for them."""
        from lerobot_unidextok.conversion.hand_stats import (
            ACTION_DELTA,
            hand_stats,
            pool_prior_episodes,
            recorded_hand_stats,
            shrunk_hand_stats,
            training_episodes,
        )

        stats = recorded_hand_stats(meta)  # a mix's, checked against its vocabulary
        if stats is None:
            stats = hand_stats(meta.root, training_episodes(meta))
            logger.info("%s: per-hand statistics computed from %s's training episodes", self.type, meta.root)
        prior = self.udt_hand_stats_prior or pool_prior_episodes(stats, self.udt_hand_stats_prior_per_hand)
        if prior > 0:
            frames_per_episode = float(meta.info.get("total_frames", 0)) / max(meta.total_episodes, 1)
            stats = shrunk_hand_stats(stats, prior * frames_per_episode)
            logger.info("%s: each hand's statistics shrunk toward the pool's by %g episodes", self.type, prior)
        stock = getattr(self, "_stock_normalization", self.normalization_mapping)
        chosen: dict[str, Any] = {"modes": {}}
        for key, kind, source in ((OBS_STATE, "STATE", OBS_STATE),
                                  (ACTION, "ACTION", ACTION_DELTA if self.udt_relative_actions else ACTION)):  # fmt: skip
            mode = HAND_NORMS[self.udt_hand_norm] or _mode_name(stock.get(kind, NormalizationMode.IDENTITY))
            if mode not in STATS_OF_MODE or source not in stats or (key == OBS_STATE and not self.udt_hand_norm_state):
                continue
            lo, hi = STATS_OF_MODE[mode]
            chosen["modes"][key] = mode
            chosen[key] = {side: {hand: {lo: s[lo], hi: s[hi], "frames": s["frames"]} for hand, s in per.items()}
                           for side, per in stats[source].items()}  # fmt: skip
            self.normalization_mapping = {**self.normalization_mapping, kind: NormalizationMode.IDENTITY}
        self.udt_hand_stats = chosen if chosen["modes"] else {}
        self._check_hand_stats()

    @property
    def num_udt_blocks(self) -> int:
        """UDHM blocks of the state the step tokenises."""
        return len(self.udt_sides) if self.udt_hand_vocabulary else len(self.udt_hand_layout)

    @property
    def identity_width(self) -> int:
        """Columns per block the hand identity adds to the token view: a mix's (`udt_hand_identity`), else none."""
        return identity_width(self.udt_hand_identity, len(self.udt_hand_vocabulary)) if self.udt_hand_vocabulary else 0

    def validate_features(self) -> None:
        self._fill_from_dataset()
        state = self.input_features.get(OBS_STATE)
        if state is None:
            raise ValueError(f"{self.type} needs '{OBS_STATE}' (UDHM hand states) among the dataset features")
        width = state.shape[0]
        self.input_features.pop(OBS_HAND_IDS, None)  # read by the tokenizer step, never by the policy
        if self.udt_hand_heads and not self.udt_hand_vocabulary:
            logger.info("%s: udt_hand_heads on one robot's dataset (one set of hands): no per-hand heads are built",
                        self.type)  # fmt: skip
        if self.udt_hand_vocabulary:
            if len(self.udt_state_names) != width or not self.udt_sides:
                raise ValueError(
                    f"{self.type} on a mix needs udt_state_names ({len(self.udt_state_names)}) for the {width}-wide "
                    f"{OBS_STATE}: train on the dataset written by unidextok-mix, which fills them"
                )
        elif not self.udt_hand_layout:
            raise ValueError(
                f"{self.type}: set --policy.udt_hand_layout='[<hand>, ...]' (one hand spec per UDHM block), "
                "or train on a dataset converted with unidextok-convert (its hand_type column names the hands)"
            )
        if not self.udt_state_names:  # hands-only state given without a dataset: 22 columns per hand
            if width % UDHM_DIM:
                raise ValueError(
                    f"{OBS_STATE} has width {width}, which matches no UDHM layout (22 per hand); train on a "
                    "dataset converted with unidextok-convert, whose state names say where the hand blocks are"
                )
            if len(self.udt_hand_layout) == 1:
                self.udt_hand_layout = self.udt_hand_layout * (width // UDHM_DIM)
        elif len(self.udt_state_names) != width:
            raise ValueError(f"udt_state_names has {len(self.udt_state_names)} names for a {width}-wide {OBS_STATE}")
        if self.udt_native_state_layout and self.udt_native_state_layout.get("names") != self.udt_state_names:
            raise ValueError(
                "udt_native_state_layout.names must be the converted state names (udt_state_names); both are filled "
                "from the training dataset, so leave them unset, or set --policy.udt_native_state=false"
            )
        num_hands = self.num_udt_blocks
        if not self.udt_state_names and num_hands * UDHM_DIM != width:
            raise ValueError(
                f"udt_hand_layout {self.udt_hand_layout} names {num_hands} hands but {OBS_STATE} (width {width}) "
                f"holds {width // UDHM_DIM}"
            )
        if self.udt_relative_actions:
            self._check_relative_layout(width)
        self.input_features.pop(OBS_HAND_TOKENS, None)  # int64 ids must not reach the normalizer
        if OBS_HAND_TOKEN_FEATURES not in self.input_features:  # a reloaded config has it already
            _, env_width = tokenizer_output_dims(
                self.tokenizer_config(), num_hands, self.udt_representation, self.identity_width
            )
            self.input_features[OBS_HAND_TOKEN_FEATURES] = PolicyFeature(type=FeatureType.ENV, shape=(env_width,))
        super().validate_features()

    def _check_relative_layout(self, state_width: int) -> None:
        """Relative actions subtract state column i from action column i: refuse an action layout that is not
        the state's first columns (by name when both are named, else by width), saying which column differs
        (`relative_layout.py`)."""
        action = self.output_features.get(ACTION)
        width = action.shape[0] if action is not None else len(self.udt_action_names)
        trained = getattr(self, "_runtime_dataset_meta", None) is not None  # else: a checkpoint loaded to run
        problem = relative_layout_problem(self.udt_action_names, self.udt_state_names, width, state_width, trained)
        if problem:
            raise InvalidInputError(problem)
