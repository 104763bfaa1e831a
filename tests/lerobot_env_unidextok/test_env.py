"""The simulator as a gymnasium env: gymnasium's own checker, seeded episodes reproduced exactly, the observation
in the hand's native units, and one clear error for each bad input."""

import gymnasium as gym
import numpy as np
import pytest

import lerobot_env_unidextok  # noqa: F401  (registers the gym ids)
from lerobot_env_unidextok import hand_model
from lerobot_env_unidextok.columns import TASK_COLUMNS, WRIST_NAMES
from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.errors import SimInputError
from lerobot_unidextok import hands

HANDS = ("inspire_rh56_unitree", "shadow", "allegro")
TASKS = ("GraspLift-v0", "FingerPress-v0")


def _rollout(env: UniDexTokEnv, seed: int, steps: int, rng_seed: int) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(rng_seed)
    states = [obs["agent_pos"]]
    for _ in range(steps):
        action = env.action_low + rng.uniform(0, 1, env.action_space.shape) * (env.action_high - env.action_low)
        obs, *_ = env.step(action.astype(np.float32))
        states.append(obs["agent_pos"])
    return np.stack(states)


def test_gymnasium_env_checker_passes():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("lerobot_env_unidextok/FingerPress-v0", hand="inspire_rh56_unitree", disable_env_checker=True)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("hand", HANDS)
def test_seeded_episodes_are_reproduced_exactly(hand):
    """Same seed, same actions: bit-identical observations in a fresh env; another seed: another episode."""
    task = "GraspLift-v0"
    a = _rollout(UniDexTokEnv(hand, task, render_mode=None), seed=7, steps=6, rng_seed=0)
    b = _rollout(UniDexTokEnv(hand, task, render_mode=None), seed=7, steps=6, rng_seed=0)
    c = _rollout(UniDexTokEnv(hand, task, render_mode=None), seed=8, steps=6, rng_seed=0)
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
    with pytest.raises(SimInputError, match="hand 'leap' .*has no simulation model.*runs: .*shadow"):
        UniDexTokEnv("leap", "GraspLift-v0")
    with pytest.raises(SimInputError, match="unknown task 'Fly-v0'"):
        UniDexTokEnv("shadow", "Fly-v0")
    env = UniDexTokEnv("allegro", "GraspLift-v0", render_mode=None)
    env.reset(seed=0)
    with pytest.raises(SimInputError, match="12 values, but this env's hand 'allegro' takes 22.*unidextok-deploy"):
        env.step(np.zeros(12, dtype=np.float32))


def test_every_shipped_model_loads_for_every_hand_spec_of_its_embodiment():
    runs = hand_model.sim_hand_names()
    assert {"inspire_rh56_unitree", "inspire_rh56", "shadow", "allegro"} <= set(runs)
    for name in runs:
        sim = hand_model.load(name)
        assert [d.native for d in sim.measuring] == list(sim.native_names)
        assert sim.posture("open").shape == (sim.spec.num_native,)
