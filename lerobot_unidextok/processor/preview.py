"""Text preview of the step's output: tokens next to the decoded state (for demos and CLIs)."""

from __future__ import annotations

import math

import torch

from lerobot_unidextok.constants import UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.processor.processor_unidextok import UniDexTokStateTokenizerStep


def token_preview(
    step: UniDexTokStateTokenizerStep, states_rad: torch.Tensor, joints: int = 6
) -> str:
    """Per frame and hand: the N x K codes, then input vs decoded angles (deg) and the mean abs error."""
    states_rad = torch.as_tensor(states_rad).reshape(
        -1, step.layout.state_dim
    )  # (B, 22*H)
    tokens, _ = step.tokenize(states_rad)  # (B, H*N*K)
    cfg = step.tokenizer.config
    codes = tokens.reshape(
        len(states_rad), step.layout.num_hands, cfg.num_tokens, cfg.num_groups
    )
    rows = states_rad.reshape(-1, UDHM_DIM)  # (B*H, 22)
    ids = step._hand_ids.repeat(len(states_rad))
    decoded = step.tokenizer.decode(
        codes.reshape(-1, cfg.num_tokens, cfg.num_groups), ids
    )  # (B*H, 22)
    deg = 180.0 / math.pi
    names = [n[:14] for n in UDHM_JOINT_NAMES[:joints]]
    lines = []
    for b in range(len(states_rad)):
        for h, hand in enumerate(step.layout.hands):
            r = b * step.layout.num_hands + h
            err = (decoded[r] - rows[r]).abs().mean().item() * deg
            lines.append(
                f"frame {b} hand {h} ({hand}): mean |decoded - input| = {err:.2f} deg"
            )
            lines += [
                "  tokens " + " ".join(f"{c:2d}" for c in codes[b, h, n].tolist())
                for n in range(cfg.num_tokens)
            ]
            lines.append("  " + "".join(f"{n:>15}" for n in names))
            lines.append(
                "  "
                + "".join(f"{v * deg:>15.1f}" for v in rows[r, :joints].tolist())
                + "   input deg"
            )
            lines.append(
                "  "
                + "".join(f"{v * deg:>15.1f}" for v in decoded[r, :joints].tolist())
                + "   decoded deg"
            )
    return "\n".join(lines)
