"""`ChordPress-v0`: gymnasium's checker passes, a seeded episode is reproduced exactly, the task columns are every
hand's, the expert does it on seeded episodes, only both named fingers together succeed (one of them alone times
out, a button outside the chord fails), and a hand with two fingers besides the thumb is refused in one line."""

import gymnasium as gym
import numpy as np
import pytest
from sim_rollout import random_rollout  # tests/fixtures

import lerobot_env_unidextok  # noqa: F401  (registers the gym ids)
from lerobot_env_unidextok.chord_press import CHORD_SIZE, HOLD_STEPS
from lerobot_env_unidextok.columns import PRESS_FINGERS, TASK_COLUMNS, TASK_TEXT
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.record import expert_episode

TASK = "ChordPress-v0"
# the hands the expert is tested on (its rates over 50 episodes per hand: docs/tasks.md, bench_sim.py): both
# model files, a built hand of three fingers besides the thumb (the Allegro) and one of four (the XHand)
HANDS = ("inspire_rh56_unitree", "shadow", "allegro", "xhand1")


def _need(hand: str) -> None:
    from lerobot_env_unidextok import sim_hands

    if hand not in sim_hands.sim_hand_names():
        pytest.skip(f"{hand}'s URDF is not found (set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf)")


def _run(env: UniDexTokEnv, seed: int, chord: tuple[str, ...] | None = None, hide: str = "") -> tuple[bool, bool, list]:
    """(success, terminated, each step's task columns) of the noiseless expert on episode `seed`; `chord`: the task's
    chord changed after the expert planned (the expert presses the chord its first observation named); `hide`: a
    finger left out of the chord the expert is shown (it presses the other one alone)."""
    from lerobot_env_unidextok.experts import Expert

    obs, _ = env.reset(seed=seed)
    expert = Expert(env, np.random.default_rng(0), noise=False)
    shown = {k: v.copy() for k, v in obs.items()}
    if hide:
        shown["agent_pos"][env.state_names.index(f"chord_{hide}")] = 0.0
    expert.reset(shown)
    if chord is not None:
        env.task.chord = chord
    seen, terminated, info = [], False, {"is_success": False}
    for _ in range(50):
        obs, _, terminated, _, info = env.step(expert.act(obs))
        seen.append(dict(zip(env.state_names, obs["agent_pos"], strict=True)))
        if terminated:
            break
    return bool(info["is_success"]), bool(terminated), seen


def test_gymnasium_env_checker_passes():
    from gymnasium.utils.env_checker import check_env

    env = gym.make(f"lerobot_env_unidextok/{TASK}", hand="shadow", disable_env_checker=True)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.task_description == TASK_TEXT[TASK]


def test_a_seeded_episode_is_reproduced_exactly_and_the_columns_are_every_hands():
    a = random_rollout(UniDexTokEnv("shadow", TASK, render_mode=None), seed=7, steps=5)
    b = random_rollout(UniDexTokEnv("shadow", TASK, render_mode=None), seed=7, steps=5)
    c = random_rollout(UniDexTokEnv("shadow", TASK, render_mode=None), seed=8, steps=5)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], c[0])
    width = len(TASK_COLUMNS[TASK])
    for hand in HANDS:
        _need(hand)
        env = UniDexTokEnv(hand, TASK, render_mode=None)
        assert env.state_names[6 : 6 + width] == list(TASK_COLUMNS[TASK]), hand
        obs, _ = env.reset(seed=3)
        cols = dict(zip(env.state_names, obs["agent_pos"], strict=True))
        named = {f for f in PRESS_FINGERS if cols[f"chord_{f}"] == 1.0}
        assert named == set(env.task.chord) and len(named) == CHORD_SIZE, hand
        assert named <= set(env.task.fingers), hand  # the Allegro's chords leave out the little finger it lacks


def test_the_expert_succeeds_on_seeded_episodes():
    for hand in HANDS:
        _need(hand)
        env = UniDexTokEnv(hand, TASK, render_mode=None)
        wins = sum(expert_episode(env, 3000 + i, 4000 + i, 50)[2] for i in range(4))
        assert wins >= 3, f"{hand} {TASK}: {wins}/4"


def test_only_both_named_fingers_held_together_succeed():
    """The noiseless expert on one episode: its chord held `HOLD_STEPS` steps succeeds. The same press when the task
    names another chord puts a button outside it down (a failure that ends the episode), whether one of the pressed
    fingers is in it or neither; one of the two named fingers pressed alone runs out of time, one of two down."""
    env = UniDexTokEnv("shadow", TASK, render_mode=None)
    env.reset(seed=1004)
    pressed = env.task.chord
    assert pressed == ("index", "ring")  # a chord with the middle between its fingers, staying up

    success, terminated, seen = _run(env, 1004)
    assert success and terminated and env.task.held == HOLD_STEPS
    assert all(s["chord_index"] == 1 and s["chord_ring"] == 1 and s["chord_middle"] == 0 for s in seen)

    success, terminated, _ = _run(env, 1004, chord=("index", "middle"))  # the ring's button is not in this one
    assert not success and terminated and env.task.failure_reason(terminated) == "wrong button"

    success, terminated, _ = _run(env, 1004, chord=("middle", "little"))
    assert not success and terminated and env.task.failure_reason(terminated) == "wrong button"

    success, terminated, _ = _run(env, 1004, hide="ring")  # the index pressed alone: the ring's never down
    assert not success and not terminated
    assert env.task.failure_reason(terminated) == f"timeout (1 of {CHORD_SIZE} down together)"


def test_a_hand_with_two_fingers_besides_the_thumb_is_refused_in_one_line():
    hand = "unitree_dex3_1"
    _need(hand)
    refusal = rf"^hand '{hand}' has 2 fingers besides the thumb \(index, middle\), and {TASK} .*FingerPress-v0"
    with pytest.raises(SimInputError, match=refusal) as e:
        gym.make(f"lerobot_env_unidextok/{TASK}", hand=hand)
    assert "\n" not in str(e.value)
    # and as lerobot-eval meets it: --env.task / --env.hand are checked when its config is made, before gym.make
    with pytest.raises(SimInputError, match=refusal):
        UniDexTokEnvConfig(task=TASK, hand=hand)
