"""Typed experiment configuration with named presets, read from YAML and `--field=value` flags."""

import argparse
import dataclasses
import typing
from dataclasses import dataclass, field, fields, replace
from pathlib import Path


@dataclass
class ExperimentConfig:
    """What every experiment shares: data, tokenizer training size, baseline sizes, outputs."""

    # --- data ---------------------------------------------------------------------------------------
    # Converted UDHM datasets (local roots or repo ids); empty = the built-in SYNTHETIC sample data.
    datasets: list[str] = field(default_factory=list)
    # Raw sources for ablation_mapping on real data, "source=path" (converted both ways); empty = samples.
    raw_sources: list[str] = field(default_factory=list)
    sample_episodes: int = 10  # per sample source
    sample_frames: int = 150  # per sample episode (+-20 %)
    data_dir: str = "outputs/experiments/_data"  # converted sample cache, reused when valid

    # --- UniDexTok training (each configuration trained once, cached under models_dir) --------------
    preset: str = "small"
    steps: int = 600
    batch_size: int = 256
    lr: float = 3e-3
    warmup_steps: int = 60
    eval_every: int = 200
    models_dir: str = "outputs/experiments/_models"

    # --- baselines ----------------------------------------------------------------------------------
    unihm_preset: str = "cpu"
    unihm_teacher_steps: int = 400  # cut from the cpu preset's 1200 to fit the 5-minute budget
    unihm_rounds: int = 2
    unihm_round_steps: int = 30  # distil and align steps per round
    unihm_finetune_steps: int = 80
    qae_preset: str = "cpu"
    qae_steps: int = 600  # FSQ / RVQ steps (cpu preset: 2000)
    with_qae: bool = True  # FSQ / RVQ (needs vector-quantize-pytorch)

    # --- transfer -----------------------------------------------------------------------------------
    holdout_hand: str = ""  # empty = the first hand whose name contains "inspire"
    fewshot_fraction: float = 0.062  # paper: 6.2 % of the held-out hand's frames
    fewshot_epochs: float = 2.0
    fewshot_batch_size: int = 64
    # Few-shot trains only the new hand's embedding row (shared encoder/codebook/decoder frozen); lr picked from
    # {5e-4, 1e-2, 5e-2} on the synthetic transfer run (2.45 / 2.29 / 4.36 deg; all-parameter adaptation: 3.08 / 23 / 173).
    fewshot_lr: float = 1e-2
    fewshot_adapt: str = "hand_embedding"  # "all" parameters or only the new "hand_embedding"

    # --- probe --------------------------------------------------------------------------------------
    linkerhand_presets: str = "/work/shared/data/real/linkerhand-ros2-sdk/linkerhand_gui_preset_actions.json"
    probe_max_per_class: int = 400  # held gesture frames per (gesture, hand) kept for the probe

    # --- output -------------------------------------------------------------------------------------
    output_root: str = "outputs/experiments"
    render_samples: int = 3  # sampled states per hand in the 3D renderings
    max_eval_frames: int = 20000  # held-out rows scored per experiment (all if fewer)
    seed: int = 0
    progress: bool = True

    def __post_init__(self) -> None:
        if self.steps < 1 or self.sample_episodes < 2 or self.sample_frames < 10:
            raise ValueError(
                f"need steps >= 1, sample_episodes >= 2, sample_frames >= 10; got {self.steps}, "
                f"{self.sample_episodes}, {self.sample_frames}"
            )
        if not 0.0 < self.fewshot_fraction <= 1.0:
            raise ValueError(f"fewshot_fraction must be in (0, 1], got {self.fewshot_fraction}")
        for item in self.raw_sources:
            if "=" not in item:
                raise ValueError(f"raw_sources items are 'source=path', got {item!r}")

    @classmethod
    def from_preset(cls, name: str, **overrides) -> "ExperimentConfig":
        if name not in PRESETS:
            raise ValueError(f"unknown experiment preset {name!r}; choose one of {sorted(PRESETS)}")
        return replace(PRESETS[name], **overrides)


PRESETS: dict[str, ExperimentConfig] = {
    # Sample data, ~3-5 minutes per experiment on 2 shared CPU cores.
    "default": ExperimentConfig(),
    # Tests: seconds. Tiny tokenizer and baselines on 2 episodes x 40 frames per source.
    "tiny": ExperimentConfig(
        sample_episodes=3, sample_frames=30, preset="tiny", steps=20, batch_size=64, warmup_steps=2, eval_every=10,
        unihm_preset="tiny", unihm_teacher_steps=20, unihm_rounds=1, unihm_round_steps=3, unihm_finetune_steps=5,
        qae_preset="tiny", qae_steps=20, fewshot_fraction=0.3, fewshot_epochs=1.0, fewshot_batch_size=16,
        probe_max_per_class=20, render_samples=2, progress=False,
    ),
}  # fmt: skip


def _convert(value: str, typ) -> object:
    origin = typing.get_origin(typ)
    if origin is list:
        value = value.strip()
        if value.startswith("["):
            value = value[1:-1]
        return [v.strip().strip("'\"") for v in value.split(",") if v.strip()]
    if typ is bool:
        if value.lower() in ("1", "true", "yes"):
            return True
        if value.lower() in ("0", "false", "no"):
            return False
        raise ValueError(f"expected true/false, got {value!r}")
    return typ(value)


def parse_config(argv: list[str] | None = None, description: str = "") -> ExperimentConfig:
    """`--tiny`, `--config_path=file.yaml` and `--<field>=<value>` for every ExperimentConfig field."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--tiny", action="store_true", help="the tiny preset (tests, seconds)")
    parser.add_argument("--config_path", default=None, help="YAML file of ExperimentConfig fields")
    hints = typing.get_type_hints(ExperimentConfig)
    for f in fields(ExperimentConfig):
        parser.add_argument(f"--{f.name}", default=None, help=f"{hints[f.name]}")
    args = parser.parse_args(argv)
    values: dict[str, object] = {}
    if args.config_path:
        import yaml

        loaded = yaml.safe_load(Path(args.config_path).read_text()) or {}
        unknown = sorted(set(loaded) - set(hints))
        if unknown:
            raise ValueError(f"{args.config_path}: unknown fields {unknown}; known: {sorted(hints)}")
        values.update(loaded)
    for f in fields(ExperimentConfig):
        raw = getattr(args, f.name)
        if raw is not None:
            try:
                values[f.name] = _convert(raw, hints[f.name])
            except ValueError as e:
                raise ValueError(f"--{f.name}={raw!r}: {e}") from e
    return ExperimentConfig.from_preset("tiny" if args.tiny else "default", **values)


def config_dict(cfg: ExperimentConfig) -> dict:
    return dataclasses.asdict(cfg)
