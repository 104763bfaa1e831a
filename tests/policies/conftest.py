"""Real G1 + Inspire episodes converted by the project's own converter, for the policy tests."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def g1_dataset(real_data_dir, tmp_path_factory) -> Path:
    """Real Unitree G1 + two Inspire hands (3 episodes) converted to UDHM by the project's converter."""
    from g1_real import convert_g1

    return convert_g1(real_data_dir, tmp_path_factory.mktemp("g1") / "ds")


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    """A tiny untrained tokenizer knowing the human hand, the L10 and the Inspire (the pooling tests' mixes)."""
    import torch
    from l10_robot import HAND as L10
    from robot_udhm import INSPIRE

    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    torch.manual_seed(2)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", L10, INSPIRE])).save_pretrained(path)
    return path
