"""LeRobot's own errors with a fix the plugin knows end in one `error:` line and exit 2 in LeRobot's CLIs: a
`<type>_udt` policy on a raw LeRobot v2.1 dataset (before: LeRobot's BackwardCompatibilityError traceback,
pointing at its v2.1 -> v3.0 script, though the policy needs `unidextok-convert`, which reads v2.1), and
`lerobot-eval --eval.n_episodes=0` (before: "`n_envs` must be at least 1" traceback)."""

import json
import subprocess
import sys
from pathlib import Path

import packaging.version
import pytest
from lerobot.datasets.utils import BackwardCompatibilityError
from linkerhand_udhm import subprocess_env

from lerobot_policy_unidextok.lerobot_errors import user_error_for
from lerobot_unidextok.errors import UserError
from lerobot_unidextok.samples.formats import write_samples

BIN = Path(sys.executable).parent


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=cwd, env=subprocess_env(OMP_NUM_THREADS="1", MUJOCO_GL="disable"), text=True,
                          capture_output=True, timeout=600)  # fmt: skip


def _one_error(r: subprocess.CompletedProcess) -> str:
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1 and "Traceback" not in r.stderr, r.stderr[-3000:]
    return errors[0]


def test_lerobot_train_of_a_udt_policy_on_a_v21_dataset_names_unidextok_convert(tmp_path):
    raw = write_samples(tmp_path, sources=["lerobot"], episodes_per_source=1, frames_per_episode=10)["lerobot"]
    assert json.loads((raw / "meta" / "info.json").read_text())["codebase_version"] == "v2.1"
    r = _run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--policy.device=cpu", "--policy.push_to_hub=false",
              "--dataset.repo_id=local/raw", f"--dataset.root={raw}", f"--output_dir={tmp_path / 'out'}", "--steps=1"],
             tmp_path)  # fmt: skip
    line = _one_error(r)
    assert line.startswith(f"error: {raw} is a LeRobot v2.1 dataset") and "act_udt policy" in line
    assert f"unidextok-convert --source=lerobot --input={raw} --root=<new folder> --source_options=" in line
    assert not (tmp_path / "out").exists()


def test_lerobot_eval_with_no_episodes_is_one_line(tmp_path):
    r = _run([str(BIN / "lerobot-eval"), "--policy.type=act", "--policy.device=cpu", "--env.type=unidextok",
              "--eval.n_episodes=0", f"--output_dir={tmp_path / 'eval'}"], tmp_path)  # fmt: skip
    assert _one_error(r) == (
        "error: --eval.n_episodes=0: lerobot-eval has no episode to run; pass --eval.n_episodes >= 1 "
        "(--eval.batch_size, the envs run at once, is at most that many)"
    )


V21 = BackwardCompatibilityError("local/raw", packaging.version.parse("2.1"))
N_ENVS = ValueError("`n_envs` must be at least 1")


def test_the_policy_type_is_read_from_the_flag_a_checkpoint_or_a_config_file(tmp_path):
    (tmp_path / "ckpt").mkdir()
    (tmp_path / "ckpt" / "config.json").write_text(json.dumps({"type": "diffusion_udt"}))
    (tmp_path / "train.yaml").write_text("policy:\n  type: vqbet_udt\n")
    (tmp_path / "stock.yaml").write_text("policy:\n  type: act\n")
    said = {}
    for name, argv in {
        "flag": ["lerobot-train", "--policy.type=act", "--policy.type", "act_udt", "--dataset.root=d"],
        "checkpoint": ["lerobot-train", f"--policy.path={tmp_path / 'ckpt'}", "--dataset.repo_id=lab/g1"],
        "config": ["lerobot-train", f"--config_path={tmp_path / 'train.yaml'}", "--dataset.root=d"],
    }.items():
        err = user_error_for(V21, argv)
        assert isinstance(err, UserError) and isinstance(err, ValueError)
        said[name] = str(err)
    assert said["flag"].startswith("d is a LeRobot v2.1 dataset") and "a act_udt policy" in said["flag"]
    assert said["checkpoint"].startswith("$HF_LEROBOT_HOME/lab/g1 is") and "diffusion_udt" in said["checkpoint"]
    assert "vqbet_udt" in said["config"]
    # a stock policy keeps LeRobot's own message (its v2.1 -> v3.0 script is the right fix there)
    assert user_error_for(V21, ["lerobot-train", "--policy.type=act", "--dataset.root=d"]) is None
    assert user_error_for(V21, ["lerobot-train", f"--config_path={tmp_path / 'stock.yaml'}"]) is None
    assert user_error_for(RuntimeError("something else"), ["lerobot-eval"]) is None


