"""The simulator's hand models as data, checked against the robots' URDFs in ../shared/data/urdf (skips without).
(The models built from URDFs, the Allegro's among them: test_urdf_model.py.)

- Every Shadow drive turns its MJCF joint the way the spec's URDF joint turns (gymnasium-robotics numbers the
  joints one lower, and four of its axes point the other way: the drives flip those).
"""

import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from lerobot_env_unidextok import sim_hands
from lerobot_env_unidextok.scene import Scene, base_spec
from lerobot_unidextok.utils.shared_data import urdf_dir as shared_urdf_dir

REPO = Path(__file__).resolve().parents[2]
URDF_DIR = shared_urdf_dir(REPO)


@pytest.fixture(scope="module")
def urdf_dir() -> Path:
    if not URDF_DIR.is_dir():
        pytest.skip(f"robot URDFs not found at {URDF_DIR}; set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf")
    return URDF_DIR


def _joint_axes(model: mujoco.MjModel, palm: str, names: list[str]) -> dict[str, np.ndarray]:
    """Each joint's axis in the palm's frame at the zero pose."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rot = data.xmat[model.body(palm).id].reshape(3, 3)
    return {n: rot.T @ data.xaxis[model.joint(n).id] for n in names}


def test_shadow_drives_turn_as_the_urdf_joints(urdf_dir):
    urdf = (urdf_dir / "dex-urdf/shadow_hand_right.urdf").read_text()
    urdf = re.sub(r"<(visual|collision)>.*?</\1>", "", urdf, flags=re.S)  # kinematics only (no meshes here)
    reference = mujoco.MjModel.from_xml_string(urdf)
    hand = sim_hands.load("shadow")
    scene = Scene.compile(base_spec(hand), hand)
    sim_axes = _joint_axes(scene.model, "hand/robot0:palm", [f"hand/{d.joint}" for d in hand.drives])
    urdf_axes = _joint_axes(reference, "palm", list(hand.native_names))
    flipped = []
    for d in hand.drives:
        dot = float(sim_axes[f"hand/{d.joint}"] @ urdf_axes[d.native])
        slope = np.sign((d.joint_rad[1] - d.joint_rad[0]) / (d.native_rad[1] - d.native_rad[0]))
        assert abs(abs(dot) - 1) < 1e-4 and np.sign(dot) == slope, (d.joint, d.native, dot)
        flipped += [d.native] if slope < 0 else []
    assert flipped == ["FFJ4", "MFJ4", "THJ2", "THJ1"]
