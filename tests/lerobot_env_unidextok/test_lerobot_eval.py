"""The stock `lerobot-eval` finds the simulator by LeRobot's plugin convention (no flag) and scores a real
`act_udt` checkpoint trained by the stock `lerobot-train` on expert episodes; a checkpoint of another hand and
a hand without a model are each refused with one `error:` line. The Shadow's 22 native joints are as many as a UDHM block, so this also checks
that the env's `state_is_native` flag, not the width, decides how its state is read."""

import ctypes.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
from linkerhand_udhm import subprocess_env

BIN = Path(sys.executable).parent
pytestmark = pytest.mark.slow


def _run(args: list[str], cwd: Path, check: bool = True, headless: bool = False) -> subprocess.CompletedProcess:
    """`args` with rendering off, or (`headless`) as on a machine without a display: MUJOCO_GL unset."""
    env = subprocess_env(OMP_NUM_THREADS="1", MUJOCO_GL="disable")
    if headless:
        env = {k: v for k, v in env.items() if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    r = subprocess.run(args, cwd=cwd, env=env, text=True, capture_output=True, timeout=600)
    if check:
        assert r.returncode == 0, f"{args}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.fixture(scope="module")
def shadow_checkpoint(tmp_path_factory) -> Path:
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    work = tmp_path_factory.mktemp("sim_eval")
    record(RecordConfig(hand="shadow", task="GraspLift-v0", episodes=2, root=str(work / "native")))
    convert(ConvertOptions(source="lerobot", input=str(work / "native"), root=str(work / "udhm"),
                           source_options={"hands": {"right": "shadow:right_"}}, test_fraction=0.0, progress=False))  # fmt: skip
    from lerobot_unidextok.configs import resolve_config_path

    _run([str(BIN / "lerobot-train"), f"--config_path={resolve_config_path('lerobot/act_udt_cpu')}",
          "--dataset.repo_id=sim/shadow", f"--dataset.root={work / 'udhm'}", "--policy.udt_relative_actions=false",
          "--policy.udt_copy_start=false", "--steps=2", "--batch_size=4", "--save_freq=2", "--log_freq=1",
          f"--output_dir={work / 'policy'}"], work)  # fmt: skip
    return work / "policy" / "checkpoints" / "last" / "pretrained_model"


def test_lerobot_eval_scores_a_checkpoint_on_the_simulator(shadow_checkpoint, tmp_path):
    _run([str(BIN / "lerobot-eval"), f"--policy.path={shadow_checkpoint}", "--env.type=unidextok",
          "--env.task=GraspLift-v0", "--env.hand=shadow", "--eval.n_episodes=2", "--eval.batch_size=2",
          "--eval.use_async_envs=false", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"], tmp_path)  # fmt: skip
    overall = json.loads((tmp_path / "eval" / "eval_info.json").read_text())["overall"]
    assert overall["n_episodes"] == 2 and 0 <= overall["pc_success"] <= 100
    line = _run([str(BIN / "unidextok-sim-success"), f"--eval={tmp_path / 'eval'}"], tmp_path).stdout
    assert "/2 = " in line and "95 % Wilson interval" in line


def test_a_checkpoint_of_another_hand_is_refused_with_the_fix(shadow_checkpoint, tmp_path):
    r = _run([str(BIN / "lerobot-eval"), f"--policy.path={shadow_checkpoint}", "--env.type=unidextok",
              "--env.hand=inspire_rh56_unitree", "--eval.n_episodes=1", "--eval.batch_size=1",
              "--eval.use_async_envs=false", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"], tmp_path,
             check=False)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1, r.stderr[-2000:]
    assert "trained on another robot or hand" in errors[0] and "unidextok-deploy" in errors[0]
    assert "shadow" in errors[0] and "Traceback" not in r.stderr


def test_a_hand_without_a_model_is_one_error_line_before_anything_runs(shadow_checkpoint, tmp_path):
    """draccus raises the env config's refusal as the cause of its own ParsingError; the plugin's hook prints it."""
    r = _run([str(BIN / "lerobot-eval"), f"--policy.path={shadow_checkpoint}", "--env.type=unidextok",
              "--env.hand=linkerhand_l6", f"--output_dir={tmp_path / 'eval'}"], tmp_path, check=False)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1, r.stderr[-2000:]
    assert errors[0].startswith(
        "error: hand 'linkerhand_l6' cannot be simulated: its spec maps no URDF (a `urdf:` block, docs/hands.md); "
        "the simulator runs: allegro, "
    ), errors[0]  # then the others: the model files' hands and every spec whose URDF is found
    assert not (tmp_path / "eval").exists()


def test_a_checkpoint_of_another_task_is_refused_as_such_before_anything_runs(shadow_checkpoint, tmp_path):
    """A GraspLift-v0 policy on FingerPress-v0 was told it "was trained on another robot or hand" at its first
    step; the hand is right, the task is not."""
    r = _run([str(BIN / "lerobot-eval"), f"--policy.path={shadow_checkpoint}", "--env.type=unidextok",
              "--env.task=FingerPress-v0", "--env.hand=shadow", "--eval.n_episodes=1", "--eval.batch_size=1",
              "--eval.use_async_envs=false", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"], tmp_path,
             check=False)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "was trained on the simulator's GraspLift-v0 task" in errors[0] and "--env.task=GraspLift-v0" in errors[0]
    assert "another robot or hand" not in errors[0] and not (tmp_path / "eval").exists()


def test_a_one_hand_checkpoint_bound_zero_shot_to_another_hand_runs_in_lerobot_eval(shadow_checkpoint, tmp_path):
    """A policy trained on the Shadow alone, bound to the Allegro by `unidextok-deploy --zero_shot=true` (refused
    before: "nothing to bind"), is scored by the stock lerobot-eval on the Allegro (issue 47). With MUJOCO_GL unset
    and no display: the Allegro's model is built (it loads MuJoCo while LeRobot parses the config), which aborted
    lerobot-eval in GLFW before the simulator chose the backend first (issue 55); its videos are written."""
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    record(RecordConfig(hand="allegro", task="GraspLift-v0", episodes=1, root=str(tmp_path / "native")))
    convert(ConvertOptions(source="lerobot", input=str(tmp_path / "native"), root=str(tmp_path / "udhm"),
                           source_options={"hands": {"right": "allegro:right_"}}, test_fraction=0.0, progress=False))  # fmt: skip
    _run([str(BIN / "unidextok-deploy"), f"--checkpoint={shadow_checkpoint}", f"--robot={tmp_path / 'udhm'}",
          "--zero_shot=true", f"--output={tmp_path / 'bound'}"], tmp_path)  # fmt: skip
    assert json.loads((tmp_path / "bound" / "config.json").read_text())["udt_hand_layout"] == ["allegro"]
    _run([str(BIN / "lerobot-eval"), f"--policy.path={tmp_path / 'bound'}", "--env.type=unidextok",
          "--env.task=GraspLift-v0", "--env.hand=allegro", "--eval.n_episodes=1", "--eval.batch_size=1",
          "--eval.use_async_envs=false", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"], tmp_path,
         headless=True)  # fmt: skip
    overall = json.loads((tmp_path / "eval" / "eval_info.json").read_text())["overall"]
    assert overall["n_episodes"] == 1 and 0 <= overall["pc_success"] <= 100
    (video,) = (tmp_path / "eval" / "videos").rglob("eval_episode_0.mp4")
    import av

    from lerobot_env_unidextok.gl import HEADLESS_BACKENDS

    frame = next(av.open(str(video)).decode(video=0)).to_ndarray(format="rgb24")
    if any(ctypes.util.find_library(lib) for _, lib in HEADLESS_BACKENDS):  # was black, after GLFW's failure
        assert frame.max() > 0
