"""PCA + uniform binning: the rival at UniDexTok's token count (8 tokens, 64 bits)."""

import numpy as np
import pytest
import torch

from lerobot_unidextok.baselines import PCAConfig, PCATokenizer, StateTokenizer, reconstruct


def _low_rank(n: int, rank: int, seed: int, mask: np.ndarray | None = None) -> np.ndarray:
    """States on a `rank`-dimensional affine subspace of the active slots (radians)."""
    rng = np.random.default_rng(seed)
    x = 0.5 + rng.uniform(-1, 1, (n, rank)) @ rng.normal(0, 0.3, (rank, 22))
    return x * (mask if mask is not None else 1.0)


def test_rate_is_8_tokens_64_bits():
    tok = PCATokenizer()
    tok.fit({"human": _low_rank(300, 12, 0)})
    assert isinstance(tok, StateTokenizer)
    assert tok.rate("human").tokens_per_state == 8 and tok.rate("human").bits_per_state == 64


def test_error_on_a_rank_8_subspace_is_the_binning_error():
    """States that PCA-8 spans exactly come back within half a bin per coefficient (the only loss)."""
    x = _low_rank(500, 8, 1)
    tok = PCATokenizer()
    tok.fit({"human": x})
    rec = reconstruct(tok, x, "human").numpy()
    b = tok.bases["human"]
    half_bin = (b.upper - b.lower) / tok.num_bins / 2  # (8,) in coefficient units; components are orthonormal
    assert np.linalg.norm(rec - x, axis=1).max() <= np.linalg.norm(half_bin) + 1e-5
    # more structure than 8 components: the error grows (PCA-8 is a real bottleneck)
    y = _low_rank(500, 16, 2)
    tok.fit({"human": y})
    assert np.abs(reconstruct(tok, y, "human").numpy() - y).mean() > 10 * np.abs(rec - x).mean()


def test_hand_with_few_dofs_and_inactive_slots():
    mask = np.zeros(22, bool)
    mask[[0, 1, 6, 10, 14, 19]] = True  # 6 DoFs < 8 components: PCA is a rotation, 6 tokens
    x = _low_rank(200, 6, 3, mask)
    tok = PCATokenizer()
    tok.fit({"inspire": x}, {"inspire": mask})
    assert tok.rate("inspire").tokens_per_state == 6
    rec = reconstruct(tok, x, "inspire").numpy()
    assert (rec[:, ~mask] == 0).all() and np.degrees(np.abs(rec - x)[:, mask]).max() < 1.0


def test_shared_basis_codes_a_hand_it_never_saw():
    mask = np.zeros(22, bool)
    mask[:10] = True
    tok = PCATokenizer(PCAConfig(shared=True))
    tok.fit({"human": _low_rank(300, 6, 4)}, {"human": np.ones(22, bool), "robot": mask})
    rec = reconstruct(tok, _low_rank(20, 6, 4, mask), "robot").numpy()
    assert rec.shape == (20, 22) and (rec[:, ~mask] == 0).all()


def test_bad_input():
    tok = PCATokenizer()
    tok.fit({"human": _low_rank(100, 9, 5)})
    with pytest.raises(ValueError, match=r"shape \(B, 8\)"):
        tok.decode(torch.zeros(2, 5, dtype=torch.long), "human")
    with pytest.raises(ValueError, match=r"lie in \[0, 256\)"):
        tok.decode(torch.full((2, 8), 256), "human")
    with pytest.raises(ValueError, match="does not know hand"):
        tok.encode(np.zeros((1, 22)), "robot")
    with pytest.raises(ValueError, match="num_components"):
        PCAConfig(num_components=0)
