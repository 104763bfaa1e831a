"""The paper's experiments, one `run(cfg)` / `main()` each; results as JSON + Markdown + PNG under
`outputs/experiments/<name>/`, collected into `benchmarks/RESULTS.md` by `make_results`."""

from experiments.config import PRESETS, ExperimentConfig, parse_config

EXPERIMENTS: tuple[str, ...] = (
    "main_table",
    "ablation_human",
    "ablation_mapping",
    "transfer",
    "probe",
    "policy_tokens",
    "rate_distortion",
    "cross_embodiment",
    "mix_lerobot_train",
    "closed_loop",
)

__all__ = ["EXPERIMENTS", "PRESETS", "ExperimentConfig", "parse_config"]
