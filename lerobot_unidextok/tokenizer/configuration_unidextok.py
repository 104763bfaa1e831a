"""UniDexTok configuration: one typed dataclass and named size presets."""
import types
import typing
from dataclasses import dataclass, field, fields, replace

from lerobot_unidextok.constants import UDHM_DIM
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.pretrained import config_path

# Bump when a change makes old checkpoints unloadable (layer names, shapes, semantics of fields).
FORMAT_VERSION = 1

SEARCH_METHODS: tuple[str, ...] = ("greedy", "sweeps")


@dataclass(frozen=True)
class EncodingConfig:
    """How `UniDexTok.encode` picks codes: the one encoding setting, owned by the tokenizer's config
    (`UniDexTokConfig.encoding`, saved in config.json). Everything else that encodes (the processor steps, the
    `<type>_udt` policies, training, `unidextok-eval`, the experiments) uses the tokenizer as configured, or one
    override of this same type passed through unchanged (None = the tokenizer's own): an override replaces the
    whole encoding, so give every setting it needs (`EncodingConfig(rounds=0)` = the nearest codes).

    Departure (option): decoder-aware code search (tokenizer/search.py). `rounds` 0 = the paper's encoding, each
    group vector snapped to its nearest code; R > 0 refines those codes by R rounds of descent on the decoder
    linearised around them (cost: benchmarks/bench_processor.py --encodings, docs/tokenizer.md "Code search").
    Same codes, same decoder; training always uses the nearest codes."""

    # Rounds of the decoder-aware code search after the nearest codes (0 = the nearest codes, the paper's encoding)
    rounds: int = 0
    # How a round moves: "greedy" makes up to `changes` best single code changes; "sweeps" (coordinate descent,
    # `sweeps` passes over the N x K positions) is what config.json files written before the search had a method
    # use, so they encode as they did.
    method: str = "greedy"
    sweeps: int = 2  # "sweeps": passes over the N x K code positions per round
    changes: int = 16  # "greedy": best single code changes per round, at most
    # "greedy": after a round, a row whose mean absolute error over its active DoFs is at most this (degrees)
    # leaves the search, so later rounds cost only for the rows still above it (0 = every row runs every round)
    tolerance_deg: float = 0.0

    def __post_init__(self) -> None:
        """The one rule for the encoding settings: a ConfigError (a ValueError) naming the setting."""
        for name, kind in (("rounds", int), ("sweeps", int), ("changes", int), ("method", str)):
            value = getattr(self, name)
            if not isinstance(value, kind) or isinstance(value, bool):
                raise ConfigError(f"encoding.{name} must be a {kind.__name__}, got {value!r}")
        if isinstance(self.tolerance_deg, bool) or not isinstance(self.tolerance_deg, (int, float)):
            raise ConfigError(f"encoding.tolerance_deg must be a number, got {self.tolerance_deg!r}")
        if self.rounds < 0:
            raise ConfigError(f"encoding.rounds must be >= 0 (0 = nearest codes), got {self.rounds}")
        if self.method not in SEARCH_METHODS:
            raise ConfigError(f"encoding.method must be one of {SEARCH_METHODS}, got {self.method!r}")
        if self.sweeps < 1:
            raise ConfigError(f"encoding.sweeps must be >= 1, got {self.sweeps}")
        if self.changes < 1:
            raise ConfigError(f"encoding.changes must be >= 1, got {self.changes}")
        if self.tolerance_deg < 0:
            raise ConfigError(
                f"encoding.tolerance_deg must be >= 0 (0 = every row runs every round), got {self.tolerance_deg}"
            )

    @classmethod
    def from_dict(cls, data: "dict | EncodingConfig") -> "EncodingConfig":
        """An encoding from its JSON dict (config.json, a saved processor step); unknown keys are refused."""
        if isinstance(data, cls):
            return data
        known = [f.name for f in fields(cls)]
        if not isinstance(data, dict):
            raise ConfigError(f"encoding must be a mapping of {known}, got {data!r}")
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ConfigError(f"encoding has keys this version does not know: {unknown}; known: {known}")
        return cls(**data)

    def describe(self) -> str:
        """How codes are picked, in words (reports, cards)."""
        if not self.rounds:
            return "nearest codes"
        if self.method == "sweeps":
            return f"code search, {self.rounds} round(s) x {self.sweeps} sweep(s)"
        stop = f", rows within {self.tolerance_deg:g} deg stop" if self.tolerance_deg else ""
        return f"greedy code search, {self.rounds} round(s) x up to {self.changes} change(s){stop}"


