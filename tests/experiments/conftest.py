"""A tiny experiment configuration in a temp dir, shared by the experiment tests (one data + model cache), and a
converted synthetic G1 sample for the experiments that take one converted dataset."""

from pathlib import Path

import pytest

from experiments import ExperimentConfig


@pytest.fixture(scope="session")
def tiny_cfg(tmp_path_factory) -> ExperimentConfig:
    """The tiny preset on the SYNTHETIC sample (explicitly: the default would pick the real recordings), with
    no real files and no URDFs, so these tests run the same with or without ../shared."""
    root = tmp_path_factory.mktemp("experiments")
    return ExperimentConfig.from_preset(
        "tiny",
        data="sample",
        output_root=str(root / "out"),
        data_dir=str(root / "_data"),
        models_dir=str(root / "_models"),
        real_data_dir=str(root / "no_real_data"),
        urdf_dir=str(root / "no_urdfs"),
    )


@pytest.fixture(scope="session")
def real_cfg(tmp_path_factory, real_data_dir) -> ExperimentConfig:
    """The tiny preset on the real recordings (G1 Inspire, the real human clip retargeted onto three hands)."""
    pytest.importorskip("dex_retargeting", reason="the retarget extra (dex-retargeting) is not installed")
    if not (real_data_dir.parent / "urdf").is_dir():
        pytest.skip("robot URDFs (../shared/data/urdf) absent")
    root = tmp_path_factory.mktemp("experiments_real")
    return ExperimentConfig.from_preset(
        "tiny",
        data="real",
        real_data_dir=str(real_data_dir),
        retarget_hands=["linkerhand_l10", "linkerhand_l20", "inspire_rh56_unitree"],
        with_qae=False,
        output_root=str(root / "out"),
        data_dir=str(root / "_data"),
        models_dir=str(root / "_models"),
    )


@pytest.fixture(scope="session")
def main_result(tiny_cfg):
    from experiments import main_table

    return main_table.run(tiny_cfg)


@pytest.fixture(scope="session", autouse=True)
def one_torch_thread():
    """As the experiment CLIs do: extra intra-op threads are ~10x slower on shared cores."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="session")
def converted_g1(tmp_path_factory) -> Path:
    """The synthetic G1 + Inspire sample (the shipped checkpoint's hand), 5 episodes: 4 train, 1 test."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

    raw = write_samples(tmp_path_factory.mktemp("raw"), sources=["lerobot"], episodes_per_source=5,
                        frames_per_episode=40)["lerobot"]  # fmt: skip
    root = tmp_path_factory.mktemp("conv") / "g1"
    convert(ConvertOptions(source="lerobot", input=raw, root=root, progress=False,
                           source_options=SAMPLE_SOURCE_OPTIONS["lerobot"]))
    return root
