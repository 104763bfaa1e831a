"""A tiny experiment configuration in a temp dir, shared by the experiment tests (one data + model cache)."""

import pytest

from lerobot_unidextok.experiments import ExperimentConfig


@pytest.fixture(scope="session")
def tiny_cfg(tmp_path_factory) -> ExperimentConfig:
    root = tmp_path_factory.mktemp("experiments")
    return ExperimentConfig.from_preset(
        "tiny", output_root=str(root / "out"), data_dir=str(root / "_data"), models_dir=str(root / "_models"),
        linkerhand_presets=str(root / "absent.json"),
    )


@pytest.fixture(scope="session")
def main_result(tiny_cfg):
    from lerobot_unidextok.experiments import main_table

    return main_table.run(tiny_cfg)
