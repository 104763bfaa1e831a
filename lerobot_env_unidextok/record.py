"""`unidextok-sim-record`: scripted expert episodes of one hand and task, written as a LeRobot v3 dataset.

    unidextok-sim-record --hand=shadow --task=GraspLift-v0 --episodes=50 --root=data/sim_shadow_grasp
    unidextok-convert --source=lerobot --input=data/sim_shadow_grasp --root=data/sim_shadow_grasp_udhm \
        --source_options='{"hands": {"right": "shadow:right_"}}'

The dataset is what a robot would record, in the hand's native units: `observation.state` (the wrist pose, the
task's object and goal columns, the hand's native joints, named as `columns.state_names`) and `action` (the wrist
target and the native hand command the expert sent), 10 fps, no images, one task text; each episode goes on
for `AFTER_SUCCESS_STEPS` steps of the expert's plan after the task succeeded. `meta/unidextok_wrist_frame.json`
records (for a task that grasps, `Task.grasps`) the wrist-pose columns, their rotation convention and the hand's grasp centre in the wrist frame
(`grasp_centre.py`), which `unidextok-convert --source=lerobot` carries into the converted dataset's record.
Only episodes the expert completed are kept (`--keep_failures=true` keeps all); episode i is drawn from seed
`seed + i` and the expert's noise from `noise_seed + i`, so a dataset is reproducible from its flags, and seeds
are never shared with `lerobot-eval`'s (1000 + i) unless asked.

`--root` follows every writer's destination rule (`lerobot_unidextok.data.destination`): it is checked before any
episode is simulated (never inside a dataset or a checkpoint; an existing LeRobot dataset only with
`--overwrite=true`); the dataset is written into a hidden sibling folder of this run's own (pid and a random
part, so two runs never touch each other's) and moved into place when finished.
"""


# no `from __future__ import annotations`: the CLI wrapper reads the config class from record_cli's annotation
import logging
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_env_unidextok.columns import TASK_TEXT
from lerobot_env_unidextok.errors import SimInputError
from lerobot_unidextok.data.destination import Kind, claim, move_into_place, release
from lerobot_unidextok.data.wrist_frame import write_recorded
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap
from lerobot_unidextok.utils.files import temp_sibling

logger = logging.getLogger(__name__)


@dataclass
class RecordConfig:
    hand: str = "inspire_rh56_unitree"  # a hand spec with a simulation model
    task: str = "GraspLift-v0"  # one of columns.TASKS (GraspLift-v0, FingerPress-v0, FingerSequence-v0, ...)
    episodes: int = 50  # episodes to write (successful ones, unless keep_failures)
    root: str = ""  # output folder (new or empty; an existing LeRobot dataset only with --overwrite=true)
    overwrite: bool = False  # replace the LeRobot dataset already at --root (once this one is finished)
    repo_id: str = ""  # dataset id (default local/sim_<hand>_<task>)
    seed: int = 100_000  # episode i is drawn from seed + i (lerobot-eval uses 1000 + i)
    noise_seed: int = 200_000  # the expert's noise for episode i: noise_seed + i
    keep_failures: bool = False
    max_attempts_factor: float = 1.5  # give up after this many attempts per episode asked
    episode_length: int = 50  # steps before an episode is cut (at 10 fps)
    # record each fingertip's position from the hand's grasp centre too (columns.FINGERTIP_COLUMNS; evaluate its
    # policies with lerobot-eval --env.fingertips=true)
    fingertips: bool = False

    def __post_init__(self) -> None:
        if not self.root:
            raise SimInputError("pass --root=<output folder> for the dataset")
        if self.episodes < 1:
            raise SimInputError(f"--episodes must be >= 1, got {self.episodes}")
        if self.episode_length < 1:
            raise SimInputError(f"--episode_length must be >= 1 step (10 steps a second), got {self.episode_length}")
        if not self.max_attempts_factor >= 1:
            raise SimInputError(
                f"--max_attempts_factor must be >= 1 (attempts per episode asked), got {self.max_attempts_factor}"
            )
        self.repo_id = self.repo_id or f"local/sim_{self.hand}_{self.task.split('-')[0].lower()}"


@dataclass
class RecordReport:
    root: Path
    episodes: int
    attempts: int
    frames: int
    seconds: float

    @property
    def expert_success(self) -> float:
        return self.episodes / max(self.attempts, 1)


