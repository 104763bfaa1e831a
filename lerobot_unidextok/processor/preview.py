"""Text preview of the step's output: tokens next to the decoded state (for demos and CLIs)."""

from __future__ import annotations

import math

import torch

from lerobot_unidextok.constants import UDHM_DIM, UDHM_JOINT_NAMES
from lerobot_unidextok.processor.processor_unidextok import UniDexTokStateTokenizerStep


def token_preview(step: UniDexTokStateTokenizerStep, states_rad: torch.Tensor, joints: int = 6) -> str:
    """Per frame and hand: the N x K codes, then input vs decoded angles (deg) of the first `joints`
    active DoFs, and the mean abs error over the hand's active DoFs."""
    states_rad = torch.as_tensor(states_rad).reshape(-1, step.layout.state_dim)  # (B, D) whole states
    tokens, _ = step.tokenize(states_rad)  # (B, H*N*K)
    cfg = step.tokenizer.config
    num_hands = step.layout.num_hands
    codes = tokens.reshape(len(states_rad), num_hands, cfg.num_tokens, cfg.num_groups)  # (B, H, N, K)
    rows = step.hand_blocks(states_rad)  # (B, H, 22) the UDHM blocks, radians
    ids = step.hand_ids.repeat(len(states_rad))  # (B*H,)
    decoded = step.tokenizer.decode(codes.reshape(-1, cfg.num_tokens, cfg.num_groups), ids)  # (B*H, 22)
    decoded = decoded.reshape(-1, num_hands, UDHM_DIM)  # (B, H, 22)
    deg = 180.0 / math.pi
    lines = []
    for b in range(len(states_rad)):
        for h, hand in enumerate(step.layout.hands):
            active = step.active_masks[h].cpu()  # (22,) bool
            slots = active.nonzero().flatten()[:joints].tolist()
            err = (decoded[b, h] - rows[b, h]).abs()[active].mean().item() * deg
            lines.append(f"frame {b} hand {h} ({hand}): {cfg.num_tokens} tokens x {cfg.num_groups} codes, "
                         f"mean |decoded - input| over {int(active.sum())} active DoFs = {err:.2f} deg")  # fmt: skip
            lines += ["  tokens " + " ".join(f"{c:2d}" for c in codes[b, h, n].tolist()) for n in range(cfg.num_tokens)]
            lines.append("  " + "".join(f"{UDHM_JOINT_NAMES[j][:16]:>17}" for j in slots))
            lines.append("  " + "".join(f"{rows[b, h, j].item() * deg:>17.1f}" for j in slots) + "   input deg")
            lines.append("  " + "".join(f"{decoded[b, h, j].item() * deg:>17.1f}" for j in slots) + "   decoded deg")
    return "\n".join(lines)
