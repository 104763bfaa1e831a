"""UniDexTok configuration: one typed dataclass and named size presets."""

from dataclasses import dataclass, field, replace

from lerobot_unidextok.constants import UDHM_DIM

# Bump when a change makes old checkpoints unloadable (layer names, shapes, semantics of fields).
FORMAT_VERSION = 1

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
    state_dim: int = UDHM_DIM  # 22 UDHM angles per hand, radians; normalised by a fixed pi
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
    codebook_weight: float = 1.0  # weight of ||q - sg[u]||^2 (paper: 1)
    entropy_weight: float = 0.0  # optional code-entropy regulariser, off by default (paper: off)
    entropy_temperature: float = 0.1  # softmax temperature over cosine similarities for the entropy term
    # Departure: dead-code re-seeding is not described in the paper. Codes whose usage EMA falls
    # below this fraction of uniform usage are re-seeded from batch features (0 disables).
    dead_code_threshold: float = 0.03
    usage_decay: float = 0.99  # EMA decay of per-code usage counts

    # --- reconstruction loss ------------------------------------------------------------------------
    # MSE in normalised angle space (paper: plain MSE). Restricting it to active DoFs is our choice (padded
    # slots are zero by construction, not targets). Optional SmoothL1 (paper mentions it, weight unknown).
    smooth_l1_weight: float = 0.0

    def __post_init__(self) -> None:
        if self.format_version != FORMAT_VERSION:
            raise ValueError(
                f"UniDexTok config format_version={self.format_version} does not match this code's "
                f"FORMAT_VERSION={FORMAT_VERSION}; re-train or convert the checkpoint, or install the "
                "lerobot-unidextok version that wrote it"
            )
        if self.hidden_dim % self.num_heads != 0:
            raise ValueError(f"hidden_dim={self.hidden_dim} must be divisible by num_heads={self.num_heads}")
        if self.codebook_dim % self.num_groups != 0:
            raise ValueError(f"codebook_dim={self.codebook_dim} must be divisible by num_groups={self.num_groups}")
        for name in ("num_tokens", "hidden_dim", "num_heads", "codebook_size", "state_dim"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        self.hand_names = list(self.hand_names)  # JSON round trip gives lists; keep one type
        self.trained_hands = list(self.trained_hands)
        if len(set(self.hand_names)) != len(self.hand_names):
            raise ValueError(f"hand_names has duplicates: {self.hand_names}")

    @property
    def group_dim(self) -> int:
        return self.codebook_dim // self.num_groups

    @classmethod
    def from_preset(cls, name: str, **overrides) -> "UniDexTokConfig":
        """A preset by name (see PRESETS), with optional field overrides."""
        if name not in PRESETS:
            raise ValueError(f"unknown UniDexTok preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(PRESETS[name], **overrides)


# Named presets; keys double as the CLI choices. VQ is the paper's (256 -> 8 x 32-entry) in all.
PRESETS: dict[str, UniDexTokConfig] = {
    # Paper sizes (N=8, C=512); depth/heads are our documented choice (not published).
    "paper": UniDexTokConfig(num_tokens=8, hidden_dim=512, encoder_depth=4, decoder_depth=4, num_heads=8),
    # CPU presets (departure: narrower and shallower than the paper so they train on 2 cores).
    # small: the paper's 8 tokens, C=64 and MLP ratio 2 so a 10-minute run on 2 shared cores converges.
    # SmoothL1 weight 1 (paper: SmoothL1 auxiliary, weight unpublished): its gradient does not vanish
    # near zero error like MSE's. Measured on gesture data: 1.56 deg held-out MAE at step 1200 of 2400
    # with it vs 1.86 deg after a full 1200-step run without it (bench: /tmp experiments, see docs/tokenizer.md).
    "small": UniDexTokConfig(
        num_tokens=8,
        hidden_dim=64,
        encoder_depth=2,
        decoder_depth=2,
        num_heads=4,
        mlp_ratio=2.0,
        smooth_l1_weight=1.0,
    ),
    "tiny": UniDexTokConfig(num_tokens=4, hidden_dim=64, encoder_depth=1, decoder_depth=1, num_heads=4),
}
