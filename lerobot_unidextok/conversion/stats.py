"""Per-episode feature stats identical to LeRobot 0.6's `compute_episode_stats`, vectorised.

LeRobot computes q01..q99 from a 5000-bin histogram per dimension with a Python loop per dimension
and quantile (`compute_stats.RunningQuantileStats`); for one batch (one episode) the same histogram,
edges and interpolation are computed here for all dimensions at once. `tests/conversion/test_stats.py`
checks equality against LeRobot's function.
"""

from __future__ import annotations

import math

import numpy as np

QUANTILES: tuple[float, ...] = (
    0.01,
    0.10,
    0.50,
    0.90,
    0.99,
)  # lerobot DEFAULT_QUANTILES
QUANTILE_KEYS: tuple[str, ...] = tuple(f"q{int(q * 100):02d}" for q in QUANTILES)
NUM_BINS = 5000  # RunningQuantileStats default


def _bin_indices(batch: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(T, D) bin of each value as np.histogram(batch[:, d], bins=edges[d]) counts it.

    Bin i holds edges[i] <= x < edges[i + 1]; the last bin is closed. Constant dimensions take one
    searchsorted; others an arithmetic guess on the near-uniform edges, corrected against the real
    edges; dimensions whose edges are not strictly increasing (float32 collapse) use searchsorted.
    """
    num, dim = batch.shape
    idx = np.empty((num, dim), dtype=np.int64)

    def exact(d: int, values: np.ndarray) -> np.ndarray:
        e = edges[d]
        out = np.searchsorted(e, values, side="right") - 1
        out[values == e[-1]] = NUM_BINS - 1
        return np.clip(out, 0, NUM_BINS - 1)

    const = batch.min(axis=0) == batch.max(axis=0)  # (D,)
    for d in np.flatnonzero(const):
        idx[:, d] = exact(d, batch[:1, d])[0]
    var = np.flatnonzero(~const)
    if not len(var):
        return idx
    e = edges[var]  # (V, B+1)
    x = batch[:, var]  # (T, V)
    strict = np.all(e[:, 1:] > e[:, :-1], axis=1)  # (V,)
    first, span = e[:, 0], (e[:, -1] - e[:, 0]).astype(np.float64)
    guess = np.floor((x - first) / np.where(span > 0, span, 1.0) * NUM_BINS)
    sub = np.clip(guess, 0, NUM_BINS - 1).astype(np.int64)  # (T, V)
    width = len(var)
    flat_edges = np.ascontiguousarray(e.T).reshape(-1)  # (B+1) * V: edge j of column v at j * V + v
    cols = np.arange(width)
    for _ in range(8):  # each pass moves a wrong guess one bin; guesses are off by at most one or two
        flat = sub * width + cols  # (T, V)
        down = flat_edges[flat] > x
        up = (sub < NUM_BINS - 1) & (flat_edges[flat + width] <= x)
        if not (down.any() or up.any()):
            break
        sub += up.astype(np.int64) - down.astype(np.int64)
    else:
        strict[:] = False
    idx[:, var] = sub
    for j in np.flatnonzero(~strict):
        idx[:, var[j]] = exact(var[j], batch[:, var[j]])
    return idx


def _vector_stats(batch: np.ndarray) -> dict[str, np.ndarray]:
    """Stats of (T, D) `batch` along axis 0, as RunningQuantileStats after one `update`."""
    num, dim = batch.shape
    if num < 2:  # lerobot _compute_basic_stats, on the raw dtype
        mean = np.mean(batch, axis=0)
        out = {
            "min": np.min(batch, axis=0),
            "max": np.max(batch, axis=0),
            "mean": mean,
            "std": np.std(batch, axis=0),
        }
        out.update({k: mean.copy() for k in QUANTILE_KEYS})
        return out

    batch = batch.astype(np.result_type(batch.dtype, np.float32), copy=False)
    mean = np.mean(batch, axis=0)
    mean_sq = np.mean(batch**2, axis=0)
    vmin, vmax = np.min(batch, axis=0), np.max(batch, axis=0)
    # RunningQuantileStats.update adds (batch_mean - mean) * 1 once more: a no-op in exact arithmetic, kept for bit-equality.
    mean += (mean - mean) * (num / num)
    mean_sq += (mean_sq - mean_sq) * (num / num)
    std = np.sqrt(np.maximum(0, mean_sq - mean**2))

    # histograms (D, NUM_BINS) on per-dimension linspace edges, np.histogram's bin rule
    # lerobot calls linspace per dimension; one vectorised call gives the same values unless some
    # dimension has a zero step (numpy then switches formula for the whole array), so those go alone.
    lo, hi = vmin - 1e-10, vmax + 1e-10
    edges = np.empty((dim, NUM_BINS + 1), dtype=np.result_type(vmin.dtype, np.float32))  # (D, B+1)
    zero_step = (hi - lo) / NUM_BINS == 0
    if (~zero_step).any():
        edges[~zero_step] = np.linspace(lo[~zero_step], hi[~zero_step], NUM_BINS + 1, axis=-1)
    for d in np.flatnonzero(zero_step):
        edges[d] = np.linspace(lo[d], hi[d], NUM_BINS + 1)
    idx = _bin_indices(batch, edges)  # (T, D) np.histogram bin of every value
    idx_sorted = np.sort(idx, axis=0)  # (T, D)

    out = {"min": vmin, "max": vmax, "mean": mean, "std": std}
    rows = np.arange(dim)
    for q, key in zip(QUANTILES, QUANTILE_KEYS, strict=True):
        # lerobot: k = searchsorted(cumsum(hist), target); cumsum counts are integers, so k is the bin
        # of the ceil(target)-th smallest value.
        target = q * num
        k = idx_sorted[math.ceil(target) - 1]  # (D,)
        before = (idx_sorted < k).sum(axis=0).astype(np.float64)  # cumsum[k - 1]
        in_bin = (idx_sorted == k).sum(axis=0).astype(np.float64)
        e0, e1 = edges[rows, k], edges[rows, np.minimum(k + 1, NUM_BINS)]
        interp = e0 + (target - before) / np.maximum(in_bin, 1) * (e1 - e0)  # float64
        res = np.where(k == 0, e0, interp)
        # lerobot builds the array from per-dimension scalars: float64 only if some value was interpolated
        out[key] = res if bool(np.any(k > 0)) else res.astype(edges.dtype)
    return out


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """Stats of one episode's feature values (T,) or (T, D), shaped as LeRobot stores them."""
    num = values.shape[0]
    stats = _vector_stats(values.reshape(num, -1))
    if values.ndim == 1:  # keepdims: (1,)
        stats = {k: v.reshape(1) for k, v in stats.items()}
    ordered = {k: stats[k] for k in ("min", "max", "mean", "std")}  # lerobot key order
    ordered["count"] = np.array([num])
    ordered.update({k: stats[k] for k in QUANTILE_KEYS})
    return ordered


def episode_stats(episode: dict[str, np.ndarray], features: dict[str, dict]) -> dict[str, dict[str, np.ndarray]]:
    """`compute_episode_stats` for numeric/bool features (strings skipped, no images)."""
    out = {}
    for key, values in episode.items():
        dtype = features[key]["dtype"]
        if dtype in ("string", "language"):
            continue
        if dtype in ("image", "video"):
            raise ValueError(f"feature {key!r} is {dtype}: the UDHM writer handles state-only datasets")
        out[key] = feature_stats(np.asarray(values))
    return out