AFTER_SUCCESS_STEPS = 5  # a recording goes on this many steps after the task succeeded (the lift goes on)


def expert_episode(env, seed: int, noise_seed: int, max_steps: int, after_success: int = 0):
    """(states (T, D), actions (T, A), success) of one expert episode; `after_success` more steps of the expert's
    plan are kept once the task succeeded (the env ends the episode there; a demonstration that stops at the
    first lifted frame shows too little of the lift for a policy to learn it)."""
    from lerobot_env_unidextok.experts import Expert  # start-up: MuJoCo and torch load with it, not with --help

    obs, _ = env.reset(seed=seed)
    expert = Expert(env, np.random.default_rng(noise_seed))
    expert.reset(obs)
    states, actions, success, left = [], [], False, max_steps
    while left > 0:
        action = expert.act(obs)
        states.append(obs["agent_pos"])
        actions.append(action)
        obs, _, terminated, _, info = env.step(action)
        left -= 1
        if info["is_success"] and not success:
            success, left = True, min(left, after_success)
        elif terminated and not success:
            break
    return np.stack(states).astype(np.float32), np.stack(actions).astype(np.float32), success


def record(cfg: RecordConfig) -> RecordReport:
    # a plain LeRobot dataset (no conversion record): what a robot records
    root = claim(cfg.root, Kind.DATASET, overwrite=cfg.overwrite, flag="--root")
    try:
        return _record_into(root, cfg)
    finally:
        release(root)  # the destination's lock (lerobot_unidextok/data/destination.py), however the run ended


def _record_into(root: Path, cfg: RecordConfig) -> RecordReport:
    """`record` into the claimed `root`."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_env_unidextok.env import UniDexTokEnv  # start-up: MuJoCo and torch load with it, not with --help

    env = UniDexTokEnv(cfg.hand, cfg.task, render_mode=None, fingertips=cfg.fingertips)
    features = {
        "observation.state": {"dtype": "float32", "shape": (len(env.state_names),), "names": env.state_names},
        "action": {"dtype": "float32", "shape": (len(env.action_names),), "names": env.action_names},
    }
    tmp = temp_sibling(root)  # this run's own: another run's is never touched
    start, kept, attempts, frames = time.time(), 0, 0, 0
    try:
        ds = LeRobotDataset.create(repo_id=cfg.repo_id, fps=env.metadata["render_fps"], features=features, root=tmp,
                                   robot_type=f"unidextok_sim_{cfg.hand}", use_videos=False)  # fmt: skip
        limit = int(np.ceil(cfg.episodes * cfg.max_attempts_factor))
        while kept < cfg.episodes:
            if attempts >= limit:
                raise SimInputError(
                    f"the expert completed {kept} of {attempts} episodes of {cfg.hand} on {cfg.task}; asked for "
                    f"{cfg.episodes}: raise --max_attempts_factor or pass --keep_failures=true"
                )
            states, actions, success = expert_episode(env, cfg.seed + attempts, cfg.noise_seed + attempts,
                                                      cfg.episode_length, AFTER_SUCCESS_STEPS)  # fmt: skip
            attempts += 1
            if not (success or cfg.keep_failures):
                continue
            for s, a in zip(states, actions, strict=True):
                ds.add_frame({"observation.state": s, "action": a, "task": TASK_TEXT[cfg.task]})
            ds.save_episode()
            kept, frames = kept + 1, frames + len(states)
        ds.finalize()
        if env.task.grasps:  # the hand's grasp centre (lerobot_unidextok/data/wrist_frame.py); a press has none
            write_recorded(tmp, env.wrist_frame())
        move_into_place(tmp, root, Kind.DATASET, cfg.overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return RecordReport(root, kept, attempts, frames, time.time() - start)


@wrap()
def record_cli(cfg: RecordConfig) -> None:
    report = record(cfg)
    print(f"wrote {report.root}: {report.episodes} episodes, {report.frames} frames ({cfg.hand}, {cfg.task}); "
          f"the expert completed {report.episodes} of {report.attempts} attempts "
          f"({100 * report.expert_success:.1f} %) in {report.seconds:.1f} s")  # fmt: skip


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", force=True)
    run_cli(record_cli)


if __name__ == "__main__":
    main()
