"""Sharded conversion on datatrove: the local executor equals a single-process conversion, re-runs resume,
the Slurm executor is built from the documented config and its scripts run with a stand-in scheduler."""

from __future__ import annotations

import json
import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import draccus
import numpy as np
import pyarrow.parquet as pq
import pytest

pytest.importorskip(
    "datatrove", reason="datatrove is an optional extra: pip install 'lerobot_policy_unidextok[datatrove]'"
)

from lerobot_unidextok.configs import shipped_config
from lerobot_unidextok.conversion.pipeline import (  # noqa: E402
    ConvertOptions,
    SetupError,
    convert,
    merge_shards,
)
from lerobot_unidextok.conversion.sharded import ExecutorOptions, SlurmOptions, convert_with_executor  # noqa: E402
from lerobot_unidextok.data import load_record
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS
from lerobot_unidextok.samples.formats import write_samples  # noqa: E402
from lerobot_unidextok.scripts.convert import ConvertConfig, run  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SOURCE = "lerobot"  # whole robot: 14 arm passthrough columns + two Inspire hands, state and action
NUM_EPISODES = 7  # odd: the two shards differ in size


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    return write_samples(
        tmp_path_factory.mktemp("raw"), sources=[SOURCE], episodes_per_source=NUM_EPISODES, frames_per_episode=30
    )[SOURCE]


def _options(raw: Path, root: Path, **kw) -> ConvertOptions:
    return ConvertOptions(
        source=SOURCE,
        input=raw,
        root=root,
        repo_id="t/g1",
        source_options=SAMPLE_SOURCE_OPTIONS[SOURCE],
        progress=False,
        **kw,
    )


@pytest.fixture(scope="module")
def single(raw, tmp_path_factory) -> Path:
    """The reference: one process, no shards."""
    root = tmp_path_factory.mktemp("single") / "g1"
    convert(_options(raw, root))
    return root


def _table(root: Path):
    return pq.read_table(sorted((root / "data").rglob("*.parquet"))).replace_schema_metadata(None)


def assert_same_dataset(single: Path, merged: Path) -> None:
    """Same frames (every column), same episodes and split records, same info, stats within float tolerance."""
    a, b = _table(single), _table(merged)
    assert a.column_names == b.column_names and a.num_rows == b.num_rows
    for col in a.column_names:  # aggregate writes list<> instead of fixed_size_list<>: compare values
        assert a.column(col).to_pylist() == b.column(col).to_pylist(), col
    sa, sb = load_record(single).to_dict(), load_record(merged).to_dict()
    assert sb["test_episodes"] == sa["test_episodes"] and sa["test_episodes"]
    assert sb["episodes"] == sa["episodes"]  # sources, splits, lengths, source episode indices, in order
    assert sb["native_layout"] == sa["native_layout"]
    ia, ib = (json.loads((r / "meta/info.json").read_text()) for r in (single, merged))
    for key in ("total_episodes", "total_frames", "total_tasks", "fps", "splits", "robot_type"):
        assert ia[key] == ib[key], key
    assert {k: v["shape"] for k, v in ia["features"].items()} == {k: v["shape"] for k, v in ib["features"].items()}
    st_a, st_b = (json.loads((r / "meta/stats.json").read_text()) for r in (single, merged))
    assert st_a.keys() == st_b.keys()
    for feature, stats in st_a.items():
        assert stats.keys() == st_b[feature].keys(), feature
        for name, value in stats.items():
            np.testing.assert_allclose(st_b[feature][name], value, rtol=1e-6, atol=1e-9, err_msg=f"{feature}/{name}")


def test_merge_shards_stats_equal_single_run(raw, single, tmp_path):
    """Catches LeRobot 0.6.1's aggregate_datasets leaving meta/stats.json of index / episode_index /
    task_index at the shard-local values (merged index mean was about half the single-run mean)."""
    shards = [tmp_path / f"shard{k}" for k in range(2)]
    for k, shard in enumerate(shards):
        convert(_options(raw, shard, shard_index=k, num_shards=2))
    merged = merge_shards(shards, tmp_path / "merged", repo_id="t/g1")
    assert_same_dataset(single, merged)
    robot_type = json.loads((raw / "meta/info.json").read_text())["robot_type"]
    assert robot_type and json.loads((merged / "meta/info.json").read_text())["robot_type"] == robot_type  # not "udhm"


