"""The simulator's tests build hand models into a cache of their own, never the user's (~/.cache/unidextok/sim)."""

import os

import pytest

CACHE_ENV = "UNIDEXTOK_SIM_CACHE"  # lerobot_env_unidextok.urdf_model.CACHE_ENV (not imported: that loads MuJoCo)


@pytest.fixture(scope="session", autouse=True)
def _sim_cache(tmp_path_factory):
    before = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(tmp_path_factory.mktemp("sim_cache"))
    yield
    if before is None:
        os.environ.pop(CACHE_ENV, None)
    else:
        os.environ[CACHE_ENV] = before
