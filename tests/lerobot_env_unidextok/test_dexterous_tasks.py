"""The dexterous tasks after GraspLift and FingerPress (issue 56; ChordPress-v0: test_chord_press.py): each passes gymnasium's checker, reproduces a
seeded episode exactly, has the same task columns for every hand, is done by its scripted expert on seeded
episodes, and refuses a hand that cannot do it at `gym.make` in one line."""

import gymnasium as gym
import numpy as np
import pytest
from sim_rollout import random_rollout  # tests/fixtures

import lerobot_env_unidextok  # noqa: F401  (registers the gym ids)
from lerobot_env_unidextok.columns import TASK_COLUMNS, TASK_TEXT
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
from lerobot_env_unidextok.env import UniDexTokEnv
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.record import expert_episode

# task -> hands its fast tests run on (the rates over 50 episodes per hand: docs/tasks.md, bench_sim.py)
TASK_HANDS = {
    "FingerSequence-v0": ("inspire_rh56_unitree", "shadow", "allegro"),
    "PinchPlace-v0": ("shadow", "xhand1", "unitree_dex3_1"),
    "PinchLift-v0": ("leap", "linkerhand_o7", "unitree_dex3_1"),
}  # the Allegro is refused by both pinches: see below


def _need(hand: str) -> None:
    from lerobot_env_unidextok import sim_hands

    if hand not in sim_hands.sim_hand_names():
        pytest.skip(f"{hand}'s URDF is not found (set UNIDEXTOK_URDF_DIR to a copy of shared/data/urdf)")


@pytest.mark.parametrize("task", list(TASK_HANDS))
def test_gymnasium_env_checker_passes(task):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(f"lerobot_env_unidextok/{task}", hand="shadow", disable_env_checker=True)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.unwrapped.task_description == TASK_TEXT[task]


@pytest.mark.parametrize("task", list(TASK_HANDS))
def test_a_seeded_episode_is_reproduced_exactly_and_the_columns_are_every_hands(task):
    a = random_rollout(UniDexTokEnv("shadow", task, render_mode=None), seed=7, steps=5)
    b = random_rollout(UniDexTokEnv("shadow", task, render_mode=None), seed=7, steps=5)
    c = random_rollout(UniDexTokEnv("shadow", task, render_mode=None), seed=8, steps=5)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], c[0])
    width = len(TASK_COLUMNS[task])
    for hand in TASK_HANDS[task]:
        _need(hand)
        names = UniDexTokEnv(hand, task, render_mode=None).state_names
        assert names[6 : 6 + width] == list(TASK_COLUMNS[task]), hand


@pytest.mark.parametrize("task", list(TASK_HANDS))
def test_the_expert_succeeds_on_seeded_episodes(task):
    for hand in TASK_HANDS[task]:
        _need(hand)
        env = UniDexTokEnv(hand, task, render_mode=None)
        wins = sum(expert_episode(env, 3000 + i, 4000 + i, 50)[2] for i in range(4))
        assert wins >= 3, f"{hand} {task}: {wins}/4"


def test_finger_sequence_succeeds_only_in_order_and_by_each_finger():
    """The presses still to do are in the columns, each place one-hot (due, next, then), and move along the order
    as `presses_done` counts the expert's presses; pressing another button of the sequence before the due one ends
    the episode as a failure."""
    from lerobot_env_unidextok.columns import PRESS_FINGERS
    from lerobot_env_unidextok.experts import Expert

    env = UniDexTokEnv("allegro", "FingerSequence-v0", render_mode=None)
    cols = {k: [env.state_names.index(f"{k}_{f}") for f in PRESS_FINGERS] for k in ("due", "next", "then")}
    due_cols, done_col = cols["due"], env.state_names.index("presses_done")

    def places(state: np.ndarray) -> list[str]:  # the fingers of due, next, then ("": no press left there)
        return [PRESS_FINGERS[int(np.argmax(state[c]))] if state[c].max() > 0 else "" for c in cols.values()]

    obs, _ = env.reset(seed=3)
    assert places(obs["agent_pos"]) == list(env.task.order) and obs["agent_pos"][done_col] == 0
    assert all(sorted(obs["agent_pos"][c]) == [0, 0, 0, 1] for c in cols.values())
    expert = Expert(env, np.random.default_rng(0), noise=False)
    expert.reset(obs)
    seen = {0: places(obs["agent_pos"])}  # presses done -> the fingers the columns named then
    for _ in range(50):
        obs, _, terminated, _, info = env.step(expert.act(obs))
        if terminated:
            break
        seen[int(obs["agent_pos"][done_col])] = places(obs["agent_pos"])
    assert info["is_success"] and obs["agent_pos"][done_col] == 3
    order = list(env.task.order)
    assert [seen[k] for k in range(3)] == [order, [*order[1:], ""], [order[2], "", ""]]

    # the same episode with the expert shown the second finger as due: its button first is out of turn
    class Swapped:
        def __init__(self, a: int, b: int) -> None:
            self.a, self.b = a, b

        def __call__(self, obs):
            state = obs["agent_pos"].copy()
            state[[self.a, self.b]] = state[[self.b, self.a]]
            return {**obs, "agent_pos": state}

    obs, _ = env.reset(seed=3)
    first, second = (due_cols[PRESS_FINGERS.index(f)] for f in env.task.order[:2])
    swap = Swapped(first, second)
    expert = Expert(env, np.random.default_rng(0), noise=False)
    expert.reset(swap(obs))
    for _ in range(50):
        obs, _, terminated, _, info = env.step(expert.act(swap(obs)))
        if terminated:
            break
    assert terminated and not info["is_success"] and env.task.failure == "wrong order"