def test_local_executor_two_tasks_equals_single_process(raw, single, tmp_path):
    """datatrove LocalPipelineExecutor, 2 tasks on 2 worker processes, then the merge task."""
    from lerobot.datasets import LeRobotDataset

    root = tmp_path / "g1"
    out = convert_with_executor(_options(raw, root), ExecutorOptions(type="local", tasks=2, workers=2))
    assert out == root.resolve()
    assert_same_dataset(single, root)
    assert LeRobotDataset("t/g1", root=root).num_frames == _table(single).num_rows
    logs = tmp_path / "g1.datatrove"
    assert sorted(p.name for p in (logs / "convert" / "completions").iterdir()) == ["00000", "00001"]
    assert (logs / "merge" / "completions" / "00000").is_file()
    assert not (logs / "shards").exists()  # removed after a successful merge
    stats = json.loads((logs / "convert" / "stats.json").read_text())
    assert "episodes" in json.dumps(stats)  # our step's counters reach datatrove's stats

    with pytest.raises(FileExistsError, match="--overwrite=true"):
        convert_with_executor(_options(raw, root), ExecutorOptions(type="local", tasks=2, workers=1))


def test_rerun_resumes_completed_shards_and_refuses_other_settings(raw, single, tmp_path):
    """An interrupted run (only task 0 done) resumes: task 0 is not redone, task 1 and the merge run."""
    from datatrove.executor import LocalPipelineExecutor

    from lerobot_unidextok.conversion.datatrove import ConvertShard, shard_roots

    root = tmp_path / "g1"
    logs = tmp_path / "g1.datatrove"
    opts = _options(raw, root)
    cfg = ExecutorOptions(type="local", tasks=2, workers=1)
    # the first run: this machine ran task 0 of 2 and stopped
    from lerobot_unidextok.conversion import sharded

    sharded._claim_logging_dir(logs, sharded._run_settings(opts, cfg, 2), overwrite=False)
    first = LocalPipelineExecutor(
        [ConvertShard(opts, logs / "shards")], tasks=2, workers=1, local_tasks=1, logging_dir=str(logs / "convert")
    )
    first.run()
    assert (shard_roots(logs / "shards", 2)[0] / "meta" / "info.json").is_file()
    assert not (logs / "convert" / "completions" / "00001").exists()

    with pytest.raises(SetupError, match=r"other settings \(test_fraction differ\).*--overwrite=true"):
        convert_with_executor(_options(raw, root, test_fraction=0.3), cfg)

    convert_with_executor(opts, cfg)
    assert_same_dataset(single, root)
    log0 = (logs / "convert" / "logs" / "task_00000.log").read_text()
    assert log0.count("Launching pipeline for rank=0") == 1  # task 0 ran once: resumed, not redone
    assert (logs / "convert" / "logs" / "task_00001.log").is_file()


def test_slurm_executor_from_documented_config(raw, tmp_path):
    """configs/convert/slurm.yaml (draccus, as the CLI reads it) builds both Slurm executors; no cluster."""
    from lerobot_unidextok.conversion.datatrove import build_executors

    cfg = draccus.parse(
        ConvertConfig,
        config_path=str(shipped_config("convert/slurm")),
        args=[f"--input={raw}", f"--root={tmp_path / 'egodex_udhm'}", "--executor.slurm.sbatch_args={account: lab}"],
    )
    ex = cfg.executor
    assert ex.type == "slurm" and ex.tasks == 64 and cfg.num_workers == ex.slurm.cpus_per_task
    opts = ConvertOptions(source=cfg.source, input=cfg.input, root=cfg.root, num_workers=cfg.num_workers)
    convert_exec, merge_exec = build_executors(opts, ex)
    assert merge_exec.depends is convert_exec and convert_exec.world_size == 64 and merge_exec.world_size == 1

    args = convert_exec.get_sbatch_args(max_array=64)
    assert args["partition"] == "cpu" and args["time"] == "08:00:00" and args["cpus-per-task"] == 8
    assert args["array"] == "0-63%32" and args["mem-per-cpu"] == "2G" and args["account"] == "lab"
    assert args["job-name"] == "egodex-udhm" and merge_exec.get_sbatch_args()["job-name"] == "egodex-udhm-merge"
    script = convert_exec.get_launch_file_contents(args, "launch_pickled_pipeline executor.pik")
    assert script.startswith("#!/bin/bash\n#SBATCH --cpus-per-task=8\n")
    assert "#SBATCH --array=0-63%32" in script and "#SBATCH --account=lab" in script
    assert f"source {Path(sys.prefix) / 'bin' / 'activate'}" in script  # compute nodes get this environment
    step = convert_exec.pipeline[0]
    assert step.options["num_workers"] == 8 and step.options["source"] == "egodex"
    assert step.shards_dir == str(tmp_path / "egodex_udhm.datatrove" / "shards")

    with pytest.raises(ValueError, match="--executor.slurm.partition"):
        ExecutorOptions(type="slurm", slurm=SlurmOptions(partition=""))


