"""The simulator as a gymnasium env: gymnasium's own checker, seeded episodes reproduced exactly, the observation
in the hand's native units, and one clear error for each bad input."""

import gymnasium as gym
import numpy as np
import pytest
from sim_rollout import random_rollout  # tests/fixtures

import lerobot_env_unidextok  # noqa: F401  (registers the gym ids)
from lerobot_env_unidextok import hand_model, sim_hands
from lerobot_env_unidextok.columns import TASK_COLUMNS, WRIST_NAMES
from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.gl import mujoco
from lerobot_unidextok import hands

HANDS = ("inspire_rh56_unitree", "shadow", "allegro")
TASKS = ("GraspLift-v0", "FingerPress-v0")


def test_gymnasium_env_checker_passes():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("lerobot_env_unidextok/FingerPress-v0", hand="inspire_rh56_unitree", disable_env_checker=True)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("hand", HANDS)
def test_seeded_episodes_are_reproduced_exactly(hand):
    """Same seed, same actions: bit-identical observations in a fresh env; another seed: another episode."""
    task = "GraspLift-v0"
    a = random_rollout(UniDexTokEnv(hand, task, render_mode=None), seed=7, steps=6, rng_seed=0)
    b = random_rollout(UniDexTokEnv(hand, task, render_mode=None), seed=7, steps=6, rng_seed=0)
    c = random_rollout(UniDexTokEnv(hand, task, render_mode=None), seed=8, steps=6, rng_seed=0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("task", TASKS)
def test_observation_layout_and_native_units(task):
    """agent_pos = wrist pose, the task's columns, the hand's native joints in its spec's units: the Inspire's
    six Unitree values in [0, 1], 1 = open at the start; the action takes the wrist and those six."""
    env = UniDexTokEnv("inspire_rh56_unitree", task, render_mode=None)
    obs, info = env.reset(seed=0)
    spec = hands.get("inspire_rh56_unitree")
    assert env.state_names[:6] == list(WRIST_NAMES)
    assert env.state_names[6 : 6 + len(TASK_COLUMNS[task])] == list(TASK_COLUMNS[task])
    assert env.state_names[-6:] == [f"right_{n}" for n in spec.joint_names]
    native = obs["agent_pos"][-6:]
    assert np.all((native >= 0) & (native <= 1)) and native.min() > 0.95  # open
    assert env.action_space.shape == (12,) and obs["state_is_native"].tolist() == [1.0]
    assert info == {"is_success": False}


def test_the_simulator_reads_back_what_the_hand_was_commanded():
    """A native command held for 1.5 s is read back as that native state (free space, within the model's
    tracking error): the drives' maps and their inverse agree, per hand."""
    for hand in HANDS:
        env = UniDexTokEnv(hand, "GraspLift-v0", render_mode=None)
        obs, _ = env.reset(seed=0)
        sim = env.hand
        command = sim.posture("press_index")
        wrist = obs["agent_pos"][:6].copy()
        wrist[2] = 0.3  # up, away from the table
        for _ in range(15):  # the Inspire's drives settle in about 0.5 s per e-fold (kp 2, damping 1)
            obs, *_ = env.step(np.concatenate([wrist, command]).astype(np.float32))
        measured = obs["agent_pos"][-len(command) :]
        actuated = {d.native for d in sim.drives if d.actuator}
        cols = [i for i, n in enumerate(sim.native_names) if n in actuated]
        span = np.ptp(np.asarray(sim.spec.raw_range("right"), dtype=float), axis=1)
        assert np.abs(measured[cols] - command[cols]).max() / span[cols].min() < 0.06, hand


def test_bad_input_is_one_clear_error():
    with pytest.raises(SimInputError, match="unknown hand 'mystery'.*runs: .*allegro"):
        UniDexTokEnv("mystery", "GraspLift-v0")
    with pytest.raises(SimInputError, match="'linkerhand_l6' cannot be simulated: its spec maps no URDF.*runs: .*shadow"):
        UniDexTokEnv("linkerhand_l6", "GraspLift-v0")
    with pytest.raises(SimInputError, match="unknown task 'Fly-v0'"):
        UniDexTokEnv("shadow", "Fly-v0")
    env = UniDexTokEnv("allegro", "GraspLift-v0", render_mode=None)
    env.reset(seed=0)
    with pytest.raises(SimInputError, match="12 values, but this env's hand 'allegro' takes 22.*unidextok-deploy"):
        env.step(np.zeros(12, dtype=np.float32))


def test_every_shipped_model_loads_for_every_hand_spec_of_its_embodiment():
    runs = sim_hands.sim_hand_names()
    assert {"inspire_rh56_unitree", "inspire_rh56", "shadow", "allegro"} <= set(runs)
    for name in runs:
        sim = sim_hands.load(name)
        read = [n for n, d in zip(sim.native_names, sim.measuring, strict=True) if d is not None]
        assert [d.native for d in sim.measuring if d is not None] == read
        if sim.spec.embodiment in hand_model.model_names():  # a model file measures every native joint
            assert read == list(sim.native_names)
        else:  # a built model: every native joint but reserved channels (no radians: the L20's 11-14)
            assert {n for n in sim.native_names if n not in read} == {
                j.name for j in sim.spec.joints if j.sides["right"].scale == 0}
        assert sim.posture("open").shape == (sim.spec.num_native,)


# hands whose models the simulator builds from their URDFs (../shared/data/urdf or $UNIDEXTOK_URDF_DIR)
BUILT_HANDS = ("leap", "xhand1", "linkerhand_l10", "linkerhand_l20", "linkerhand_l21", "linkerhand_l25",
               "linkerhand_o7", "brainco_revo1", "unitree_dex3_1")  # fmt: skip


def _need(hand: str) -> None:
    if hand not in sim_hands.sim_hand_names():
        pytest.skip(f"{hand}'s URDF is not found (set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf)")


@pytest.mark.parametrize("hand", BUILT_HANDS)
def test_a_built_hand_passes_the_env_checker_and_reproduces_its_episodes(hand):
    from gymnasium.utils.env_checker import check_env

    _need(hand)
    check_env(UniDexTokEnv(hand, "FingerPress-v0", render_mode=None), skip_render_check=True)
    a = random_rollout(UniDexTokEnv(hand, "GraspLift-v0", render_mode=None), seed=7, steps=4, rng_seed=0)
    b = random_rollout(UniDexTokEnv(hand, "GraspLift-v0", render_mode=None), seed=7, steps=4, rng_seed=0)
    np.testing.assert_array_equal(a, b)
    spec = hands.get(hand)
    assert a.shape[1] == 6 + len(TASK_COLUMNS["GraspLift-v0"]) + spec.num_native
    lo, hi = np.asarray(spec.raw_range("right"), dtype=np.float32).T
    assert np.all((a[:, -spec.num_native :] >= lo - 1e-4) & (a[:, -spec.num_native :] <= hi + 1e-4))


@pytest.mark.parametrize("hand", HANDS)
def test_fingertips_are_the_tips_from_the_grasp_centre_in_one_space_for_every_hand(hand):
    """`fingertips=True` adds the same 15 columns for every hand, after the task's, and changes nothing else; they
    are each tip's place from the grasp centre (m): far at the open start, and at the power grasp (in free space)
    their mean is the grasp centre itself; a finger the hand lacks (the Allegro's little finger) takes its nearest
    finger's tip (the ring's)."""
    from lerobot_env_unidextok.columns import FINGERS, FINGERTIP_COLUMNS

    task = "GraspLift-v0"
    plain, tips = UniDexTokEnv(hand, task, render_mode=None), UniDexTokEnv(hand, task, render_mode=None, fingertips=True)
    at = 6 + len(TASK_COLUMNS[task])
    assert tips.state_names == [*plain.state_names[:at], *FINGERTIP_COLUMNS, *plain.state_names[at:]]
    assert tips.observation_space["agent_pos"].shape == (len(plain.state_names) + 15,)
    a, _ = plain.reset(seed=3)
    b, _ = tips.reset(seed=3)
    np.testing.assert_array_equal(np.delete(b["agent_pos"], range(at, at + 15)), a["agent_pos"])
    open_m = b["agent_pos"][at : at + 15].reshape(5, 3)
    present = np.array([f in tips.hand.fingers for f in FINGERS])
    assert np.linalg.norm(open_m[present], axis=1).min() > 0.03
    if hand == "allegro":  # four fingers: the little finger's columns hold the ring's tip
        assert not present[4] and np.array_equal(open_m[4], open_m[3])
    else:
        assert present.all() and len({tuple(t) for t in open_m}) == 5
    # the hand put at its power posture: the tips' centroid is the grasp centre (its definition, grasp_centre.py)
    tips.scene.place_hand(tips.data, tips.hand.posture("power"))
    mujoco.mj_kinematics(tips.model, tips.data)
    np.testing.assert_allclose(tips._obs()["agent_pos"][at : at + 15].reshape(5, 3)[present].mean(0), 0, atol=1e-6)
    # the power grasp commanded in free space, the wrist still: every tip comes closer to the centre
    tips.reset(seed=3)
    for _ in range(15):
        obs, *_ = tips.step(np.concatenate([b["agent_pos"][:6], tips.hand.posture("power")]).astype(np.float32))
    closed_m = obs["agent_pos"][at : at + 15].reshape(5, 3)[present]
    assert np.all(np.linalg.norm(closed_m, axis=1) < np.linalg.norm(open_m[present], axis=1))


def test_a_finger_the_hand_lacks_takes_its_nearest_fingers_tip():
    from lerobot_env_unidextok.columns import FINGERS, tip_sources

    assert tip_sources(FINGERS) == FINGERS
    assert tip_sources(("thumb", "index", "middle", "ring")) == ("thumb", "index", "middle", "ring", "ring")
    assert tip_sources(("thumb", "index", "middle")) == ("thumb", "index", "middle", "middle", "middle")
    assert tip_sources(("thumb", "index", "ring", "little")) == ("thumb", "index", "index", "ring", "little")
    with pytest.raises(ValueError, match="a finger besides the thumb"):
        tip_sources(("thumb",))