NEAREST_CODES = EncodingConfig(rounds=0)  # the paper's encoding, as an override

# Config fields (of UniDexTokConfig, and of TrainConfig) that only change how `encode` picks codes at use, never
# training: cache keys and fingerprints of trainings leave them out.
ENCODING_FIELDS: tuple[str, ...] = ("encoding",)

# Legacy upgrade: configs written before `EncodingConfig` kept the encoding as flat fields (a UniDexTok
# config.json, a processor step's `tokenizer_config`); old name -> EncodingConfig field. Only this module and the
# legacy-upgrade code of the processor step and the policy config know these names
# (tests/tokenizer/test_encoding_owner.py).
LEGACY_ENCODING_KEYS: dict[str, str] = {"search_rounds": "rounds", "search_method": "method",
                                        "search_sweeps": "sweeps", "search_changes": "changes",
                                        "search_tolerance_deg": "tolerance_deg"}  # fmt: skip
# What a config.json written before `search_method` existed searched with (`UniDexTokConfig.from_dict`).
LEGACY_SEARCH_METHOD = "sweeps"


def upgrade_legacy_encoding(data: dict, method_when_absent: str | None = LEGACY_SEARCH_METHOD) -> dict:
    """A UniDexTokConfig dict with the flat legacy `search_*` keys moved into one `encoding` dict (a dict without
    them is returned as it is). A legacy dict without `search_method` searched with `method_when_absent` (None:
    this version's default); a dict with both forms is refused."""
    legacy = {k: data[k] for k in LEGACY_ENCODING_KEYS if k in data}
    if not legacy:
        return data
    if "encoding" in data:
        raise ConfigError(f"UniDexTok config has both `encoding` and the legacy keys {sorted(legacy)}; keep `encoding`")
    encoding = {LEGACY_ENCODING_KEYS[k]: v for k, v in legacy.items()}
    if "method" not in encoding and method_when_absent is not None:
        encoding["method"] = method_when_absent
    return {**{k: v for k, v in data.items() if k not in LEGACY_ENCODING_KEYS}, "encoding": encoding}


# Hand-type vocabulary used for conditioning by default. Names are hand-spec names (side-independent);
# any other name maps to the "unknown hand" embedding when `allow_unknown=True`.
DEFAULT_HAND_NAMES: tuple[str, ...] = (
    "human",
    "inspire_rh56",
    "inspire_rh56_unitree",
    "linkerhand_l6",
    "linkerhand_l10",
    "linkerhand_l20",
    "xhand1",
    "brainco_revo1",
    "allegro",
    "leap",
    "shadow",
)


