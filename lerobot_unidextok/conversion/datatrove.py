"""datatrove pipeline steps and executors for sharded conversion (LeRobot's own porting pattern).

Follows `examples/port_datasets/slurm_port_shards.py` and `slurm_aggregate_shards.py` in
huggingface/lerobot: a `PipelineStep` whose `run(data, rank, world_size)` converts shard `rank` of
`world_size` (`ConvertShard`: `pipeline.convert` with `shard_index=rank, num_shards=world_size`: a
contiguous slice of the source-ordered episode list, the test split chosen over the whole source), and
an executor with one task that depends on the first and merges the shards in order (`MergeShards`:
`pipeline.merge_shards`, i.e. LeRobot's `aggregate_datasets` plus our records). Each shard task
validates its shard before it is marked complete.

Use `conversion.sharded.convert_with_executor` (set-up checks, resume guard); `build_executors` alone
constructs the executors without running anything (e.g. to inspect a Slurm script). datatrove is an
optional extra (`pip install 'lerobot_policy_unidextok[datatrove]'`), imported only by this module.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import json
import logging
import shutil
import sys
from dataclasses import asdict, replace
from pathlib import Path

from datatrove.executor import LocalPipelineExecutor
from datatrove.executor.slurm import SlurmPipelineExecutor
from datatrove.pipeline.base import PipelineStep

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.conversion.executor_options import ExecutorOptions, logging_dir_of
from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert, merge_shards

logger = logging.getLogger(__name__)

__all__ = ["ConvertShard", "MergeShards", "build_executors", "shard_roots"]


def shard_roots(shards_dir: str | Path, num_shards: int) -> list[Path]:
    """Folder of each shard dataset, in shard order."""
    return [Path(shards_dir) / f"shard-{k:05d}-of-{num_shards:05d}" for k in range(num_shards)]


class ConvertShard(PipelineStep):
    """Convert shard `rank` of `world_size` into `shards_dir` (a contiguous slice of the episode list)."""

    name = "convert shard"
    type = "UDHM"

    def __init__(self, options: ConvertOptions, shards_dir: str | Path):
        super().__init__()
        self.options = asdict(options)  # plain data: the executor is pickled for Slurm
        self.shards_dir = str(shards_dir)

    def run(self, data=None, rank: int = 0, world_size: int = 1):
        from lerobot_unidextok.conversion.validate import validate_dataset

        root = shard_roots(self.shards_dir, world_size)[rank]
        # overwrite: a shard written by an attempt that died before datatrove marked it complete is redone
        opts = ConvertOptions(
            **{**self.options, "root": root, "shard_index": rank, "num_shards": world_size, "overwrite": True}
        )
        report = convert(opts)
        check = validate_dataset(root, load=False)  # the data checks; the shard fits this task's memory
        if not check.ok:
            raise RuntimeError(f"shard {rank}/{world_size} at {root} failed validation:\n{check.table()}")
        self.stat_update("episodes", value=report.num_episodes, unit="shard")
        self.stat_update("frames", value=report.num_frames, unit="shard")
        self.stat_update("skipped_episodes", value=len(report.failures), unit="shard")
        logger.info("shard %d/%d: %d episodes, %d frames -> %s", rank, world_size, report.num_episodes,
                    report.num_frames, root)  # fmt: skip


class MergeShards(PipelineStep):
    """One task: merge the shards in order into the target (records and episode counts checked), then
    remove the shards.

    Each shard was validated by its own task (`validate_dataset(load=False)`); the merged dataset is not
    read again here (it may not fit one machine's memory): `unidextok-convert --validate=true --root=...`."""

    name = "merge shards"
    type = "UDHM"

    def __init__(
        self,
        shards_dir: str | Path,
        num_shards: int,
        root: str | Path,
        repo_id: str,
        overwrite: bool = False,
        keep_shards: bool = False,
    ):
        super().__init__()
        self.shards_dir, self.num_shards = str(shards_dir), num_shards
        self.root, self.repo_id = str(root), repo_id
        self.overwrite, self.keep_shards = overwrite, keep_shards

    def run(self, data=None, rank: int = 0, world_size: int = 1):
        if rank != 0:
            return
        shards = shard_roots(self.shards_dir, self.num_shards)
        missing = [str(s) for s in shards if not (s / INFO_PATH).is_file()]
        if missing:
            raise FileNotFoundError(f"shard datasets missing (did every convert task finish?): {missing}")
        target = merge_shards(shards, self.root, self.repo_id, overwrite=self.overwrite)
        info = json.loads((target / INFO_PATH).read_text())
        self.stat_update("episodes", value=int(info["total_episodes"]), unit="dataset")
        self.stat_update("frames", value=int(info["total_frames"]), unit="dataset")
        if not self.keep_shards:
            shutil.rmtree(self.shards_dir, ignore_errors=True)
        logger.info("merged %d shards -> %s", len(shards), target)


def _venv_command() -> str | None:
    """`source <venv>/bin/activate` when this Python runs in a venv, so compute nodes find datatrove."""
    activate = Path(sys.prefix) / "bin" / "activate"
    return f"source {activate}" if sys.prefix != sys.base_prefix and activate.is_file() else None


def _preload_local_workers() -> None:
    """Import this package once in datatrove's forkserver (multiprocess) so that each local worker forks
    with it loaded instead of importing it again (seconds of CPU per worker: lerobot, torch)."""
    import multiprocess

    from lerobot_unidextok.conversion.registry import CONVERTERS_PACKAGE

    multiprocess.get_context("forkserver").set_forkserver_preload([__name__, CONVERTERS_PACKAGE])


def build_executors(opts: ConvertOptions, cfg: ExecutorOptions, num_shards: int | None = None):
    """(convert executor, merge executor); the merge one depends on the other: run it to run both.

    Constructing them reads no data and starts nothing, so a Slurm configuration can be checked without
    a cluster (`merge.depends.get_sbatch_args()`, `get_launch_file_contents(...)`).
    """
    num_shards = num_shards or cfg.tasks
    target = Path(opts.root).expanduser().resolve()
    logs = logging_dir_of(opts, cfg)
    shards_dir = logs / "shards"
    shard_opts = replace(opts, root=target, input=str(Path(opts.input).expanduser().resolve()), progress=False)
    convert_step = ConvertShard(shard_opts, shards_dir)
    merge_step = MergeShards(shards_dir, num_shards, target, opts.repo_id, opts.overwrite, cfg.keep_shards)
    if cfg.type == "local":
        _preload_local_workers()
        convert_exec = LocalPipelineExecutor(
            pipeline=[convert_step], tasks=num_shards, workers=cfg.workers, logging_dir=str(logs / "convert")
        )
        merge_exec = LocalPipelineExecutor(
            pipeline=[merge_step], tasks=1, workers=1, logging_dir=str(logs / "merge"), depends=convert_exec
        )
        return convert_exec, merge_exec
    s = cfg.slurm
    common = dict(
        time=s.time,
        partition=s.partition,
        cpus_per_task=s.cpus_per_task,
        mem_per_cpu_gb=s.mem_per_cpu_gb,
        qos=s.qos,
        env_command=s.env_command or _venv_command(),
        sbatch_args=dict(s.sbatch_args),
        max_array_size=s.max_array_size,
    )
    convert_exec = SlurmPipelineExecutor(
        pipeline=[convert_step],
        tasks=num_shards,
        workers=cfg.workers,
        job_name=s.job_name,
        logging_dir=str(logs / "convert"),
        **common,
    )
    merge_exec = SlurmPipelineExecutor(
        pipeline=[merge_step],
        tasks=1,
        workers=1,
        job_name=f"{s.job_name}-merge",
        logging_dir=str(logs / "merge"),
        depends=convert_exec,
        **common,
    )
    return convert_exec, merge_exec
