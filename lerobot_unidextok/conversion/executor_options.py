"""Where a conversion runs (this process, or sharded on datatrove): executor type, tasks, workers, Slurm fields, the run's folder.

Plain dataclasses (no datatrove import), shared by `conversion.sharded` (set-up checks, resume guard) and
`conversion.datatrove` (the executors built from them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lerobot_unidextok.conversion.pipeline import ConvertOptions

EXECUTORS = ("pool", "local", "slurm")  # pool: `pipeline.convert` in this process, no datatrove


@dataclass
class SlurmOptions:
    """Fields of datatrove's `SlurmPipelineExecutor` for the shard job (the merge job: same, one task)."""

    partition: str = ""  # required for type="slurm" (`sinfo` lists them)
    time: str = "04:00:00"  # time limit of one task
    cpus_per_task: int = 2  # give each task as many as --num_workers
    mem_per_cpu_gb: int = 2
    job_name: str = "unidextok-convert"
    qos: str = "normal"
    # shell line(s) that put `launch_pickled_pipeline` (datatrove) on the PATH of the compute nodes;
    # empty = activate the venv running this command (when it runs in one)
    env_command: str = ""
    sbatch_args: dict[str, str] = field(default_factory=dict)  # extra #SBATCH lines, e.g. {"account": "lab"}
    max_array_size: int = 1001  # the cluster's MaxArraySize; more tasks become several array jobs


@dataclass
class ExecutorOptions:
    """Where a conversion runs: in this process, or sharded on a datatrove executor."""

    # "pool": this process, `num_workers` reader processes (no datatrove) | "local" / "slurm": datatrove's
    # Local/Slurm PipelineExecutor, `tasks` shard conversions (each with `num_workers` processes), then one merge
    type: str = "pool"
    tasks: int = 2  # shards = datatrove tasks; capped at the number of episodes
    workers: int = -1  # tasks running at the same time (-1: all)
    logging_dir: str | None = None  # datatrove run folder (logs, completions, shards); default <root>.datatrove
    keep_shards: bool = False  # keep the shard datasets after the merge
    slurm: SlurmOptions = field(default_factory=SlurmOptions)  # datatrove's Slurm executor settings (type="slurm")

    def __post_init__(self) -> None:
        if isinstance(self.slurm, dict):
            self.slurm = SlurmOptions(**self.slurm)
        if self.type not in EXECUTORS:
            raise ValueError(
                f"--executor.type must be {', '.join(EXECUTORS[:-1])} or {EXECUTORS[-1]}, got {self.type!r}"
            )
        if self.tasks < 1:
            raise ValueError(f"--executor.tasks must be >= 1, got {self.tasks}")
        if self.workers == 0 or self.workers < -1:
            raise ValueError(f"--executor.workers must be >= 1 (or -1: all tasks at once), got {self.workers}")
        if self.type == "slurm" and not self.slurm.partition:
            raise ValueError(
                "--executor.type=slurm needs a partition: --executor.slurm.partition=<name> (sinfo lists them)"
            )


def logging_dir_of(opts: ConvertOptions, cfg: ExecutorOptions) -> Path:
    """The run's folder: `cfg.logging_dir`, else `<root>.datatrove` beside the target."""
    if cfg.logging_dir:
        return Path(cfg.logging_dir).expanduser().resolve()
    target = Path(opts.root).expanduser().resolve()
    return target.parent / f"{target.name}.datatrove"