_STAND_INS = {
    # sbatch: keep the script and its arguments, answer like sbatch
    "sbatch": """#!/bin/bash
n=$(ls "$FAKE_SLURM"/*.sh 2>/dev/null | wc -l); id=$((1000 + n))
cp "${@: -1}" "$FAKE_SLURM/$id.sh"; printf '%s\\n' "${@:1:$#-1}" > "$FAKE_SLURM/$id.args"
echo "Submitted batch job $id"
""",
    # srun -l -n 1 <command...>: run the command here
    "srun": """#!/bin/bash
while [[ "$1" == -* ]]; do case "$1" in -n|-N) shift 2;; *) shift;; esac; done
exec "$@"
""",
    "scontrol": "#!/bin/bash\necho localhost\n",  # scontrol show hostnames <list>
}


@pytest.mark.slow
def test_slurm_path_runs_with_stand_in_scheduler(raw, single, tmp_path, monkeypatch):
    """The CLI submits through datatrove's SlurmPipelineExecutor; sbatch / srun / scontrol stand-ins record
    the jobs, then each array task's script runs here as Slurm would run it. Same result as one process."""
    bin_dir, jobs = tmp_path / "bin", tmp_path / "jobs"
    bin_dir.mkdir()
    jobs.mkdir()
    for name, text in _STAND_INS.items():
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(stat.S_IRWXU)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setenv("FAKE_SLURM", str(jobs))
    root = tmp_path / "g1"
    cfg = ConvertConfig(
        source=SOURCE,
        input=str(raw),
        root=str(root),
        repo_id="t/g1",
        source_options=json.dumps(SAMPLE_SOURCE_OPTIONS[SOURCE]),
        executor=ExecutorOptions(
            type="slurm", tasks=2, slurm=SlurmOptions(partition="cpu", time="00:10:00", cpus_per_task=1)
        ),
    )
    assert run(cfg) == 0
    assert not root.exists()  # submitted, not run
    submitted = {int(p.stem): (p.read_text(), (jobs / f"{p.stem}.args").read_text()) for p in jobs.glob("*.sh")}
    convert_job, merge_job = (
        next(i for i, (s, _) in sorted(submitted.items()) if f"--job-name={name}\n" in s)
        for name in ("unidextok-convert", "unidextok-convert-merge")
    )
    convert_script, _ = submitted[convert_job]
    merge_script, merge_args = submitted[merge_job]
    assert "#SBATCH --array=0-1\n" in convert_script and "#SBATCH --partition=cpu" in convert_script
    assert f"--dependency=afterok:{convert_job}" in merge_args  # the merge waits for every shard task
    assert "launch_pickled_pipeline" in convert_script

    def run_job(job_id: int, script: str, array_index: int) -> None:
        env = dict(os.environ, SLURM_ARRAY_TASK_ID=str(array_index), SLURM_JOB_ID=str(job_id), RUN_OFFSET="0",
                   SLURM_NODELIST="localhost")  # fmt: skip
        done = subprocess.run(["bash", "-c", script], env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-3000:]

    for k in range(int(re.search(r"--array=0-(\d+)", convert_script).group(1)) + 1):
        run_job(convert_job, convert_script, k)
    run_job(merge_job, merge_script, 0)
    assert_same_dataset(single, root)


