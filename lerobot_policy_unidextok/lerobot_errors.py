"""LeRobot's own errors that are a user's mistake with a fix this plugin knows, as one `error:` line.

The plugin's hook in LeRobot's CLIs (`lerobot_unidextok.utils.cli.user_errors_in_lerobot_clis`) prints this
package's `UserError`s as one line; `user_error_for` gives it one for an error LeRobot raised itself, read
with the command line that led to it:

- `lerobot-train` of a `<type>_udt` policy on a LeRobot v2.1 dataset: LeRobot 0.6 refuses v2.1
  (`BackwardCompatibilityError`, pointing at its own v2.1 -> v3.0 script), while the policy needs the dataset
  converted to UDHM anyway, and `unidextok-convert --source=lerobot` reads v2.1 as it is;
- `lerobot-eval` with `--eval.n_episodes` (or `--eval.batch_size`) below 1: LeRobot's `make_env` raises
  "`n_envs` must be at least 1" after loading everything, a traceback naming neither flag;
- `lerobot-train --output_dir=<a dataset or a checkpoint>`: LeRobot's `FileExistsError` ("already exists and resume
  is False") says to pick another folder but not that this one is a dataset, whose files other tools read whole
  (`lerobot_unidextok/policies/train_output.py`; an `--output_dir` inside one is refused when a `<type>_udt` policy
  is built).

Anything else (and a stock policy's v2.1 dataset, for which LeRobot's hint is right) is left as it was.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from lerobot_unidextok.data.destination import DestinationError
from lerobot_unidextok.errors import InvalidInputError, UserError
from lerobot_unidextok.policies.train_output import output_dir_problem

UDT_SUFFIX = "_udt"
N_ENVS_MESSAGE = "`n_envs` must be at least 1"  # lerobot/envs/factory.py make_env, LeRobot 0.6.1


def user_error_for(err: BaseException, argv: list[str]) -> UserError | None:
    """The one-line user error for LeRobot's `err` under the command line `argv`, or None."""
    from lerobot.datasets.utils import BackwardCompatibilityError  # loaded already when LeRobot raised it

    if isinstance(err, BackwardCompatibilityError) and (_policy_type(argv) or "").endswith(UDT_SUFFIX):
        return InvalidInputError(_v21_message(argv, _policy_type(argv)))
    if isinstance(err, ValueError) and str(err) == N_ENVS_MESSAGE:
        return InvalidInputError(_no_envs_message(argv))
    output_dir = _flag(argv, "--output_dir")
    if isinstance(err, FileExistsError) and output_dir and output_dir_problem(output_dir):
        return DestinationError(output_dir_problem(output_dir))
    return None


def _v21_message(argv: list[str], policy_type: str) -> str:
    root = _flag(argv, "--dataset.root")
    repo_id = _flag(argv, "--dataset.repo_id") or "<repo_id>"
    source = root or f"$HF_LEROBOT_HOME/{repo_id}"
    return (
        f"{source} is a LeRobot v2.1 dataset, which this LeRobot cannot load, and a {policy_type} policy trains on a "
        "dataset converted to UDHM anyway: unidextok-convert reads v2.1 as it is. Convert it, then train on the "
        f"result: unidextok-convert --source=lerobot --input={source} --root=<new folder> "
        "--source_options='{\"hands\": {\"right\": \"<hand spec>:<its column prefix>\"}}', then "
        "--dataset.root=<new folder> (docs/conversion.md)"
    )


def _no_envs_message(argv: list[str]) -> str:
    episodes, batch = _flag(argv, "--eval.n_episodes"), _flag(argv, "--eval.batch_size")
    if episodes is not None and _int(episodes) is not None and _int(episodes) < 1:
        return (
            f"--eval.n_episodes={episodes}: lerobot-eval has no episode to run; pass --eval.n_episodes >= 1 "
            "(--eval.batch_size, the envs run at once, is at most that many)"
        )
    if batch is not None and _int(batch) is not None and _int(batch) < 1:
        return f"--eval.batch_size={batch}: the envs run at once must be >= 1 (0 chooses from the CPU count)"
    return "lerobot-eval has no env to run: --eval.n_episodes and --eval.batch_size must be >= 1"


def _policy_type(argv: list[str]) -> str | None:
    """The policy type the command line asks for: --policy.type, else the type in --policy.path's config.json,
    else in --config_path's `policy` section."""
    kind = _flag(argv, "--policy.type")
    if kind:
        return kind
    path = _flag(argv, "--policy.path")
    if path and (Path(path) / "config.json").is_file():
        return _read(Path(path) / "config.json").get("type")
    config = _flag(argv, "--config_path")
    if config and Path(config).is_file():
        policy = _read(Path(config)).get("policy")
        return policy.get("type") if isinstance(policy, dict) else None
    return None


def _read(path: Path) -> dict:
    try:
        text = path.read_text()
        data = yaml.safe_load(text) if path.suffix in (".yaml", ".yml") else json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError, yaml.YAMLError):
        return {}
    return data if isinstance(data, dict) else {}


def _flag(argv: list[str], name: str) -> str | None:
    """The last value of `--name=value` or `--name value` in `argv` (as draccus reads it: the last wins)."""
    value = None
    for i, arg in enumerate(argv):
        if arg.startswith(f"{name}="):
            value = arg.split("=", 1)[1]
        elif arg == name and i + 1 < len(argv):
            value = argv[i + 1]
    return value


def _int(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


__all__ = ["user_error_for"]