@dataclass
class UniDexTokConfig:
    """Sizes, hand vocabulary and VQ settings of a UniDexTok model (saved as config.json)."""

    # --- checkpoint format -------------------------------------------------------------------
    # Checked on load: a config.json with another value is rejected with a clear error.
    format_version: int = FORMAT_VERSION

    # --- input / latent tokens -----------------------------------------------------------------
    state_dim: int = UDHM_DIM  # 22 UDHM angles per hand, radians
    # Input/output normalisation: "pi" divides angles by a fixed pi (paper); "range" maps each UDHM joint's
    # `joint_range_rad` [lo, hi] onto [-1, 1] (departure, an option; training fills the ranges from the
    # training hands' registered joint ranges). The loss is in angle / pi units either way.
    input_norm: str = "pi"
    # (22, 2) [lo, hi] per UDHM joint for input_norm="range"; None until training fills it (then pi is used)
    joint_range_rad: list[list[float]] | None = None
    # Departure (option): besides the normalised angles x, the encoder input gets sin / cos(pi/2 * 2^k * x) for
    # k < fourier_octaves, so encoder groups can quantise fine phases of a joint (0 = the paper's linear input).
    fourier_octaves: int = 0
    num_tokens: int = 8  # N latent tokens (paper: 8)
    hidden_dim: int = 512  # C token width (paper: 512)

    # --- transformer ------------------------------------------------------------------------------
    # Depth, heads and MLP ratio are not published; 4 + 4 blocks x 8 heads is our choice for `paper`.
    encoder_depth: int = 4
    decoder_depth: int = 4
    num_heads: int = 8
    mlp_ratio: float = 4.0
    dropout: float = 0.0

    # --- hand conditioning ----------------------------------------------------------------------
    # Vocabulary of the hand-type embedding c_h (width C, paper: size not published). One extra row
    # is the "unknown hand" embedding used for hands outside this list (zero-shot).
    hand_names: list[str] = field(default_factory=lambda: list(DEFAULT_HAND_NAMES))
    # Hands the checkpoint was actually trained on (set by training; [] = not recorded). Vocabulary rows
    # of other hands were never trained: the processor step refuses them or routes them to "unknown hand".
    trained_hands: list[str] = field(default_factory=list)

    # --- factorised cosine VQ ---------------------------------------------------------------------
    codebook_dim: int = 256  # C -> 256 projection before quantisation (paper)
    num_groups: int = 8  # K groups of codebook_dim / K = 32 dims (paper)
    codebook_size: int = 32  # entries per group codebook (paper)
    commitment_weight: float = 0.25  # beta on ||sg[q] - u||^2 (paper)
    codebook_weight: float = 1.0  # weight of ||q - sg[u]||^2 (paper: 1; unused with codebook_update="ema")
    # How codes move: "gradient" of the codebook loss (paper) or "ema" (exponential moving average of the
    # unit-norm encoder vectors assigned to each code, as in VQ-VAE-2; departure, an option).
    codebook_update: str = "gradient"
    ema_decay: float = 0.99  # decay of the EMA codebook statistics
    # How the gradient passes the quantiser: "straight_through" copies it (paper), "rotation" rotates it with the
    # rotation that maps the encoder vector onto its code (Fifty et al. 2024, the rotation trick; an option).
    gradient_estimator: str = "straight_through"
    entropy_weight: float = 0.0  # optional code-entropy regulariser, off by default (paper: off)
    entropy_temperature: float = 0.1  # softmax temperature over cosine similarities for the entropy term
    # Departure: dead-code re-seeding is not described in the paper. Codes whose usage EMA falls
    # below this fraction of uniform usage are re-seeded from batch features (0 disables).
    dead_code_threshold: float = 0.03
    usage_decay: float = 0.99  # EMA decay of per-code usage counts

    # --- residual stages (departure, an option; 0 = the paper's single factorised VQ) ----------------------------
    # Each residual stage is a second factorised cosine VQ (same K groups x codebook_size codes) on what the stages
    # before it left out: the decoder input the unsnapped group vectors would give minus what the codes give. The
    # decoder reads the sum. Codes: (B, N, K) per stage, concatenated along the last axis (stage 1 first), so the
    # first stage stays the paper's token sequence (`UniDexTok.encode(..., stages=1)`).
    residual_stages: int = 0
    # In training, this share of rows is decoded from the first stage alone (the later stages dropped, as
    # SoundStream's quantizer dropout), so the first stage's codes also decode on their own.
    residual_drop_prob: float = 0.25

    # --- encoding ----------------------------------------------------------------------------------
    # How `encode` picks codes (EncodingConfig: the nearest codes by default, the paper's; or the code search)
    encoding: EncodingConfig = field(default_factory=EncodingConfig)

    # --- reconstruction loss ------------------------------------------------------------------------
    # In angle / pi units: MSE (paper: plain MSE) + optional SmoothL1 (paper mentions it, weight unknown) +
    # optional L1 (departure: the reported metric is a mean absolute error). Restricting them to active DoFs
    # is our choice (padded slots are zero by construction, not targets).
    mse_weight: float = 1.0
    smooth_l1_weight: float = 0.0
    l1_weight: float = 0.0

    def __post_init__(self) -> None:
        if self.format_version != FORMAT_VERSION:
            raise ConfigError(
                f"UniDexTok config format_version={self.format_version!r} does not match this code's "
                f"FORMAT_VERSION={FORMAT_VERSION}; install the lerobot-unidextok version that wrote the checkpoint, "
                "or re-train"
            )
        if self.hidden_dim % self.num_heads != 0:
            raise ConfigError(f"hidden_dim={self.hidden_dim} must be divisible by num_heads={self.num_heads}")
        if self.codebook_dim % self.num_groups != 0:
            raise ConfigError(f"codebook_dim={self.codebook_dim} must be divisible by num_groups={self.num_groups}")
        if self.fourier_octaves < 0:
            raise ConfigError(f"fourier_octaves must be >= 0, got {self.fourier_octaves}")
        for name in ("num_tokens", "hidden_dim", "num_heads", "codebook_size", "state_dim"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        self.hand_names = list(self.hand_names)  # JSON round trip gives lists; keep one type
        self.trained_hands = list(self.trained_hands)
        if self.input_norm not in ("pi", "range"):
            raise ConfigError(f"input_norm must be 'pi' or 'range', got {self.input_norm!r}")
        if self.joint_range_rad is not None:
            rng = self.joint_range_rad
            if len(rng) != self.state_dim or any(len(r) != 2 or r[0] > r[1] for r in rng):
                raise ConfigError(f"joint_range_rad must be {self.state_dim} [lo, hi] pairs with lo <= hi, got {rng}")
            self.joint_range_rad = [[float(a), float(b)] for a, b in rng]
        if self.gradient_estimator not in ("straight_through", "rotation"):
            raise ConfigError(
                f"gradient_estimator must be 'straight_through' or 'rotation', got {self.gradient_estimator!r}"
            )
        if self.codebook_update not in ("gradient", "ema"):
            raise ConfigError(f"codebook_update must be 'gradient' or 'ema', got {self.codebook_update!r}")
        self.encoding = EncodingConfig.from_dict(self.encoding)  # a dict from JSON or a keyword
        if self.residual_stages < 0:
            raise ConfigError(f"residual_stages must be >= 0 (0 = the paper's single VQ), got {self.residual_stages}")
        if not 0.0 <= self.residual_drop_prob < 1.0:
            raise ConfigError(f"residual_drop_prob must be in [0, 1), got {self.residual_drop_prob}")
        if self.residual_stages and self.encoding.rounds:
            raise ConfigError(
                f"the code search picks one stage's codes: with residual_stages={self.residual_stages} the encoding "
                "must be the nearest codes (encoding.rounds=0)"
            )
        if min(self.mse_weight, self.smooth_l1_weight, self.l1_weight) < 0:
            raise ConfigError("mse_weight, smooth_l1_weight and l1_weight must be >= 0")
        if len(set(self.hand_names)) != len(self.hand_names):
            raise ConfigError(f"hand_names has duplicates: {self.hand_names}")

    @classmethod
    def from_dict(cls, data: dict) -> "UniDexTokConfig":
        """A config from config.json's dict; a file without `format_version` is read as `format_version=None`
        (refused), not as the current version. A file with the flat legacy `search_*` keys (written before
        `EncodingConfig`) is upgraded (`upgrade_legacy_encoding`), one without `search_method` searching with
        LEGACY_SEARCH_METHOD (the only code search there was when it was written)."""
        data = upgrade_legacy_encoding(data)
        unknown = sorted(set(data) - {f.name for f in fields(cls)})
        if unknown:
            raise ConfigError(
                f"UniDexTok config.json has keys this version does not know: {unknown}; remove them, or install "
                "the lerobot-unidextok version that wrote the checkpoint"
            )
        hints = typing.get_type_hints(cls)
        for key, value in data.items():
            if not _fits(value, hints[key]):
                raise ConfigError(
                    f"UniDexTok config.json: {key}={value!r} is a {type(value).__name__}, expected "
                    f"{_type_name(hints[key])}; correct the value in config.json"
                )
        return cls(**{"format_version": None, **data})

    @classmethod
    def from_pretrained(cls, pretrained_model_name_or_path: str, revision: str | None = None) -> "UniDexTokConfig":
        """The config of a checkpoint (any name `UniDexTok.from_pretrained` takes), without its weights."""
        import json


        path = config_path(pretrained_model_name_or_path, revision)
        if not path.is_file():
            raise FileNotFoundError(f"{path} not found: a UniDexTok checkpoint folder holds config.json")
        return cls.from_dict(json.loads(path.read_text()))

    @property
    def group_dim(self) -> int:
        return self.codebook_dim // self.num_groups

    @property
    def num_stages(self) -> int:
        """Quantiser stages: 1 (the paper's) + the residual stages."""
        return 1 + self.residual_stages

    def symbols_per_hand(self, stages: int | None = None) -> int:
        """Codes one hand state becomes: N tokens x K groups per stage (None = every stage)."""
        return self.num_tokens * self.num_groups * (self.num_stages if stages is None else stages)

    @classmethod
    def from_preset(cls, name: str, **overrides) -> "UniDexTokConfig":
        """A preset by name (see PRESETS), with optional field overrides."""
        if name not in PRESETS:
            raise ConfigError(f"unknown UniDexTok preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(PRESETS[name], **overrides)


def _fits(value, hint) -> bool:
    """Whether a JSON value fits a field's annotation (int, float, str, bool, list[...], X | None; EncodingConfig:
    a dict, checked by `EncodingConfig.from_dict`)."""
    if hint is EncodingConfig:
        return isinstance(value, (dict, EncodingConfig))
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, a) for a in args)
    if hint is type(None):
        return value is None
    if origin is list:
        return isinstance(value, list) and (not args or all(_fits(v, args[0]) for v in value))
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, hint)


