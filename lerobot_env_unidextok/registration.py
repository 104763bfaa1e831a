"""The gymnasium ids `lerobot_env_unidextok/<task>` (the env module, and MuJoCo, load on `gym.make`)."""

from lerobot_env_unidextok.columns import EPISODE_STEPS, TASKS

GYM_NAMESPACE = "lerobot_env_unidextok"


def register_gym_ids() -> None:
    import gymnasium as gym

    for task in TASKS:
        env_id = f"{GYM_NAMESPACE}/{task}"
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="lerobot_env_unidextok.env:UniDexTokEnv",
                         max_episode_steps=EPISODE_STEPS, kwargs={"task": task})  # fmt: skip
