"""`--env.type=unidextok`: LeRobot's config of the simulator (registered on import, with the gym ids; no MuJoCo
import). `lerobot_policy_unidextok`, which LeRobot's CLIs discover, imports this module.

    lerobot-eval --policy.path=<checkpoint> --env.type=unidextok --env.task=GraspLift-v0 \
        --env.hand=inspire_rh56_unitree --eval.n_episodes=50 --eval.batch_size=10 --eval.use_async_envs=false

LeRobot sizes the loaded policy's action head by `features["action"]` (`make_policy(env_cfg=...)` replaces the
checkpoint's output features with the env's), so the config says what the *model* predicts: `policy_action="udhm"`
(the default) for `<type>_udt` checkpoints, whose model predicts the wrist pose and one 22-wide UDHM block (28
values) and whose post-processor hands the env the hand's native command; `"native"` for a policy trained on the
simulator's native dataset without UDHM (6 + the hand's native joints).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs import parser
from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig

from lerobot_env_unidextok.columns import EPISODE_STEPS, FPS, TASKS, WRIST_NAMES, state_names
from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.policy_fit import check_policy_fits
from lerobot_env_unidextok.registration import GYM_NAMESPACE, register_gym_ids

ENV_TYPE = "unidextok"
POLICY_ACTIONS = ("udhm", "native")
UDHM_DIM = 22


@EnvConfig.register_subclass(ENV_TYPE)
@dataclass
class UniDexTokEnvConfig(EnvConfig):
    # the task: GraspLift-v0 (grasp and lift objects of varied shape, size and place), FingerPress-v0 (press the
    # button under the finger the goal names), FingerSequence-v0 (three buttons in a given order, each by its own
    # finger), PinchPlace-v0 (pinch a cylinder with the thumb and the named finger, stand it in a target),
    # ChordPress-v0 (the buttons under two named fingers down together, each by its own finger) or PinchLift-v0
    # (pinch a cylinder with the thumb and the named finger, lift it)
    task: str | None = "GraspLift-v0"
    fps: int = FPS
    # the hand: a registered hand spec with a simulation model: a model file (inspire_rh56_unitree, inspire_rh56,
    # shadow), a built model the package ships (allegro, leap, xhand1, the LinkerHands, unitree_dex3_1, ...) or one
    # built from your URDF (the list: sim_hands.sim_hand_names()); observation and action in the spec's native units
    hand: str = "inspire_rh56_unitree"
    episode_length: int = EPISODE_STEPS  # steps (at fps) before an episode is cut
    # what the policy's model predicts: "udhm" (<type>_udt: wrist + one UDHM block) or "native"
    policy_action: str = "udhm"
    # observe each fingertip's position from the hand's grasp centre too (columns.FINGERTIP_COLUMNS, 15 values): a
    # policy trained on a recording made with `unidextok-sim-record --fingertips=true` needs it
    fingertips: bool = False
    render_width: int = 320
    render_height: int = 240
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=lambda: {"agent_pos": "observation.state", "action": "action"})

    def __post_init__(self) -> None:
        # start-up: MuJoCo and the hand specs (torch) load here, not in every LeRobot CLI that imports this module
        from lerobot_env_unidextok import sim_hands, task_classes

        if self.task not in TASKS:
            raise SimInputError(f"unknown task {self.task!r}; --env.task takes one of {', '.join(TASKS)}")
        if self.policy_action not in POLICY_ACTIONS:
            raise SimInputError(f"--env.policy_action must be one of {POLICY_ACTIONS}, got {self.policy_action!r}")
        if self.episode_length < 1:
            raise SimInputError(f"--env.episode_length must be >= 1 step, got {self.episode_length}")
        sim_hand = sim_hands.load(self.hand)
        # a hand that cannot do the task (FingerSequence-v0 on a two-finger Dex3-1) is refused here in one line, not
        # in lerobot-eval's gym.make traceback
        task_classes.TASKS[self.task](sim_hand)
        native = sim_hand.native_names
        # the checkpoint lerobot-eval was given, read from the command line as LeRobot's EvalPipelineConfig does
        check_policy_fits(parser.get_path_arg("policy"), self.task, self.hand, self.fingertips)
        hand_width = UDHM_DIM if self.policy_action == "udhm" else len(native)
        self.features = {
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(len(state_names(self.task, native, self.fingertips)),)),
            "action": PolicyFeature(type=FeatureType.ACTION, shape=(len(WRIST_NAMES) + hand_width,)),
        }

    @property
    def package_name(self) -> str:
        return GYM_NAMESPACE

    @property
    def gym_id(self) -> str:
        return f"{GYM_NAMESPACE}/{self.task}"

    @property
    def gym_kwargs(self) -> dict:
        return {"hand": self.hand, "max_episode_steps": self.episode_length, "width": self.render_width,
                "height": self.render_height, "fingertips": self.fingertips}  # fmt: skip


register_gym_ids()
