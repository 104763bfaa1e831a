"""A tiny experiment configuration in a temp dir, shared by the experiment tests (one data + model cache)."""

import pytest

from lerobot_unidextok.experiments import ExperimentConfig


@pytest.fixture(scope="session")
def tiny_cfg(tmp_path_factory) -> ExperimentConfig:
    root = tmp_path_factory.mktemp("experiments")
    return ExperimentConfig.from_preset(
        "tiny",
        output_root=str(root / "out"),
        data_dir=str(root / "_data"),
        models_dir=str(root / "_models"),
        linkerhand_presets=str(root / "absent.json"),
    )


@pytest.fixture(scope="session")
def main_result(tiny_cfg):
    from lerobot_unidextok.experiments import main_table

    return main_table.run(tiny_cfg)


@pytest.fixture(scope="session", autouse=True)
def one_torch_thread():
    """As the experiment CLIs do: extra intra-op threads are ~10x slower on shared cores."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
