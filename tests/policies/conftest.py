"""Real G1 + Inspire episodes converted by the project's own converter, for the policy tests."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def g1_dataset(real_data_dir, tmp_path_factory) -> Path:
    """Real Unitree G1 + two Inspire hands (3 episodes) converted to UDHM by the project's converter."""
    from g1_real import convert_g1

    return convert_g1(real_data_dir, tmp_path_factory.mktemp("g1") / "ds")
