"""Vectorised episode stats equal LeRobot's compute_episode_stats bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok.conversion.stats import episode_stats


def _cases():
    rng = np.random.default_rng(7)
    for trial in range(24):
        num, dim = int(rng.integers(1, 300)), int(rng.integers(1, 8))
        kind = trial % 6
        if kind == 0:
            x = rng.normal(size=(num, dim))
        elif kind == 1:
            x = rng.normal(size=(num, dim)) * 1e-6 + 3  # float32 edge collapse
        elif kind == 2:
            x = rng.integers(0, 3, size=(num, dim))  # many ties
        elif kind == 3:
            x = np.round(rng.uniform(0, 1000, size=(num, dim))) / 1000
        elif kind == 4:
            x = np.zeros((num, dim))
            x[::3] = 1e-3
        else:
            x = np.full((num, dim), 0.7)  # constant
        yield f"{trial}-{kind}", x.astype(np.float32)


@pytest.mark.parametrize("name,x", list(_cases()))
def test_float_features_bit_exact(name, x):
    from lerobot.datasets.compute_stats import compute_episode_stats

    features = {
        "x": {"dtype": "float32", "shape": (x.shape[1],)},
        "m": {"dtype": "bool", "shape": (x.shape[1],)},
    }
    ep = {"x": x, "m": x > np.median(x)}
    a, b = compute_episode_stats(ep, features), episode_stats(ep, features)
    for key in a:
        assert list(a[key]) == list(b[key])
        for stat in a[key]:
            assert a[key][stat].dtype == b[key][stat].dtype, (key, stat)
            np.testing.assert_array_equal(b[key][stat], a[key][stat], err_msg=f"{key}/{stat}")


def test_scalar_features_and_strings():
    from lerobot.datasets.compute_stats import compute_episode_stats

    n = 123
    features = {
        "t": {"dtype": "float32", "shape": (1,)},
        "i": {"dtype": "int64", "shape": (1,)},
        "s": {"dtype": "string", "shape": (1,)},
    }
    ep = {
        "t": np.arange(n) / 30,
        "i": np.arange(n, dtype=np.int64),
        "s": np.array(["a"] * n),
    }
    a, b = compute_episode_stats(ep, features), episode_stats(ep, features)
    assert "s" not in b and a.keys() == b.keys()
    for key in a:
        for stat in a[key]:
            assert a[key][stat].shape == b[key][stat].shape == (1,)
            np.testing.assert_array_equal(b[key][stat], a[key][stat])


def test_mixed_constant_and_varying_dimensions_of_a_real_episode_shape():
    """UDHM-like episode: masked zero slots, constant mask columns and moving joints side by side."""
    from lerobot.datasets.compute_stats import compute_episode_stats

    rng = np.random.default_rng(11)
    state = np.cumsum(rng.normal(0, 0.02, size=(700, 44)), axis=0).astype(np.float32)
    state[:, [1, 3, 17, 23, 39]] = 0.0
    state[:, 5] = 1.25
    mask = np.ones((700, 44), bool)
    mask[:, [1, 3, 17, 23, 39]] = False
    features = {
        "s": {"dtype": "float32", "shape": (44,)},
        "m": {"dtype": "bool", "shape": (44,)},
    }
    ep = {"s": state, "m": mask}
    a, b = compute_episode_stats(ep, features), episode_stats(ep, features)
    for key in a:
        for stat in a[key]:
            assert a[key][stat].dtype == b[key][stat].dtype
            np.testing.assert_array_equal(b[key][stat], a[key][stat], err_msg=f"{key}/{stat}")
