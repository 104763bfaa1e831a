"""The share rule of `unidextok-mix`: each input's share of the sampled training frames, chosen without tuning.

An input's share is proportional to its training frames to the power `alpha` (`--share_alpha`, 0.43 by default):

    share[k] = frames[k] ** alpha / sum_j frames[j] ** alpha

`alpha = 1` is each input at its frame share (what LeRobot samples when every frame is taken equally), `alpha = 0`
one equal share per input; in between, a small input gets more than its frames and never as much as a large one.
0.43 is π0's exponent (Black et al. 2024, "π0: A Vision-Language-Action Flow Model for General Robot Control",
arXiv 2410.24164, section V-A: each task-robot combination of the pre-training mixture weighted by n^0.43, n its
samples). With 10 target demonstrations beside 50 per other hand it gives the target 0.33 of the frames between two
hands and 0.09 among six, where the closed-loop runs measured their best shares, 0.4 and 0.1 (docs/pooling.md):
the share follows the pool without a number typed in per pool.

`--share_rule=frames` keeps the mix as it was before the rule: each input at its frame share, no share recorded.
`--weights` overrides the rule.

Layer 3 (conversion): numpy only.
"""

from __future__ import annotations

import math

import numpy as np

POWER, FRAMES, WEIGHTS = "power", "frames", "weights"
SHARE_RULES = (POWER, FRAMES)  # what --share_rule takes (WEIGHTS is recorded when --weights chose the shares)
DEFAULT_ALPHA = 0.43  # π0's exponent (arXiv 2410.24164, section V-A)


def alpha_problem(alpha: float) -> str:
    """'' for an exponent the rule takes (a finite number in [0, 1]), else what is wrong with it."""
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float)) or not math.isfinite(alpha):
        return f"share_alpha must be a finite number in [0, 1], got {alpha!r}"
    if not 0 <= alpha <= 1:
        return (f"share_alpha must be in [0, 1] (0: one equal share per input, 1: each input at its frame share), "
                f"got {alpha:g}")  # fmt: skip
    return ""


def power_shares(train_frames: list[int], alpha: float) -> list[float]:
    """Each input's share, proportional to `train_frames[k] ** alpha`, summing to 1. Computed in logs, relative to
    the largest input, so that no count overflows whatever its size."""
    frames = np.asarray(train_frames, dtype=np.float64)
    if frames.size == 0 or not (frames > 0).all():
        raise ValueError(f"the share rule needs a positive count of training frames per input, got {train_frames}")
    weights = np.exp(alpha * (np.log(frames) - np.log(frames.max())))  # in (0, 1]
    return [float(w) for w in weights / weights.sum()]


def rule_text(rule: str, alpha: float | None = None) -> str:
    """'frames^0.43', 'each input's frame share', '--weights': how the shares were chosen, for the summary."""
    if rule == POWER:
        return f"frames^{alpha:g}"
    if rule == WEIGHTS:
        return "--weights"
    return "each input's frame share"


__all__ = ["DEFAULT_ALPHA", "FRAMES", "POWER", "SHARE_RULES", "WEIGHTS", "alpha_problem", "power_shares", "rule_text"]
