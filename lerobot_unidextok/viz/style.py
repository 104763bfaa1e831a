"""Shared colours and figure helpers (matplotlib object API, no pyplot state: headless-safe)."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

GROUND_TRUTH_COLOR = "#e8e8e8"  # white / light grey
UNIDEXTOK_COLOR = "#2ecc40"  # green
BASELINE_COLORS = ("#ff4136", "#ff851b", "#f012be", "#b10dc9", "#ffdc00")  # red first, then distinct warm hues
DARK_BG = "#2a2a2a"
OTHER_COLORS = ("#0074d9", "#7fdbff", "#39cccc", "#85144b", "#3d9970")
# Camera views of a hand in its wrist frame (udhm/frames.py: x palmar normal, y thumb side of a right hand,
# z distal): name -> (elevation, azimuth) in degrees, matplotlib's convention.
VIEWS: dict[str, tuple[float, float]] = {
    "side": (0.0, 90.0),  # from the thumb side: flexion profile
    "oblique": (25.0, 35.0),  # between palm and thumb side
    "palm": (0.0, 0.0),  # facing the palm: abduction and spread
}


def method_colors(methods: list[str]) -> dict[str, str]:
    """UniDexTok green, ground truth light grey, baselines red then other warm hues, in the given order."""
    colors: dict[str, str] = {}
    baseline_i = 0
    for m in methods:
        key = m.lower()
        if key in ("gt", "ground truth", "ground_truth"):
            colors[m] = GROUND_TRUTH_COLOR
        elif "unidextok" in key:
            colors[m] = UNIDEXTOK_COLOR
        else:
            palette = BASELINE_COLORS + OTHER_COLORS
            colors[m] = palette[baseline_i % len(palette)]
            baseline_i += 1
    return colors


def save(fig: Figure, out_path: str | Path, dpi: int = 120) -> Path:
    """Write the figure as PNG (parents created) and return the path."""
    path = Path(out_path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"plots are written as PNG; give a path ending in .png, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, facecolor=fig.get_facecolor(), bbox_inches="tight")
    return path
