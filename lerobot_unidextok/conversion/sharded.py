"""Sharded conversion on a datatrove executor: options, set-up checks, resume guard (no datatrove import).

    from lerobot_unidextok.conversion import ConvertOptions
    from lerobot_unidextok.conversion.sharded import ExecutorOptions, convert_with_executor
    convert_with_executor(ConvertOptions(source="egodex", input="raw/egodex", root="out/egodex_udhm"),
                          ExecutorOptions(type="local", tasks=8, workers=2))

`convert_with_executor` checks the set-up once in this process (source options, hands, input, existing
target: the same `SetupError`s as `convert`), caps the tasks at the number of episodes, then runs the
datatrove pipeline of `conversion.datatrove`: `tasks` shard conversions and one merge.

- `type="local"`: datatrove's `LocalPipelineExecutor` (`tasks` shards, `workers` at a time) here.
- `type="slurm"`: datatrove's `SlurmPipelineExecutor`: one sbatch array job for the shards and a
  merge job that depends on it (`afterok`). Returns once both are submitted.

Everything of a run lives in `logging_dir` (default `<root>.datatrove` beside the target): datatrove's
logs, stats and completion markers (`convert/`, `merge/`), the shard datasets (`shards/`, deleted after
a successful merge unless `keep_shards`) and `run_settings.json`. Re-running the same command resumes
(datatrove skips completed tasks); a re-run with other settings on the same `logging_dir` is refused.
`overwrite=True` starts from scratch and replaces an existing target only when the merge is done.

`logging_dir` is a destination like `--root` (`data.destination.claim`, kind `LOGGING`), claimed with the target
before anything is read or deleted: it may be missing, an empty folder, or a logging folder an earlier run left
(recognised by its `run_settings.json`, `destination.LOGGING_MARKER`); an input, the target, a dataset, a
checkpoint, a run folder or a folder of other files is refused with one line. Only a recognised logging folder is
ever deleted (`overwrite=True`), and only after every check passed.
"""

from __future__ import annotations

import json
import logging
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Any

from lerobot_unidextok.conversion.executor_options import EXECUTORS, ExecutorOptions, SlurmOptions, logging_dir_of
from lerobot_unidextok.conversion.pipeline import (
    ConvertOptions,
    SetupError,
    checked_paths,
    plan_episodes,
)
from lerobot_unidextok.conversion.registry import import_sources, make_reader
from lerobot_unidextok.data.destination import LOGGING_MARKER, Kind, claim, kind_of, release
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.utils.imports import missing_package_message

logger = logging.getLogger(__name__)

__all__ = ["EXECUTORS", "ExecutorOptions", "SlurmOptions", "convert_with_executor", "logging_dir_of"]

RUN_SETTINGS = LOGGING_MARKER  # the settings of the run that owns a logging_dir (resume guard, and its marker)
DATATROVE_MISSING = missing_package_message(
    "datatrove", "datatrove", purpose="--executor.type=local|slurm", hint=" (or pip install 'datatrove>=0.10,<0.11')"
)


def _run_settings(opts: ConvertOptions, cfg: ExecutorOptions, num_shards: int) -> dict[str, Any]:
    """What a re-run must share to resume from a logging_dir (not workers, Slurm fields or overwrite)."""
    keep = ("source", "input", "root", "repo_id", "source_options", "mapping", "on_error", "test_fraction",
            "max_episodes", "sides", "fps", "keep")  # fmt: skip
    settings = {k: v for k, v in asdict(opts).items() if k in keep}
    settings.update(
        input=str(Path(opts.input).expanduser().resolve()),
        root=str(Path(opts.root).expanduser().resolve()),
        executor=cfg.type,
        num_shards=num_shards,
    )
    return json.loads(json.dumps(settings, default=str))


def _check_logging_dir(logs: Path, inputs: list[Path] | tuple[Path, ...] = (), overwrite: bool = False) -> Path:
    """`logs` may hold this run's logs (`data.destination.claim`, module docstring); nothing is changed."""
    return claim(logs, Kind.LOGGING, inputs=inputs, overwrite=overwrite, resume=True, flag="--executor.logging_dir")


def _claim_logging_dir(logs: Path, settings: dict, overwrite: bool, inputs: list[Path] | tuple[Path, ...] = ()) -> None:
    """Check `logs` (`_check_logging_dir`), then start it afresh (`overwrite`: an earlier logging folder of this
    writer, and nothing else, is deleted) or resume it (same settings), and record `settings`."""
    logs = _check_logging_dir(logs, inputs, overwrite)
    path = logs / RUN_SETTINGS
    if overwrite and kind_of(logs) is Kind.LOGGING:
        shutil.rmtree(logs)
    if path.is_file():
        before = json.loads(path.read_text())
        if before != settings:
            changed = sorted(k for k in settings.keys() | before.keys() if settings.get(k) != before.get(k))
            raise SetupError(
                f"{logs} holds a run with other settings ({', '.join(changed)} differ): resume it with the same "
                "settings, pass --overwrite=true to start again, or choose another --executor.logging_dir"
            )
        logger.info("resuming the run in %s: completed tasks are skipped", logs)
    logs.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(settings, indent=1))


def convert_with_executor(opts: ConvertOptions, cfg: ExecutorOptions) -> Path:
    """Set up once here, then convert the shards and merge them (local) or submit both jobs (Slurm).

    Returns the target folder (for Slurm: where the merge job will write it).
    """
    if cfg.type == "pool":
        raise InvalidInputError("ExecutorOptions(type='pool') converts in this process: call conversion.convert")
    if opts.shard_index != 0 or opts.num_shards != 1:
        raise InvalidInputError("with an executor each task converts one shard: leave shard_index/num_shards unset")
    try:  # datatrove is an optional extra: imported only when a run needs it
        import lerobot_unidextok.conversion.datatrove as dt
    except ImportError as exc:
        raise SetupError(f"{DATATROVE_MISSING}; {exc}") from exc
    target, input_path = checked_paths(opts)
    try:
        logs = logging_dir_of(opts, cfg)
        claimed_with = [input_path, target]  # the logs are neither, hold neither and sit inside neither
        _check_logging_dir(logs, claimed_with, opts.overwrite)  # before the input is read or anything deleted
        import_sources()
        plan = plan_episodes(make_reader(opts.source, opts.reader_options()), opts, input_path)
        num_shards = min(cfg.tasks, len(plan.items))
        if num_shards < cfg.tasks:
            logger.warning("%d tasks for %d episodes: running %d tasks", cfg.tasks, len(plan.items), num_shards)

        _claim_logging_dir(logs, _run_settings(opts, cfg, num_shards), opts.overwrite, claimed_with)
        convert_exec, merge_exec = dt.build_executors(opts, cfg, num_shards)
    finally:
        release(target)  # its lock: the merge task claims the target again, in its own process under Slurm
    merge_exec.run()  # runs (local) or submits (Slurm) its dependency, the shard conversions, first
    if cfg.type == "slurm":
        logger.info(
            "submitted Slurm job %s (convert, %d tasks) and %s (merge, after it); logs in %s",
            convert_exec.job_id, num_shards, merge_exec.job_id, logs,
        )  # fmt: skip
    return target