@pytest.mark.parametrize("task", ["PinchPlace-v0", "PinchLift-v0"])
def test_a_pinch_fails_when_another_finger_than_the_named_one_touches(task):
    """The expert pinches with the finger its first observation named; the task then names the other one: the
    named finger's neighbour holds the cylinder, which ends the episode as a failure, not a success."""
    from lerobot_env_unidextok.experts import Expert

    env = UniDexTokEnv("shadow", task, render_mode=None)
    obs, _ = env.reset(seed=1001)
    cols = dict(zip(env.state_names, obs["agent_pos"], strict=True))
    assert cols["pinch_index"] + cols["pinch_middle"] == 1
    assert cols["object_z"] == pytest.approx(cols["object_half_height"])  # standing on the table
    expert = Expert(env, np.random.default_rng(0), noise=False)
    expert.reset(obs)
    env.task.finger = "middle" if cols["pinch_index"] else "index"
    for _ in range(50):
        obs, _, terminated, _, info = env.step(expert.act(obs))
        if terminated:
            break
    assert terminated and not info["is_success"] and env.task.failure == "other finger"


@pytest.mark.parametrize(("task", "hand", "refusal"), [
    ("FingerSequence-v0", "unitree_dex3_1", r"^hand 'unitree_dex3_1' has 2 fingers besides the thumb .*FingerPress-v0"),
    ("PinchPlace-v0", "allegro", r"^hand 'allegro' cannot pinch .*no closer than 35 mm to the middle's .*GraspLift-v0"),
    ("PinchLift-v0", "allegro", r"^hand 'allegro' cannot pinch .*PinchLift-v0 asks for.* 35 mm to the middle's "),
])  # fmt: skip
def test_a_hand_that_cannot_do_the_task_is_refused_in_one_line(task, hand, refusal):
    _need(hand)
    with pytest.raises(SimInputError, match=refusal) as e:
        gym.make(f"lerobot_env_unidextok/{task}", hand=hand)
    assert "\n" not in str(e.value)
    # and as lerobot-eval meets it: --env.task / --env.hand are checked when its config is made, before gym.make
    with pytest.raises(SimInputError, match=refusal):
        UniDexTokEnvConfig(task=task, hand=hand)


def test_pinch_lift_succeeds_only_while_the_two_fingers_hold_it_up():
    """The expert's episode: success comes once the cylinder is 4 cm over its rest with the thumb and the named
    finger on it, not before (lifted 2 cm is not enough); with no target, the columns are the cylinder and the
    finger alone."""
    from lerobot_env_unidextok.experts import Expert
    from lerobot_env_unidextok.pinch_lift import PinchLift

    env = UniDexTokEnv("shadow", "PinchLift-v0", render_mode=None)
    assert not any(c.startswith("target") for c in TASK_COLUMNS["PinchLift-v0"])
    obs, _ = env.reset(seed=1002)
    expert = Expert(env, np.random.default_rng(0), noise=False)
    expert.reset(obs)
    heights = []
    for _ in range(50):
        obs, _, terminated, _, info = env.step(expert.act(obs))
        heights.append(float(obs["agent_pos"][env.state_names.index("object_z")]) - env.task.rest_z)
        if info["is_success"] or terminated:
            break
    assert info["is_success"] and not env.task.failure
    assert heights[-1] >= PinchLift.GOAL_M and max(heights[:-1]) < PinchLift.GOAL_M  # the first frame at 4 cm
    assert any(0.02 <= h < PinchLift.GOAL_M for h in heights)  # it passed 2 cm without succeeding
