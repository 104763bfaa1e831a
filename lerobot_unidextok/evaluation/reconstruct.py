"""Run a tokenizer over in-memory rows: encode -> decode in batches, with codebook statistics."""

from dataclasses import dataclass

import numpy as np
import torch


@dataclass
class Reconstruction:
    states_rad: np.ndarray  # (N, 22) decoded states
    codes: np.ndarray  # (N, T, K) int64


@torch.no_grad()
def reconstruct(
    model,
    states_rad: np.ndarray,
    hands: np.ndarray,
    batch_size: int = 4096,
    allow_unknown: bool = False,
    masks: np.ndarray | None = None,
    encoding=None,
    stages: int | None = None,
) -> Reconstruction:
    """decode(encode(x)) for every row; `hands` names one hand per row, `masks` (N, 22) bool its active DoFs (for
    the code search; None = from the hand specs), `encoding` (an EncodingConfig) None = the model's own, `stages`
    the quantiser stages encoded and decoded (None = all; 1 = a residual model's first stage alone)."""
    was_training = model.training
    model.eval()
    outs, codes = [], []
    try:
        for i in range(0, len(states_rad), batch_size):
            x = torch.as_tensor(states_rad[i : i + batch_size], dtype=torch.float32)
            h = [str(s) for s in hands[i : i + batch_size]]
            m = None if masks is None else torch.tensor(masks[i : i + batch_size], dtype=torch.bool)  # (b, 22)
            c = model.encode(x, h, allow_unknown=allow_unknown, mask=m, encoding=encoding, stages=stages)  # (b, T, K*s)
            outs.append(model.decode(c, h, allow_unknown=allow_unknown).cpu().numpy())
            codes.append(c.cpu().numpy())
    finally:
        model.train(was_training)
    if not outs:
        raise ValueError("nothing to reconstruct: zero rows")
    return Reconstruction(np.concatenate(outs), np.concatenate(codes))


def codebook_usage(codes: np.ndarray, codebook_size: int) -> dict[str, float]:
    """Fraction of (group, code) pairs used and mean per-group perplexity over all tokens."""
    flat = codes.reshape(-1, codes.shape[-1])  # (M, K)
    k = flat.shape[1]
    counts = np.stack([np.bincount(flat[:, g], minlength=codebook_size) for g in range(k)])  # (K, S)
    p = counts / max(1, flat.shape[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        ent = -np.where(p > 0, p * np.log(p), 0.0).sum(1)
    return {
        "usage": float((counts > 0).mean()),
        "perplexity": float(np.exp(ent).mean()),
        "codebook_size": int(codebook_size),
    }
