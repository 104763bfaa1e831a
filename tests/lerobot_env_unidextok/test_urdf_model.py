"""The URDF -> MJCF builder and the hands it derives, checked against the robots' URDFs in ../shared/data/urdf (the
tests skip without them, except the shipped Allegro's and the error for a spec without a URDF).

- The builder on three URDFs: the LEAP's (collision boxes, kept) and the XHand's and LinkerHand L10's (meshes
  only: capsules along the links, a palm box; the L10's mimic joints as equality constraints).
- Forward kinematics of the built model, posed by the drives from native commands, agrees with the URDF's own
  (yourdfpy, mimic followers from their tags) at the fingertips within 1 mm.
- Every shipped model is what the builder makes from its URDF, byte for byte, with its licence beside it, and runs
  without the URDF; built models are cached, and a damaged cache heals with one warning naming the file.
- A URDF the builder cannot read is one error naming the file and the joint.
"""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from lerobot_env_unidextok import sim_hands, urdf_model
from lerobot_env_unidextok.errors import SimBuildError, SimHandError
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
    sim = sim_hands.load(hand)
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


# every hand whose URDF's licence permits shipping its built model (../shared/data/urdf/README.md)
SHIPPED = ("allegro", "brainco_revo1", "leap", "linkerhand_l10", "linkerhand_l20", "linkerhand_l21", "linkerhand_l25",
           "linkerhand_o7", "unitree_dex3_1", "xhand1")  # fmt: skip


def test_the_shipped_hands_are_those_with_a_permissive_licence_each_beside_its_model():
    shipped = tuple(n for n in hands.names() if urdf_model.shipped_path(hands.get(n)) is not None)
    assert shipped == SHIPPED
    for name in shipped:
        folder = urdf_model.shipped_path(hands.get(name)).parent
        (licence,) = folder.glob("LICENSE*")
        text = licence.read_text()
        assert "Permission is hereby granted" in text or "Apache License" in text or "Redistribution and use" in text


@pytest.mark.parametrize("hand", SHIPPED)
def test_a_shipped_model_is_what_the_builder_makes(hand):
    need_urdfs()
    spec = hands.get(hand)
    built = urdf_model.build_mjcf(urdf_model.urdf_path(spec).read_text(), spec)
    assert built == urdf_model.shipped_path(spec).read_text()  # rebuild: tools/sim/build_hand.py --shipped


def test_the_shipped_hands_run_without_the_urdf_and_the_urdf_dir_rebuilds_them(monkeypatch, tmp_path):
    monkeypatch.setenv(URDF_DIR_ENV, str(tmp_path / "no_urdfs"))
    assert set(SHIPPED) | {"shadow", "inspire_rh56_unitree"} <= set(sim_hands.sim_hand_names())
    for hand in SHIPPED:
        assert urdf_model.model_xml(hands.get(hand)) == urdf_model.shipped_path(hands.get(hand)).read_text()
    assert not (tmp_path / "cache").exists()  # nothing built
    need_urdfs()
    monkeypatch.setenv(URDF_DIR_ENV, str(URDF_DIR))
    urdf_model.model_xml(hands.get("leap"))
    assert len(list((tmp_path / "cache").glob("leap_right_*.xml"))) == 1  # with the URDF folder set: built


def test_built_models_are_cached_outside_the_repository(tmp_path):
    need_urdfs()
    spec = hands.get("xhand1")
    first = urdf_model.model_xml(spec)
    cached = list((tmp_path / "cache").glob("xhand1_right_*.xml"))
    assert len(cached) == 1 and urdf_model.read_cached(cached[0]) == (first, None)
    before = cached[0].stat().st_mtime_ns
    assert urdf_model.model_xml(spec) == first and cached[0].stat().st_mtime_ns == before  # read, not rebuilt


