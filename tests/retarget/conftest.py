"""Retargeting tests read the robot URDFs in ../shared/data/urdf (users supply their own) and skip without them."""

import pytest


@pytest.fixture(scope="session")
def urdf_dir(real_data_dir):
    folder = real_data_dir.parent / "urdf"
    if not folder.is_dir():
        pytest.skip(f"robot URDFs not found at {folder} (../shared/data/urdf)")
    pytest.importorskip("dex_retargeting", reason="the retarget extra (dex-retargeting) is not installed")
    return folder


@pytest.fixture(scope="session")
def human_clip(real_data_dir):
    """(T, 21, 3) m: the real right-hand MediaPipe clip (dex-retargeting's example), MANO wrist frame."""
    import numpy as np

    return np.load(real_data_dir / "dex-retargeting" / "human_joint_right.npy")  # listed in REAL_DATA_FILES
