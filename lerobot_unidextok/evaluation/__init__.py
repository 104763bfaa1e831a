"""Evaluation (layer 5): reconstruction metrics (MPJAE, MPJPE, fingertip), tokenizer reports."""

from lerobot_unidextok.evaluation.metrics import (
    fingertip_error_mm,
    keypoint_errors_mm,
    mpjae_deg,
    mpjpe_mm,
    per_joint_mae_deg,
    reconstruction_metrics,
)
from lerobot_unidextok.evaluation.reconstruct import Reconstruction, codebook_usage, reconstruct
from lerobot_unidextok.evaluation.report import evaluate_tokenizer, markdown_table, write_report

__all__ = [
    "Reconstruction",
    "codebook_usage",
    "evaluate_tokenizer",
    "fingertip_error_mm",
    "keypoint_errors_mm",
    "markdown_table",
    "mpjae_deg",
    "mpjpe_mm",
    "per_joint_mae_deg",
    "reconstruct",
    "reconstruction_metrics",
    "write_report",
]
