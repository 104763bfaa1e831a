"""Fixtures shared with tests/fixtures/linkerhand_udhm.py (real LinkerHand L10 presets as UDHM)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))

from linkerhand_udhm import l10_preset_states, write_l10_dataset


@pytest.fixture(scope="session")
def l10_states(real_data_dir):
    """(P, 44) float32 UDHM radians of real two-hand L10 preset poses."""
    return l10_preset_states(real_data_dir)


@pytest.fixture(scope="session")
def l10_dataset(real_data_dir, tmp_path_factory) -> Path:
    """A LeRobotDataset v3.0 folder following the converted-dataset contract."""
    return write_l10_dataset(tmp_path_factory.mktemp("l10") / "ds", real_data_dir)