@pytest.mark.parametrize(("damage", "said"), [
    (lambda text: text[: len(text) // 2], "cut short or edited"),
    (lambda text: "", "not a model this builder wrote"),
    (lambda text: "\x00garbage\xff" * 50, "not a model this builder wrote"),
    (lambda text: text.replace('armature="0.002"', 'armature="0.2"', 1), "cut short or edited"),  # valid, hand-edited
])  # fmt: skip
def test_a_damaged_cached_model_is_rebuilt_with_one_warning_naming_it(tmp_path, caplog, damage, said):
    need_urdfs()
    spec = hands.get("xhand1")
    first = urdf_model.model_xml(spec)
    (cached,) = (tmp_path / "cache").glob("xhand1_right_*.xml")
    cached.write_text(damage(cached.read_text()))
    with caplog.at_level("WARNING", logger="lerobot_env_unidextok.urdf_model"):
        assert urdf_model.model_xml(spec) == first
    (warning,) = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert str(cached) in warning and said in warning, warning
    assert urdf_model.read_cached(cached) == (first, None)  # healed on disk too


def _urdf(tmp_path: Path, hand: str, edit) -> None:
    """A copy of the hand's URDF folder layout under tmp_path/urdfs, the file edited by `edit`."""
    spec = hands.get(hand)
    path = tmp_path / "urdfs" / spec.urdf.files["right"]
    path.parent.mkdir(parents=True)
    path.write_text(edit((URDF_DIR / spec.urdf.files["right"]).read_text()))


@pytest.mark.parametrize(("edit", "said"), [
    (lambda t: t[: len(t) // 2], r"linkerhand_l10_right.urdf is not a readable URDF \(.*\): is the file cut short"),
    (lambda t: t.replace('<parent link="index_proximal" />', '<parent link="no_such_link" />', 1),
     r"linkerhand_l10_right.urdf: joint '\w+' names parent link 'no_such_link', which the file does not have"),
    (lambda t: t.replace('lower="0"', 'lower="nan"', 1),
     r"linkerhand_l10_right.urdf: joint '\w+' has limits \[nan, .*\] rad; a built joint needs finite limits"),
    (lambda t: t.replace('lower="0"', 'lower="zero"', 1), r"joint '\w+' has limits 'zero', .*not numbers"),
    (lambda t: t.replace("<robot", "<robat", 1).replace("</robot>", "</robat>"), r"its root element is <robat>"),
    (lambda t: t.replace('type="revolute"', 'type="continuous"', 1), r"joint '\w+' has no limits \(a continuous"),
    (lambda t: t.replace('type="revolute"', 'type="bogus"', 1), r"joint '\w+' has type 'bogus'; a URDF joint is one"),
])  # fmt: skip
def test_a_urdf_that_cannot_be_built_is_one_error_naming_the_file_and_joint(monkeypatch, tmp_path, edit, said):
    need_urdfs()
    _urdf(tmp_path, "linkerhand_l10", edit)
    monkeypatch.setenv(URDF_DIR_ENV, str(tmp_path / "urdfs"))
    with pytest.raises(SimBuildError, match=said) as err:
        urdf_model.model_xml(hands.get("linkerhand_l10"))
    assert "\n" not in str(err.value)


def test_the_record_cli_says_a_broken_urdf_in_one_line(tmp_path):
    """From the command line: one `error:` line naming the file and the joint, exit 2, no traceback, no dataset."""
    import subprocess
    import sys

    from linkerhand_udhm import subprocess_env

    need_urdfs()
    _urdf(tmp_path, "linkerhand_l10", lambda t: t.replace('lower="0"', 'lower="nan"', 1))
    env = subprocess_env(MUJOCO_GL="disable", UNIDEXTOK_URDF_DIR=str(tmp_path / "urdfs"),
                         UNIDEXTOK_SIM_CACHE=str(tmp_path / "cache"))  # fmt: skip
    r = subprocess.run([str(Path(sys.executable).parent / "unidextok-sim-record"), "--hand=linkerhand_l10",
                        "--episodes=1", f"--root={tmp_path / 'out'}"], env=env, cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "linkerhand_l10_right.urdf: joint" in errors[0] and "nan" in errors[0]
    assert not (tmp_path / "out").exists()


def test_a_spec_without_a_urdf_is_one_clear_error(monkeypatch, tmp_path):
    with pytest.raises(SimHandError, match=r"hand 'linkerhand_l6' cannot be simulated: its spec maps no URDF.*"
                                           r"the simulator runs: .*allegro.*shadow") as err:  # fmt: skip
        sim_hands.load("linkerhand_l6")
    assert "\n" not in str(err.value)
    monkeypatch.setenv(URDF_DIR_ENV, str(tmp_path / "no_urdfs"))
    with pytest.raises(SimHandError, match=r"hand 'oymotion_rohand' cannot be simulated: its URDF "
                                           r"rohand_urdf_ros2/.*is not under .*no_urdfs and no built model of it "
                                           r"ships \(set UNIDEXTOK_URDF_DIR"):  # fmt: skip
        sim_hands.load("oymotion_rohand")
