"""Real G1 + Inspire episodes converted by the project's own converter, for the policy tests."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def g1_dataset(real_data_dir, tmp_path_factory) -> Path:
    """Real Unitree G1 + two Inspire hands (3 episodes) converted to UDHM by the project's converter."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    root = tmp_path_factory.mktemp("g1") / "ds"
    hands = {
        "left": "inspire_rh56_unitree:kLeftHand",
        "right": "inspire_rh56_unitree:kRightHand",
    }
    convert(ConvertOptions(source="lerobot", input=real_data_dir / "g1-inspire", root=root, repo_id="test/g1_udhm",
                           source_options={"hands": hands}, max_episodes=3, progress=False))  # fmt: skip
    return root