def _type_name(hint) -> str:
    return getattr(hint, "__name__", None) if typing.get_origin(hint) is None else str(hint).replace("typing.", "")


# Named presets; keys double as the CLI choices. VQ is the paper's (256 -> 8 x 32-entry) in all (first stage).
PRESETS: dict[str, UniDexTokConfig] = {
    # Paper sizes (N=8, C=512); depth/heads are our documented choice (not published).
    "paper": UniDexTokConfig(num_tokens=8, hidden_dim=512, encoder_depth=4, decoder_depth=4, num_heads=8),
    # CPU presets (departure: narrower and shallower than the paper so they train on 2 cores).
    # small: the paper's 8 tokens and VQ, C=64, 2 + 2 blocks, MLP ratio 2. Tuned on unseen real episodes
    # (docs/tokenizer.md, experiments/unseen_episodes.py): SmoothL1 weight 1 (paper: weight unpublished),
    # commitment weight 3 instead of the VQ-VAE 0.25 (the largest single gain: with a weak commitment the
    # encoder vectors drift far from their codes and the straight-through gradient misleads), and per-joint
    # range normalisation of the angles (paper: fixed pi).
    "small": UniDexTokConfig(
        num_tokens=8,
        hidden_dim=64,
        encoder_depth=2,
        decoder_depth=2,
        num_heads=4,
        mlp_ratio=2.0,
        smooth_l1_weight=1.0,
        commitment_weight=3.0,
        input_norm="range",
    ),
    "tiny": UniDexTokConfig(num_tokens=4, hidden_dim=64, encoder_depth=1, decoder_depth=1, num_heads=4),
}
# small_residual: small + one residual stage (departure, #48): 2 x 64 codes a hand, the first 64 the paper's sequence
PRESETS["small_residual"] = replace(PRESETS["small"], residual_stages=1)
