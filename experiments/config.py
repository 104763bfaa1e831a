"""Typed experiment configuration, parsed with draccus like the CLIs in `scripts/` (dotted flags,
`--config_path=experiments/configs/<size>.yaml`, `--help`)."""

import dataclasses
from dataclasses import dataclass, field, replace
from pathlib import Path

from lerobot_unidextok.training.config import TrainConfig
from lerobot_unidextok.utils.draccus_cli import parse_config as parse_cli
from lerobot_unidextok.utils.shared_data import real_data_dir, urdf_dir

DATA_CHOICES = ("auto", "real", "sample")
# TrainConfig fields each experiment sets itself, and the flag that controls them
SET_BY_THE_EXPERIMENT = {
    "datasets": "--datasets", "output_dir": "--models_dir", "hand_names": "the training rows", "seed": "--seed",
    "progress": "--progress", "eval_max_frames": "--max_eval_frames", "save_last_every": "the experiment",
}  # fmt: skip
# The checkout these experiments belong to: its sibling `shared/data/real` holds the real recordings.
PROJECT_ROOT = Path(__file__).resolve().parents[1]


def default_real_data_dir() -> str:
    """`../shared/data/real` beside the checkout, or `UNIDEXTOK_REAL_DATA` (`utils/shared_data.py`)."""
    return str(real_data_dir(PROJECT_ROOT))


@dataclass
class ExperimentTraining(TrainConfig):
    """`unidextok-train`'s settings with the experiments' shorter defaults (draccus builds a nested config
    from its class defaults, so they are declared here rather than passed to TrainConfig)."""

    steps: int = 600
    lr: float = 3e-3
    warmup_steps: int = 60
    eval_every: int = 200