@pytest.mark.parametrize(("argv", "said"), [
    (["--eval.n_episodes=-3"], "--eval.n_episodes=-3: lerobot-eval has no episode to run"),
    (["--eval.n_episodes=4", "--eval.batch_size=-1"], "--eval.batch_size=-1: the envs run at once must be >= 1"),
    ([], "lerobot-eval has no env to run: --eval.n_episodes and --eval.batch_size must be >= 1"),
])  # fmt: skip
def test_no_envs_names_the_flag(argv, said):
    assert str(user_error_for(N_ENVS, ["lerobot-eval", *argv])).startswith(said)


def test_a_translator_that_fails_leaves_the_error_as_it_was(tmp_path):
    """The hook asks the translator only about exceptions that are not ours; one it cannot read, or a bug of its
    own, keeps LeRobot's traceback and status."""
    script = tmp_path / "lerobot-x"
    script.write_text(
        "import sys\n"
        "from lerobot_unidextok.errors import InvalidInputError\n"
        "from lerobot_unidextok.utils.cli import user_errors_in_lerobot_clis\n"
        "def translate(err, argv):\n"
        "    if argv[1] == 'broken': raise RuntimeError('translator bug')\n"
        "    return InvalidInputError('translated: ' + str(err)) if argv[1] == 'known' else None\n"
        "user_errors_in_lerobot_clis(translate)\n"
        "raise ValueError('from lerobot')\n"
    )
    for what, status in (("known", 2), ("unknown", 1), ("broken", 1)):
        r = subprocess.run([sys.executable, str(script), what], capture_output=True, text=True, timeout=60,
                           env={k: v for k, v in subprocess_env().items() if k != "UNIDEXTOK_TRACEBACK"})  # fmt: skip
        assert r.returncode == status, r.stderr
        if status == 2:
            assert r.stderr.splitlines()[0] == "error: translated: from lerobot" and "Traceback" not in r.stderr
        else:
            assert "ValueError: from lerobot" in r.stderr and "translator bug" not in r.stderr


def test_lerobot_train_into_a_dataset_or_inside_one_is_one_line(g1_like, tmp_path):
    """`--output_dir=<dataset>` was LeRobot's FileExistsError traceback; `--output_dir=<dataset>/runs/a` wrote the
    checkpoints into the converted dataset. The first is one line from LeRobot's error, the second is refused when
    the `<type>_udt` policy is built, before the first step; nothing is written into the dataset."""
    from lerobot_unidextok.policies.train_output import refuse_training_into_a_unit

    root = g1_like["root"]
    exists = FileExistsError(f"Output directory {root} already exists and resume is False.")
    err = user_error_for(exists, ["lerobot-train", "--policy.type=act", f"--output_dir={root}"])
    assert isinstance(err, UserError) and str(err).startswith(f"--output_dir {root} is a dataset written by "
                                                              "unidextok-convert, whose files other tools read")
    assert user_error_for(exists, ["lerobot-train", f"--output_dir={tmp_path}"]) is None  # any other folder: LeRobot's
    before = sorted(p.relative_to(root) for p in root.rglob("*"))
    r = _run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--policy.device=cpu", "--policy.push_to_hub=false",
              "--policy.udt_preset=tiny", "--dataset.repo_id=test/g1", f"--dataset.root={root}", "--steps=1",
              f"--output_dir={root / 'runs' / 'a'}"], tmp_path)  # fmt: skip
    line = _one_error(r)
    assert line.startswith(f"error: --output_dir {root / 'runs' / 'a'} sits inside a dataset written by "
                           f"unidextok-convert ({root})") and "choose an --output_dir outside it" in line
    assert sorted(p.relative_to(root) for p in root.rglob("*")) == before
    refuse_training_into_a_unit(["python", f"--output_dir={root / 'runs' / 'a'}"])  # only lerobot-train's flag
