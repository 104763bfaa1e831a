"""Nothing lost, nothing silently wrong: NaN in an arm column, a conversion killed with SIGKILL or SIGTERM while
its workers run (real subprocesses and signals, bounded in time)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from lerobot_unidextok.conversion.pipeline import ConversionError, ConvertOptions, convert
from lerobot_unidextok.conversion.validate import validate_dataset
from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples

BIN = Path(sys.executable).parent
G1_OPTIONS = SAMPLE_SOURCE_OPTIONS["lerobot"]


@pytest.fixture(scope="module")
def g1_raw(tmp_path_factory) -> Path:
    """The synthetic G1-like LeRobot v2.1 recording (arms + two Inspire hands)."""
    return write_samples(tmp_path_factory.mktemp("raw"), sources=["lerobot"], episodes_per_source=3,
                         frames_per_episode=30)["lerobot"]  # fmt: skip


def _nan_in_an_arm(raw: Path, episode: int, frames: list[int]) -> None:
    path = raw / "data" / "chunk-000" / f"episode_{episode:06d}.parquet"
    table = pq.read_table(path)
    state = np.stack(table.column("observation.state").to_pylist()).astype(np.float32)
    state[frames, 2] = np.nan  # the left shoulder yaw, a passthrough column
    column = pa.array(state.tolist(), type=table.schema.field("observation.state").type)
    pq.write_table(table.set_column(table.schema.get_field_index("observation.state"), "observation.state", column),
                   path)  # fmt: skip


def test_nan_in_an_arm_column_is_refused_naming_the_column_and_frames(g1_raw, tmp_path):
    raw = tmp_path / "raw"
    shutil.copytree(g1_raw, raw)
    _nan_in_an_arm(raw, 1, [4, 5])
    with pytest.raises(ConversionError, match=r"NaN/inf in observation.state columns \['kLeftShoulderYaw'\] at "
                                              r"frames \[4, 5\].*--on_error=skip"):  # fmt: skip
        convert(ConvertOptions(source="lerobot", input=raw, root=tmp_path / "out", source_options=G1_OPTIONS,
                               progress=False))  # fmt: skip
    assert not (tmp_path / "out").exists()
    report = convert(ConvertOptions(source="lerobot", input=raw, root=tmp_path / "skip", source_options=G1_OPTIONS,
                                    on_error="skip", progress=False))  # fmt: skip
    assert report.num_episodes == 2 and "kLeftShoulderYaw" in report.failures[0].reason
    assert validate_dataset(tmp_path / "skip").ok


def test_the_validator_finds_nan_in_a_passthrough_column(g1_raw, tmp_path):
    root = tmp_path / "out"
    convert(ConvertOptions(source="lerobot", input=g1_raw, root=root, source_options=G1_OPTIONS, progress=False))
    data = sorted((root / "data").rglob("*.parquet"))[0]
    table = pq.read_table(data)
    state = np.stack(table.column("observation.state").to_pylist())
    state[7, 0] = np.inf
    column = pa.FixedSizeListArray.from_arrays(pa.array(state.reshape(-1), pa.float32()), state.shape[1])
    pq.write_table(table.set_column(table.schema.get_field_index("observation.state"), "observation.state", column),
                   data)  # fmt: skip
    report = validate_dataset(root, load=False)
    check = next(c for c in report.checks if c.name == "every numeric column finite")
    assert not report.ok and not check.ok and "kLeftShoulderPitch" in check.detail and "frame 7" in check.detail


def _session_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _start_conversion(raw: Path, root: Path) -> subprocess.Popen:
    cmd = [str(BIN / "unidextok-convert"), "--source=lerobot", f"--input={raw}", f"--root={root}",
           f"--source_options={json.dumps(G1_OPTIONS)}", "--num_workers=2", "--progress=false"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # the workers are up once the first episodes are being written
        if list(root.parent.glob(f".{root.name}.tmp-*")) and len(_children(proc.pid)) >= 2:
            return proc
        if proc.poll() is not None:
            pytest.fail(f"the conversion ended before it could be killed: {proc.stderr.read()[-2000:]}")
        time.sleep(0.2)
    proc.kill()
    pytest.fail("the conversion did not start its workers within 120 s")


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "-g", str(os.getpgid(pid))], capture_output=True, text=True)
    return [int(p) for p in out.stdout.split() if int(p) != pid]


@pytest.fixture(scope="module")
def long_raw(tmp_path_factory) -> Path:
    """Enough episodes that a 2-worker conversion is still running when it is killed."""
    return write_samples(tmp_path_factory.mktemp("long"), sources=["lerobot"], episodes_per_source=40,
                         frames_per_episode=200)["lerobot"]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_killed_conversion_leaves_no_process_and_no_folder(long_raw, tmp_path, sig):
    """SIGTERM is handled like Ctrl-C (temp folder removed, exit 143); after SIGKILL, which runs no code, the
    forkserver and the workers still end, and the next run removes the temp folder of the dead one."""
    root = tmp_path / "out"
    for _ in range(3):  # on a loaded machine the run can finish between the check that it runs and the signal
        proc = _start_conversion(long_raw, root)
        pgid = os.getpgid(proc.pid)
        os.kill(proc.pid, sig)
        proc.wait(timeout=60)
        if proc.returncode != 0:
            break
        shutil.rmtree(root)  # it finished first: nothing was killed, try again
    assert proc.returncode != 0, "the conversion finished before the signal three times"
    deadline = time.monotonic() + 45  # normally a second or two; generous for a loaded machine
    while _session_alive(pgid) and time.monotonic() < deadline:
        time.sleep(0.2)
    leftover = _children(proc.pid) if _session_alive(pgid) else []
    if leftover:
        os.killpg(pgid, signal.SIGKILL)
    assert not leftover, f"processes of the killed conversion still alive: {leftover}"
    assert not root.exists()
    if sig == signal.SIGTERM:
        assert proc.returncode == 143 and "terminated (SIGTERM)" in proc.stderr.read()
        assert not list(tmp_path.glob(".out.tmp-*"))
    else:
        assert list(tmp_path.glob(".out.tmp-*"))  # SIGKILL runs no clean-up ...
        from lerobot_unidextok.utils.files import recover_folder

        recover_folder(root)  # ... the next run's removes it
        assert not list(tmp_path.glob(".out.tmp-*"))


DEAD = 999999999  # no such process


@pytest.mark.parametrize("writer", ["convert", "mix"])
def test_a_kill_between_the_renames_of_an_overwrite_is_restored_on_the_next_run(g1_raw, tmp_path, caplog, writer):
    """The state an overwrite killed between its two renames leaves: the root missing, the old dataset set aside
    (`.<root>.old-<pid>-*`), the finished new one in `.<root>.tmp-<pid>-*`. The next run removed both, and when
    it then failed nothing was left. Now it puts the old dataset back first, keeps the new one beside it, says
    so, and a failing run leaves both."""
    import logging

    from lerobot_unidextok.conversion.mix import MixOptions, mix
    from lerobot_unidextok.errors import UserError

    source = tmp_path / "g1"
    convert(ConvertOptions(source="lerobot", input=g1_raw, root=source, progress=False, source_options=G1_OPTIONS))
    root = tmp_path / "out"
    if writer == "convert":
        convert(ConvertOptions(source="lerobot", input=g1_raw, root=root, progress=False, source_options=G1_OPTIONS))
    else:
        mix(MixOptions(inputs=[str(source)], root=str(root), progress=False))
    info = (root / "meta" / "info.json").read_text()
    shutil.copytree(root, tmp_path / f".out.tmp-{DEAD}-bbbb")  # the killed run's finished output
    root.rename(tmp_path / f".out.old-{DEAD}-aaaa")

    with caplog.at_level(logging.WARNING), pytest.raises(UserError):  # the next run fails (a bad option) ...
        if writer == "convert":
            convert(ConvertOptions(source="lerobot", input=g1_raw, root=root, overwrite=True, progress=False,
                                   source_options={"hands": "no_such_hand"}))  # fmt: skip
        else:
            mix(MixOptions(inputs=[str(source), str(tmp_path / "nowhere")], root=str(root), overwrite=True,
                           progress=False))  # fmt: skip
    assert (root / "meta" / "info.json").read_text() == info  # ... and the dataset is back in place
    assert (tmp_path / f"out.unfinished-{DEAD}" / "meta" / "info.json").is_file()
    assert "out restored: a run (pid 999999999) was killed while replacing it" in caplog.text
    assert not list(tmp_path.glob(".out.*"))
