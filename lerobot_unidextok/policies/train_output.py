"""`lerobot-train --output_dir` held to the destination rule (`data/destination.py`) where the plugin can see it.

LeRobot 0.6.1 checks only that a new `--output_dir` does not exist yet. Pointed at a converted dataset it raised
its own `FileExistsError` traceback; pointed inside one (`--output_dir=<dataset>/runs/a`) it wrote its checkpoints
into the dataset, whose files other tools read as one unit. The plugin sees the flag in two places:

- LeRobot's `FileExistsError` for an `--output_dir` that is a dataset or a checkpoint: one `error:` line
  (`lerobot_policy_unidextok/lerobot_errors.py`, any policy type);
- a `<type>_udt` policy built for training (`UdtConfigMixin.validate_features`): an `--output_dir` inside a
  dataset or a checkpoint is refused before the first step.

It reads the flag as LeRobot does (`lerobot.configs.parser.parse_arg`): an `output_dir` set in a
`--config_path` file, or a stock policy type with an `--output_dir` inside a dataset, is not seen (docs/lerobot.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

from lerobot_unidextok.data.destination import UNITS, DestinationError, enclosing_unit, kind_of

TRAIN_COMMANDS = ("lerobot-train", "lerobot_train")


def output_dir_problem(output_dir: str | Path) -> str:
    """Why lerobot-train must not write its run into `output_dir` (it is or sits inside a dataset or a
    checkpoint), or ""."""
    path = Path(output_dir).expanduser().resolve()
    kind = kind_of(path)
    unit = (path, kind) if kind in UNITS else enclosing_unit(path)
    if unit is None:
        return ""
    where = f"is {unit[1].value}" if unit[0] == path else f"sits inside {unit[1].value} ({unit[0]})"
    return (
        f"--output_dir {path} {where}, whose files other tools read as one unit: lerobot-train would write its "
        "checkpoints into it; choose an --output_dir outside it (e.g. outputs/train/<run name>)"
    )


def refuse_training_into_a_unit(argv: list[str] | None = None) -> None:
    """In `lerobot-train`, refuse an `--output_dir` flag that is or sits inside a dataset or a checkpoint."""
    from lerobot.configs.parser import parse_arg  # loaded with LeRobot's train script already

    argv = sys.argv if argv is None else argv
    if not argv or Path(argv[0]).name not in TRAIN_COMMANDS:
        return
    output_dir = parse_arg("output_dir", argv[1:])
    problem = output_dir_problem(output_dir) if output_dir else ""
    if problem:
        raise DestinationError(problem)


__all__ = ["output_dir_problem", "refuse_training_into_a_unit"]
