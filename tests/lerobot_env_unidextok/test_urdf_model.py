"""The URDF -> MJCF builder and the hands it derives, checked against the robots' URDFs in ../shared/data/urdf (the
tests skip without them, except the shipped Allegro's and the error for a spec without a URDF).

- The builder on three URDFs: the LEAP's (collision boxes, kept) and the XHand's and LinkerHand L10's (meshes
  only: capsules along the links, a palm box; the L10's mimic joints as equality constraints).
- Forward kinematics of the built model, posed by the drives from native commands, agrees with the URDF's own
  (yourdfpy, mimic followers from their tags) at the fingertips within 1 mm.
- The shipped Allegro model is what the builder makes from dex-urdf's file, byte for byte; built models are cached.
"""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from lerobot_env_unidextok import hand_model, urdf_model
from lerobot_env_unidextok.hand_model import SimHandError
from lerobot_env_unidextok.urdf_hand import HandFK, set_mimic_followers
from lerobot_unidextok import hands
from lerobot_unidextok.utils.shared_data import URDF_DIR_ENV
from lerobot_unidextok.utils.shared_data import urdf_dir as shared_urdf_dir

REPO = Path(__file__).resolve().parents[2]
URDF_DIR = shared_urdf_dir(REPO)
TIPS = (4, 8, 12, 16, 20)  # MANO-21 fingertips


@pytest.fixture(autouse=True)
def _urdfs(monkeypatch, tmp_path):
    """The checkout's URDF folder whatever the cwd, and a cache of the test's own."""
    if URDF_DIR.is_dir():
        monkeypatch.setenv(URDF_DIR_ENV, str(URDF_DIR))
    monkeypatch.setenv(urdf_model.CACHE_ENV, str(tmp_path / "cache"))


def need_urdfs() -> None:
    if not URDF_DIR.is_dir():
        pytest.skip(f"robot URDFs not found at {URDF_DIR}; set {URDF_DIR_ENV} to a copy of shared/data/urdf")


def _built(hand: str) -> tuple[hands.HandSpec, mujoco.MjModel]:
    need_urdfs()
    spec = hands.get(hand)
    xml = urdf_model.build_mjcf(urdf_model.urdf_path(spec).read_text(), spec)
    return spec, mujoco.MjModel.from_xml_string(xml)


def _geoms(model: mujoco.MjModel, body: str, kind: mujoco.mjtGeom) -> int:
    return int(np.sum((model.geom_bodyid == model.body(body).id) & (model.geom_type == int(kind))))


def test_primitives_are_kept_and_every_joint_has_its_limits_and_one_actuator():
    spec, model = _built("leap")
    assert model.njnt == 16 and model.nu == 16 and model.neq == 0
    assert _geoms(model, "base", mujoco.mjtGeom.mjGEOM_BOX) > 0
    assert _geoms(model, "base", mujoco.mjtGeom.mjGEOM_CAPSULE) == 0
    assert _geoms(model, "fingertip", mujoco.mjtGeom.mjGEOM_CAPSULE) == 1  # its soft tip is a mesh: a capsule
    j = model.joint("1").id
    np.testing.assert_allclose(model.jnt_range[j], [-0.314, 2.23])
    a = model.actuator("1_drive").id
    np.testing.assert_allclose(model.actuator_ctrlrange[a], [-0.314, 2.23])
    assert model.body_mass[model.body("mcp_joint").id] == pytest.approx(0.044, abs=1e-3)  # the URDF's inertial


@pytest.mark.parametrize(("hand", "palm", "link", "followers"), [
    ("xhand1", "right_hand_link", "right_hand_index_rota_link1", 0),
    ("linkerhand_l10", "hand_base_link", "index_proximal", 10),
])  # fmt: skip
def test_mesh_only_links_get_capsules_to_their_child_and_the_palm_a_box(hand, palm, link, followers):
    spec, model = _built(hand)
    assert model.neq == followers  # mimic joints: MuJoCo's joint equalities, no actuator of their own
    assert model.nu == model.njnt - followers
    assert _geoms(model, palm, mujoco.mjtGeom.mjGEOM_BOX) == 1
    body = model.body(link).id
    capsule = np.flatnonzero((model.geom_bodyid == body) & (model.geom_type == int(mujoco.mjtGeom.mjGEOM_CAPSULE)))
    child = int(np.flatnonzero(model.body_parentid == body)[0])
    assert len(capsule) == 1  # from the link's origin to its child's, so centred halfway
    np.testing.assert_allclose(model.geom_pos[capsule[0]], model.body_pos[child] / 2, atol=1e-6)
    assert 0.006 <= model.geom_size[capsule[0], 0] <= 0.012
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon == 0  # at the zero pose nothing of the hand touches (excluded or apart)