def test_cli_local_executor_and_clear_errors(raw, single, tmp_path, capsys, monkeypatch):
    """--executor.type=local from the CLI (workers=1: tasks one after the other in this process); flag
    mistakes exit 2 with one line naming the fix, before any task starts."""
    from lerobot_unidextok.scripts.convert import main

    def cli(*flags: str) -> int:
        monkeypatch.setattr(sys, "argv", ["unidextok-convert", *flags])
        with pytest.raises(SystemExit) as exit_info:
            main()
        return exit_info.value.code

    base = dict(source=SOURCE, input=str(raw), repo_id="t/g1", source_options=json.dumps(SAMPLE_SOURCE_OPTIONS[SOURCE]))
    flags = [f"--source={SOURCE}", f"--input={raw}", "--repo_id=t/g1"]
    root = tmp_path / "g1"
    local = ExecutorOptions(type="local", tasks=3, workers=1)
    assert run(ConvertConfig(**base, root=str(root), executor=local)) == 0
    out = capsys.readouterr().out
    assert f"wrote {root}: {NUM_EPISODES} episodes" in out and "--dataset.episodes=" in out
    assert_same_dataset(single, root)

    with pytest.raises(ConfigError, match="drop --shard_index/--num_shards"):
        run(ConvertConfig(**base, root=str(tmp_path / "a"), executor=local, shard_index=1, num_shards=2))
    assert cli(*flags, f"--root={tmp_path / 'b'}", "--executor.type=slurm") == 2
    assert "--executor.slurm.partition" in capsys.readouterr().err
    assert cli(*flags, f"--root={tmp_path / 'c'}", "--executor.type=ray") == 2
    assert "--executor.type must be pool, local or slurm" in capsys.readouterr().err
    assert cli(*flags, f"--root={tmp_path / 'c'}", "--executor=slurm") == 2  # the old spelling: read as a type
    err = capsys.readouterr().err
    assert "note: --executor is now --executor.type" in err and "--executor.slurm.partition" in err
    assert cli(*flags, f"--root={tmp_path / 'c'}", "--executor.slurm=local") == 2  # a group of flags, not a value
    assert "--executor.slurm.<field>=..." in capsys.readouterr().err
    bad = dict(base, source_options='{"hands": {"left": "no_such_hand:kLeftHand"}}')
    with pytest.raises(SetupError, match="no_such_hand"):
        run(ConvertConfig(**bad, root=str(tmp_path / "d"), executor=ExecutorOptions(type="local")))
    assert not (tmp_path / "d.datatrove").exists()  # set-up failed before the run folder was claimed
    assert not any((tmp_path / name).exists() for name in ("b", "b.datatrove", "c", "c.datatrove"))


def test_old_executor_flags_are_read_for_one_release_with_a_note(capsys):
    """`unidextok-convert --executor=local --tasks=4 --workers=2`, documented until the executor options became a
    group, now reads as --executor.type/.tasks/.workers with one note per flag."""
    from lerobot_unidextok.scripts.convert import renamed_flags

    args = renamed_flags(["--source=x", "--executor=local", "--tasks=4", "--workers=2", "--executor={type: local}"])
    assert args == ["--source=x", "--executor.type=local", "--executor.tasks=4", "--executor.workers=2",
                    "--executor={type: local}"]  # fmt: skip
    notes = capsys.readouterr().err.splitlines()
    assert len(notes) == 3 and notes[0].startswith("note: --executor is now --executor.type")


def test_missing_datatrove_is_a_setup_error_with_the_install_command(raw, tmp_path, monkeypatch):
    """Without the extra, --executor.type=local says which package to install instead of a traceback."""
    monkeypatch.setitem(sys.modules, "lerobot_unidextok.conversion.datatrove", None)  # import fails
    with pytest.raises(SetupError, match=r"pip install 'lerobot_policy_unidextok\[datatrove\]'"):
        convert_with_executor(_options(raw, tmp_path / "g1"), ExecutorOptions(type="local"))
    assert not (tmp_path / "g1").exists() and not (tmp_path / "g1.datatrove").exists()