@dataclass
class ExperimentConfig:
    """What every experiment shares: data, tokenizer training size, baseline sizes, outputs."""

    # --- data ---------------------------------------------------------------------------------------
    data: str = "auto"
    """auto: the real recordings in real_data_dir when present, else the SYNTHETIC sample; real | sample force one."""
    # Folder of the real recordings (../shared/data/real beside the checkout; env UNIDEXTOK_REAL_DATA); empty = that.
    real_data_dir: str = ""
    # Folder (or file) of robot URDFs for retargeting the real human motion (empty = ../shared/data/urdf).
    urdf_dir: str = ""
    # Robot hands the real human motion is retargeted onto (protocol b, UniHM's training data).
    retarget_hands: list[str] = field(
        default_factory=lambda: ["linkerhand_l10", "linkerhand_l20", "xhand1", "inspire_rh56_unitree"]
    )
    human_segment_s: float = 2.0  # the real human clip is cut into episodes of this length (s)
    # Converted UDHM datasets (local roots or repo ids) instead of the default data; overrides `data`.
    datasets: list[str] = field(default_factory=list)
    # Raw sources for ablation_mapping on real data, "source=path" (converted both ways); empty = samples.
    raw_sources: list[str] = field(default_factory=list)
    sample_episodes: int = 10  # per sample source
    sample_frames: int = 150  # per sample episode (+-20 %)
    data_dir: str = "outputs/experiments/_data"  # converted data cache, reused when valid

    # --- UniDexTok training (each configuration trained once, cached under models_dir) --------------
    train: ExperimentTraining = field(default_factory=ExperimentTraining)
    """unidextok-train's settings (--train.preset=tiny --train.steps=2000 ...); datasets, output folder, hand
    vocabulary, seed, progress and selection rows come from this config."""
    models_dir: str = "outputs/experiments/_models"  # trained tokenizers, reused for the same settings and rows

    # --- baselines ----------------------------------------------------------------------------------
    unihm_preset: str = "cpu"  # UniHM baseline size (baselines.unihm.UNIHM_PRESETS)
    unihm_teacher_steps: int = 400  # cut from the cpu preset's 1200 to fit the 5-minute budget
    unihm_rounds: int = 2
    unihm_round_steps: int = 30  # distil and align steps per round
    unihm_finetune_steps: int = 80
    qae_preset: str = "cpu"  # FSQ / RVQ baseline size (baselines.quantized_ae.QAE_PRESETS)
    qae_steps: int = 600  # FSQ / RVQ steps (cpu preset: 2000)
    with_qae: bool = True  # FSQ / RVQ (needs vector-quantize-pytorch)
    pca_components: int = 8  # PCA baseline: components = tokens per state (UniDexTok: 8)
    pca_bits: int = 8  # bits per PCA coefficient (8 x 8 = 64 bits per state)

    # --- transfer -----------------------------------------------------------------------------------
    holdout_hand: str = ""  # empty = the first hand whose name contains "inspire"
    fewshot_fraction: float = 0.062  # paper: 6.2 % of the held-out hand's frames
    fewshot_epochs: float = 2.0
    fewshot_batch_size: int = 64
    # lr of the embedding-row adaptation (shared encoder/codebook/decoder frozen), chosen among 5e-4, 1e-2 and
    # 5e-2 on the synthetic transfer run
    fewshot_lr: float = 1e-2
    # lr of the paper's few-shot fine-tuning of the whole tokenizer (transfer runs both adaptations)
    fewshot_lr_all: float = 5e-4
    fewshot_repeats: int = 3  # few-shot draws (different episodes of the held-out hand): mean and spread
    # On real recordings, add the SYNTHETIC sample robot hands (not the held-out one) to the base training data
    transfer_sample_hands: bool = True

    # --- probe --------------------------------------------------------------------------------------
    linkerhand_presets: str = ""
    """LinkerHand vendor presets (JSON); empty = <real_data_dir>/linkerhand-ros2-sdk/linkerhand_gui_preset_actions.json"""
    # Labelled real human gestures (MediaPipe HandLandmarker results); empty = <real_data_dir>/mediapipe/...
    human_gestures: str = ""
    probe_max_per_class: int = 400  # held gesture frames per (gesture, hand) kept for the probe

    # --- output -------------------------------------------------------------------------------------
    output_root: str = "outputs/experiments"  # result files: <output_root>/<experiment>/<experiment>.{json,md}
    render_samples: int = 3  # sampled states per hand in the 3D renderings
    max_eval_frames: int = 20000  # held-out rows scored per experiment (all if fewer)
    seed: int = 0  # seeds data sampling, training and the baselines
    progress: bool = True  # progress bars

    def __post_init__(self) -> None:
        if self.sample_episodes < 2 or self.sample_frames < 10:
            raise ValueError(
                f"need sample_episodes >= 2, sample_frames >= 10; got {self.sample_episodes}, {self.sample_frames}"
            )
        if isinstance(self.train, dict):
            self.train = ExperimentTraining(**self.train)
        default = TrainConfig()
        for name, owner in SET_BY_THE_EXPERIMENT.items():
            if getattr(self.train, name) != getattr(default, name):
                raise ValueError(f"train.{name} is set by each experiment from {owner}; drop --train.{name}")
        if self.data not in DATA_CHOICES:
            raise ValueError(f"data must be one of {DATA_CHOICES}, got {self.data!r}")
        if not 0.0 < self.fewshot_fraction <= 1.0:
            raise ValueError(f"fewshot_fraction must be in (0, 1], got {self.fewshot_fraction}")
        if self.human_segment_s <= 0:
            raise ValueError(f"human_segment_s must be > 0, got {self.human_segment_s}")
        for item in self.raw_sources:
            if "=" not in item:
                raise ValueError(f"raw_sources items are 'source=path', got {item!r}")

    # --- resolved paths -----------------------------------------------------------------------------
    @property
    def real_dir(self) -> Path:
        return Path(self.real_data_dir or default_real_data_dir())

    @property
    def urdf_root(self) -> Path:
        return Path(self.urdf_dir) if self.urdf_dir else urdf_dir(PROJECT_ROOT)

    @property
    def linkerhand_presets_path(self) -> Path:
        if self.linkerhand_presets:
            return Path(self.linkerhand_presets)
        return self.real_dir / "linkerhand-ros2-sdk" / "linkerhand_gui_preset_actions.json"

    @property
    def human_gestures_path(self) -> Path:
        if self.human_gestures:
            return Path(self.human_gestures)
        return self.real_dir / "mediapipe" / "mediapipe_hand_fixtures.json"

    @classmethod
    def from_preset(cls, name: str, **overrides) -> "ExperimentConfig":
        if name not in PRESETS:
            raise ValueError(f"unknown experiment preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(PRESETS[name], **overrides)


PRESETS: dict[str, ExperimentConfig] = {
    # ~3-5 minutes per experiment on 2 shared CPU cores (experiments/configs/default.yaml).
    "default": ExperimentConfig(),
    # Tests: seconds. Tiny tokenizer and baselines on 3 episodes x 30 frames per source
    # (experiments/configs/tiny.yaml holds the same values for the command line).
    "tiny": ExperimentConfig(
        sample_episodes=3, sample_frames=30,
        train=ExperimentTraining(preset="tiny", steps=20, batch_size=64, warmup_steps=2, eval_every=10),
        unihm_preset="tiny", unihm_teacher_steps=20, unihm_rounds=1, unihm_round_steps=3, unihm_finetune_steps=5,
        qae_preset="tiny", qae_steps=20, fewshot_fraction=0.3, fewshot_epochs=1.0, fewshot_batch_size=16,
        probe_max_per_class=20, render_samples=2, progress=False,
    ),
}  # fmt: skip


def parse_config(argv: list[str] | None = None, description: str = "") -> ExperimentConfig:
    """draccus, like the CLIs: `--config_path=experiments/configs/tiny.yaml` and `--<field>=<value>` for every
    field (lists as `--datasets='[a,b]'`, training as `--train.steps=2000`); `--help` lists the fields with
    their comments. `description` is accepted for callers that pass their docstring; draccus takes the help
    text from the field comments."""
    return parse_cli(ExperimentConfig, args=argv)


def config_dict(cfg: ExperimentConfig) -> dict:
    return dataclasses.asdict(cfg)
