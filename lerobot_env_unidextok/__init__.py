"""lerobot-unidextok's simulator: dexterous hands on a floating wrist in MuJoCo, as a LeRobot env plugin.

Importing this package registers the gymnasium ids `lerobot_env_unidextok/<task>` for every task of
`columns.TASKS` (`GraspLift-v0`, `FingerPress-v0`, `FingerSequence-v0`, `PinchPlace-v0`, `ChordPress-v0`,
`PinchLift-v0`; gymnasium only: the env module, and MuJoCo, load on `gym.make`); `lerobot_env_unidextok.configuration` registers
LeRobot's `--env.type=unidextok` config, and LeRobot's CLIs import it through `lerobot_policy_unidextok` (the
distribution they discover). Needs the `sim` extra (`pip install 'lerobot_policy_unidextok[sim]'`) to run an episode.

    import gymnasium as gym, lerobot_env_unidextok
    env = gym.make("lerobot_env_unidextok/GraspLift-v0", hand="shadow")
    obs, info = env.reset(seed=0)     # obs["agent_pos"]: wrist pose, object and goal, the Shadow's 22 joints (rad)

Layout, lowest first: `errors`, `columns` (vector names), `objects` (the shapes to grasp), `gl` (MuJoCo, its
OpenGL backend chosen first: every module imports MuJoCo from it), `hand_model` (a hand's model and how its native
joints drive it; the YAML model files in `hand_models/`), `urdf_model` (a hand's MJCF built from its URDF, or the
one shipped in `assets/`) and `urdf_hand` (the rest read from its kinematic chain), `sim_hands` (which of the two
a hand runs on), `scene` (table, wrist, hand), `tasks` (and a module per later task, all in `task_classes`),
`grasp_centre`, `env` (the gymnasium env), `experts` (scripted demonstrations), `record` (expert datasets,
`unidextok-sim-record`), `success`, `configuration` (LeRobot's config).
"""

from lerobot_env_unidextok.registration import GYM_NAMESPACE, register_gym_ids

register_gym_ids()

__all__ = ["GYM_NAMESPACE", "register_gym_ids"]
