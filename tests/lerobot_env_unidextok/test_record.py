"""`unidextok-sim-record` writes where every writer may write, and only there: its destination is checked before
an episode is simulated, its temp folder is its own (two runs into one root never delete each other's), and bad
options are one line."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from linkerhand_udhm import subprocess_env

from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.record import RecordConfig, record
from lerobot_unidextok.data.destination import DestinationError, Kind, kind_of

BIN = Path(sys.executable).parent


def _record(*flags: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([str(BIN / "unidextok-sim-record"), "--hand=shadow", "--task=FingerPress-v0", *flags],
                            cwd=cwd, env=subprocess_env(OMP_NUM_THREADS="1", MUJOCO_GL="disable"), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip


def _converted_dataset(folder: Path) -> Path:
    """What `destination.kind_of` reads as a converted dataset: LeRobot's info.json and the conversion record."""
    (folder / "meta").mkdir(parents=True)
    (folder / "meta" / "info.json").write_text(json.dumps({"codebase_version": "v3.0"}))
    (folder / "meta" / "unidextok_conversion.json").write_text(json.dumps({"source": "lerobot"}))
    return folder


def _checkpoint(folder: Path) -> Path:
    folder.mkdir(parents=True)
    for name in ("config.json", "model.safetensors", "policy_preprocessor.json"):
        (folder / name).write_text("{}")
    return folder


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("make", [_converted_dataset, _checkpoint], ids=["converted_dataset", "checkpoint"])
def test_a_root_inside_a_dataset_or_a_checkpoint_is_refused_before_anything_runs(tmp_path, make):
    unit = make(tmp_path / "unit")
    before = _tree(unit)
    with pytest.raises(DestinationError, match=r"sits inside .* choose a --root outside it"):
        record(RecordConfig(hand="shadow", episodes=1, root=str(unit / "sim")))
    assert _tree(unit) == before and sorted(p.name for p in tmp_path.iterdir()) == ["unit"]


def test_the_cli_refuses_a_root_inside_a_converted_dataset_with_one_line(tmp_path):
    unit = _converted_dataset(tmp_path / "converted")
    r = _record("--episodes=1", f"--root={unit / 'sim'}", cwd=tmp_path)
    _, err = r.communicate(timeout=300)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and len(errors) == 1 and "Traceback" not in err, err[-2000:]
    assert "sits inside a dataset written by unidextok-convert" in errors[0]
    assert sorted(p.name for p in unit.iterdir()) == ["meta"]


def test_an_existing_dataset_is_replaced_only_with_overwrite_and_other_folders_never(tmp_path):
    first = record(RecordConfig(hand="shadow", task="FingerPress-v0", episodes=1, root=str(tmp_path / "sim"),
                                episode_length=5, keep_failures=True))  # fmt: skip
    assert kind_of(first.root) is Kind.DATASET and first.frames == 5
    assert not (first.root / "meta" / "unidextok_wrist_frame.json").exists()  # a press grasps nothing: no grasp centre
    before = _tree(tmp_path / "sim")
    with pytest.raises(DestinationError, match="already holds a LeRobot dataset: pass --overwrite=true"):
        record(RecordConfig(hand="shadow", task="FingerPress-v0", episodes=1, root=str(tmp_path / "sim")))
    assert _tree(tmp_path / "sim") == before
    again = record(RecordConfig(hand="shadow", task="FingerPress-v0", episodes=1, root=str(tmp_path / "sim"),
                                episode_length=7, keep_failures=True, overwrite=True))  # fmt: skip
    assert again.frames == 7 and _tree(tmp_path / "sim") != before
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "todo.txt").write_text("mine")
    with pytest.raises(DestinationError, match="holds other files, not a LeRobot dataset"):
        record(RecordConfig(hand="shadow", episodes=1, root=str(tmp_path / "notes"), overwrite=True))
    assert _tree(tmp_path / "notes") == {"todo.txt": b"mine"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes", "sim"]  # no temp folder left beside them


@pytest.mark.parametrize(("flag", "said"), [
    ("episode_length=0", "--episode_length must be >= 1 step"),
    ("episodes=0", "--episodes must be >= 1"),
    ("max_attempts_factor=0.5", "--max_attempts_factor must be >= 1"),
])  # fmt: skip
def test_bad_lengths_are_one_line_before_anything_runs(tmp_path, flag, said):
    key, value = flag.split("=")
    with pytest.raises(SimInputError, match=said):
        RecordConfig(hand="shadow", root=str(tmp_path / "sim"), **{key: type(getattr(RecordConfig, key))(value)})
    assert not any(tmp_path.iterdir())


def test_two_runs_into_one_new_root_never_delete_each_others_temp(tmp_path):
    """Before: both runs wrote `.<root>.record-tmp`, and the second deleted the first's as it started; the first
    died with a FileNotFoundError traceback, its recording lost. Now each run has its own temp, and the second
    is refused as it starts, with one line naming the run writing there (`destination.claim` sees the first's
    live temp folder); the first is left to finish its recording whole. The first run is paused (SIGSTOP) while
    the second starts, so they overlap for sure."""
    long = _record("--episodes=20", "--keep_failures=true", "--root=sim", cwd=tmp_path)
    deadline = time.time() + 120
    while not any(p.name.startswith(".sim") for p in tmp_path.iterdir()):
        assert long.poll() is None and time.time() < deadline, long.communicate()[1][-2000:]
        time.sleep(0.02)
    os.kill(long.pid, signal.SIGSTOP)
    try:
        short = _record("--episodes=1", "--keep_failures=true", "--episode_length=3", "--root=sim", cwd=tmp_path)
        _, short_err = short.communicate(timeout=300)
    finally:
        os.kill(long.pid, signal.SIGCONT)
    _, long_err = long.communicate(timeout=600)
    errors = [line for line in short_err.splitlines() if line.startswith("error:")]
    assert short.returncode == 2 and len(errors) == 1 and "Traceback" not in short_err, short_err[-2000:]
    assert f"is being written by another run now: pid {long.pid}" in errors[0], errors[0]
    assert long.returncode == 0 and "Traceback" not in long_err, long_err[-2000:]
    info = json.loads((tmp_path / "sim" / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 20  # the first run's dataset, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim"]  # neither run left a temp folder