@pytest.mark.parametrize("hand", ["leap", "xhand1", "linkerhand_l10", "allegro"])
def test_built_fingertips_follow_the_urdf_within_a_millimetre(hand):
    """Native commands (open, power, pinch and two seeded random ones) -> the drives' joint angles -> the built
    model's tips, against yourdfpy's FK of the URDF at the same independent joints (mimics from their tags)."""
    pytest.importorskip("yourdfpy")
    from lerobot_unidextok.hands.urdf import UrdfHand

    need_urdfs()
    sim = hand_model.load(hand)
    spec = sim.spec
    urdf = UrdfHand.load(urdf_model.urdf_path(spec), spec.urdf.keypoints["right"])
    fk = HandFK(sim)
    lo, hi = np.asarray(spec.raw_range("right"), dtype=float).T
    rng = np.random.default_rng(0)
    commands = [sim.posture("open"), sim.posture("power"), sim.posture("pinch"), *rng.uniform(lo, hi, (2, len(lo)))]
    for raw in commands:
        fk.pose(raw)
        built = np.stack([fk.data.xpos[fk.model.body(spec.urdf.keypoints["right"][k].link).id]
                          + fk.data.xmat[fk.model.body(spec.urdf.keypoints["right"][k].link).id].reshape(3, 3)
                          @ np.asarray(spec.urdf.keypoints["right"][k].offset_m) for k in TIPS])  # fmt: skip
        cfg = {name: float(fk.data.qpos[fk.model.jnt_qposadr[fk.model.joint(name).id]]) for name in urdf.joint_names}
        reference = urdf.keypoints_m([cfg])[0, list(TIPS)]
        assert np.abs(built - reference).max() < 1e-3, (hand, np.abs(built - reference).max())


def test_mimic_followers_are_set_from_their_leaders():
    spec, model = _built("linkerhand_l10")
    data = mujoco.MjData(model)
    data.qpos[model.jnt_qposadr[model.joint("index_mcp_pitch").id]] = 1.0
    set_mimic_followers(model, data)
    pip = data.qpos[model.jnt_qposadr[model.joint("index_pip").id]]
    assert pip == pytest.approx(1.18, abs=0.02)  # the URDF's mimic ratio (the spec's `coupled:` note)


def test_the_shipped_allegro_model_is_what_the_builder_makes():
    need_urdfs()
    spec = hands.get("allegro")
    built = urdf_model.build_mjcf(urdf_model.urdf_path(spec).read_text(), spec)
    assert built == urdf_model.shipped_path(spec).read_text()  # rebuild: tools/sim/build_hand.py --hand allegro


def test_the_shipped_allegro_runs_without_the_urdf(monkeypatch, tmp_path):
    monkeypatch.setenv(URDF_DIR_ENV, str(tmp_path / "no_urdfs"))
    assert {"allegro", "shadow", "inspire_rh56_unitree"} <= set(hand_model.sim_hand_names())
    xml = urdf_model.model_xml(hands.get("allegro"))
    assert xml == urdf_model.shipped_path(hands.get("allegro")).read_text()


def test_built_models_are_cached_outside_the_repository(tmp_path):
    need_urdfs()
    spec = hands.get("xhand1")
    first = urdf_model.model_xml(spec)
    cached = list((tmp_path / "cache").glob("xhand1_right_*.xml"))
    assert len(cached) == 1 and cached[0].read_text() == first
    cached[0].write_text(first + "<!-- read back -->")
    assert urdf_model.model_xml(spec).endswith("<!-- read back -->")  # the cache is what is read


def test_a_spec_without_a_urdf_is_one_clear_error(monkeypatch, tmp_path):
    with pytest.raises(SimHandError, match=r"hand 'linkerhand_l6' cannot be simulated: its spec maps no URDF.*"
                                           r"the simulator runs: .*allegro.*shadow") as err:  # fmt: skip
        hand_model.load("linkerhand_l6")
    assert "\n" not in str(err.value)
    monkeypatch.setenv(URDF_DIR_ENV, str(tmp_path / "no_urdfs"))
    with pytest.raises(SimHandError, match=r"hand 'leap' cannot be simulated: its URDF dex-urdf/leap_hand_right.urdf "
                                           r"is not under .*no_urdfs \(set UNIDEXTOK_URDF_DIR"):  # fmt: skip
        hand_model.load("leap")
