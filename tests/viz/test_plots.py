"""Every plot writes a readable, non-empty PNG and rejects bad input with a clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from lerobot_unidextok import udhm
from lerobot_unidextok.viz import (
    GROUND_TRUTH_COLOR,
    UNIDEXTOK_COLOR,
    codebook_usage,
    method_colors,
    plot_codebook_usage,
    plot_hand_reconstructions,
    plot_per_joint_errors,
    plot_rate_distortion,
)


def _check_png(path: Path, min_kb: float = 10.0) -> np.ndarray:
    assert path.is_file() and path.suffix == ".png"
    assert path.stat().st_size > min_kb * 1024
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    assert img[..., :3].std() > 0.05  # not a blank canvas
    return img


def _has_color(img: np.ndarray, hex_color: str, min_pixels: int = 30) -> bool:
    rgb = np.array([int(hex_color[i : i + 2], 16) / 255 for i in (1, 3, 5)])
    return int((np.abs(img[..., :3] - rgb).max(-1) < 0.06).sum()) >= min_pixels


def test_hand_reconstructions_draws_every_method(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    gt = udhm.sample_angles(rng, (3,))
    recon = {"UniDexTok": gt + 0.03, "UniHM": gt + rng.normal(0, 0.15, gt.shape)}
    path = plot_hand_reconstructions(gt, recon, "inspire_rh56", tmp_path / "hands" / "inspire.png")
    img = _check_png(path)
    assert _has_color(img, GROUND_TRUTH_COLOR) and _has_color(img, UNIDEXTOK_COLOR)
    assert _has_color(img, method_colors(["UniHM"])["UniHM"])


def test_hand_reconstructions_on_real_recording(tmp_path: Path, real_data_dir: Path) -> None:
    keypoints_m = np.load(real_data_dir / "dex-retargeting" / "human_joint_right.npy")[::150][:4]  # (4, 21, 3)
    states = udhm.inverse_kinematics(keypoints_m).angles_rad  # (4, 22)
    path = plot_hand_reconstructions(states, {"binning": np.round(states * 8) / 8}, "human", tmp_path / "real.png",
                                     views=("side", "oblique", "palm"))  # fmt: skip
    _check_png(path)


def test_hand_reconstructions_bad_input(tmp_path: Path) -> None:
    gt = np.zeros((2, 22))
    with pytest.raises(ValueError, match=r"\(2, 22\)"):
        plot_hand_reconstructions(gt, {"x": np.zeros((3, 22))}, "human", tmp_path / "a.png")
    with pytest.raises(ValueError, match="unknown views"):
        plot_hand_reconstructions(gt, {}, "human", tmp_path / "a.png", views=("top",))
    with pytest.raises(ValueError, match="png"):
        plot_hand_reconstructions(gt, {}, "human", tmp_path / "a.jpg")


def test_per_joint_errors(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    per_state = np.abs(rng.normal(0, 3, (200, 22)))
    per_state[:, [2, 3]] = np.nan  # inactive slots
    path = plot_per_joint_errors({"UniDexTok": per_state, "binning": np.full(22, 0.1)}, tmp_path / "joints.png")
    img = _check_png(path)
    assert _has_color(img, UNIDEXTOK_COLOR)
    with pytest.raises(ValueError, match=r"\(22,\)"):
        plot_per_joint_errors({"a": np.zeros(21)}, tmp_path / "b.png")


def test_rate_distortion(tmp_path: Path) -> None:
    rows = [
        {"method": "binning", "hand": "human", "bits_per_state": 176.0, "mpjae_deg": 0.12},
        {"method": "UniDexTok", "hand": "human", "bits_per_state": 320.0, "mpjae_deg": 1.5},
        {"method": "unihm", "hand": "inspire_rh56", "bits_per_state": 10.0, "mpjae_deg": 6.0},
    ]
    _check_png(plot_rate_distortion(rows, tmp_path / "rd.png", error_label="MPJAE (deg)"))
    with pytest.raises(ValueError, match="mpjpe_mm"):
        plot_rate_distortion(rows, tmp_path / "rd2.png", error="mpjpe_mm")


def test_codebook_usage_stats_and_plot(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    codes = rng.integers(0, 16, size=(500, 8, 8))  # half of a 32-entry codebook per group
    stats = codebook_usage(codes, 32)
    assert stats["counts"].shape == (8, 32) and stats["counts"].sum() == 500 * 8 * 8
    np.testing.assert_allclose(stats["used_fraction"], 0.5)
    assert np.all((stats["perplexity"] > 15) & (stats["perplexity"] <= 16))
    _check_png(plot_codebook_usage(codes, 32, tmp_path / "usage.png"))
    _check_png(plot_codebook_usage(rng.integers(0, 1024, size=(400, 1)), 1024, tmp_path / "usage1.png"), min_kb=5)
    with pytest.raises(ValueError, match=r"\[0, 32\)"):
        codebook_usage(codes + 20, 32)
