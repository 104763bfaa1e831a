"""The destinations of every writer, as one table (issue 45): each writer crossed with each kind of destination and
each leftover state. A cell is either one clear refusal (a `DestinationError`, which every CLI prints as one
`error:` line and exit status 2) with nothing changed, or a correct result. Adding a writer is adding a row.

How the cells run, to keep the table fast (130 cells and the commands: 27 s on a loaded 2-core machine):
- Every cell calls `data.destination.claim` / `claim_files` exactly as that writer does before it writes (its kind,
  flag, inputs, `overwrite` / `resume`; `WRITERS` below, each with the module it mirrors). The destinations are
  folders with the files `kind_of` recognises (a dataset's `meta/info.json` and conversion record, a checkpoint's
  `config.json` + weights...), which is all `claim` reads.
- A representative subset runs the real CLIs' `main()` (`test_the_real_commands`): convert, mix, eval and the
  sharded conversion's `--executor.logging_dir`, on the smallest sample input the conversion tests use.
- The destination's lock (`.<name>.lock`, taken by a folder writer's claim): the column `live run's lock` holds it
  from another open file (flock conflicts between open files, also within one process); two real processes run
  in `test_a_second_writer_is_refused_as_it_starts_and_a_killed_ones_lock_is_taken_over`.
- `unidextok-sim-record` (owned by another change right now) is the row `sim-record`: `claim(root, Kind.DATASET,
  flag="--root")` without overwrite, the call its record module is being routed through.
- A read-only parent: we run as root, which `chmod` does not stop, so the cell runs in a child process in its own
  mount namespace where the parent is bind-mounted read-only (`unshare -m`, a real read-only file system); as
  another user, `chmod 0555` does it in this process. Where neither works the cell is skipped, saying why.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from lerobot_unidextok.data.destination import DestinationError, Kind, claim, claim_files, lock_path, release

DEAD = 999999999  # no such process
COLUMNS = ("input", "dataset", "converted", "checkpoint", "run", "logging", "user", "empty", "own", "read-only parent",
           "file as parent", "dead run's leftovers", "dead run's leftovers, root made empty",
           "live run's leftovers", "live run's lock", "dead run's lock")  # fmt: skip


# ---------------------------------------------------------------------------------------------
# the sandbox: one of each kind of folder
# ---------------------------------------------------------------------------------------------
def _dataset(root: Path, source: str | None) -> Path:
    (root / "meta").mkdir(parents=True)
    (root / "meta" / "info.json").write_text("{}")
    if source is not None:
        (root / "meta" / "unidextok_conversion.json").write_text(json.dumps({"source": source}))
    (root / "data").mkdir()
    (root / "data" / "episode_0.parquet").write_bytes(b"rows")
    return root


def _checkpoint(root: Path, policy: bool) -> Path:
    root.mkdir(parents=True)
    for name in ("config.json", "model.safetensors", *(["policy_preprocessor.json"] if policy else [])):
        (root / name).write_text("{}")
    return root


def build_sandbox(base: Path) -> None:
    """Everything a cell may point at, under `base`."""
    (base / "raw" / "data").mkdir(parents=True)
    (base / "raw" / "data" / "episode_0.h5").write_bytes(b"source")
    _dataset(base / "converted", "lerobot")  # the input of the writers that read a converted dataset
    _dataset(base / "converted2", "lerobot")  # another one, not an input
    _dataset(base / "plain", None)  # a LeRobot dataset without a conversion record (a recording)
    _checkpoint(base / "policy_in", policy=True)  # deploy's input
    _checkpoint(base / "policy", policy=True)
    _checkpoint(base / "run" / "best", policy=False)
    (base / "run" / "eval.json").write_text(json.dumps({"per_hand": {}, "overall": {}, "training": {}}))
    (base / "logs" / "convert").mkdir(parents=True)
    (base / "logs" / "run_settings.json").write_text(json.dumps({"executor": "local", "num_shards": 2, "root": "x"}))
    (base / "user").mkdir()
    (base / "user" / "notes.txt").write_text("mine")
    (base / "empty").mkdir()
    (base / "ro").mkdir()
    (base / "afile").write_text("a file")


def tree_hash(base: Path) -> dict[str, str]:
    """Every path under `base` (hidden ones too) -> sha1 of its bytes ("dir" for a folder)."""
    return {str(p.relative_to(base)): "dir" if p.is_dir() else hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(base.rglob("*"))}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# the writers: how each claims its destination
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Writer:
    mirrors: str  # where the writer claims
    claim: Callable[[Path, Path], object]  # (destination, sandbox) -> claims as the writer does
    input: str | None  # the sandbox folder it reads (its "input" column), if any
    own: Callable[[Path], Path]  # makes what this writer wrote before, returns the destination naming it
    # one letter per column: E = refused, nothing changed; o = a correct result; R = the dead run's folder
    # restored (nothing lost), then refused as an existing output (a writer without --overwrite); - = no such cell.
    # A folder writer's claim takes the destination's lock (`.<name>.lock` beside it), which the cell releases.
    expected: str
    folder: bool = True  # writes a folder (`claim`: recovers leftovers), else files (`claim_files`)


def _eval_claim(dest: Path, base: Path):
    from lerobot_unidextok.evaluation.report import claim_report
    from lerobot_unidextok.scripts.eval import refuse_a_training_report, report_stem

    stem = report_stem(str(dest))
    refuse_a_training_report(stem)
    return claim_report(stem, inputs=[base / "converted"])


def _own_report(base: Path) -> Path:
    (base / "reports").mkdir()
    (base / "reports" / "eval.json").write_text(json.dumps({"per_hand": {}, "overall": {}}))
    (base / "reports" / "eval.md").write_text("| hand |")
    return base / "reports"


def _own_video(base: Path) -> Path:
    (base / "clip.mp4").write_bytes(b"an earlier render")
    return base / "clip.mp4"


WRITERS: dict[str, Writer] = {
    # columns: input dataset converted checkpoint run logging user empty own ro-parent file-parent dead dead+empty live
    "convert": Writer(
        "conversion/pipeline.py checked_paths (--overwrite=true)",
        lambda d, b: claim(d, Kind.CONVERTED, inputs=[b / "raw"], overwrite=True),
        "raw", lambda b: b / "converted2", "EEoEEEEooEEooEEo"),
    "mix": Writer(
        "conversion/mix.py mix (--overwrite=true)",
        lambda d, b: claim(d, Kind.MIX, inputs=[b / "converted"], overwrite=True),
        "converted", lambda b: _dataset(b / "mixed", "mix"), "EEEEEEEooEEooEEo"),
    "train run folder": Writer(
        "training/run.py claim_run_folder (--overwrite=true)",
        lambda d, b: claim(d, Kind.TOKENIZER_RUN, inputs=[b / "converted"], overwrite=True, flag="--output_dir"),
        "converted", lambda b: b / "run", "EEEEoEEooEEooEEo"),
    "logging dir": Writer(
        "conversion/sharded.py _check_logging_dir (--overwrite=true)",
        lambda d, b: _logging_claim(d, b),
        "raw", lambda b: b / "logs", "EEEEEoEooEEooEEo"),
    "eval output": Writer(
        "scripts/eval.py run: report_stem, refuse_a_training_report, claim_report",
        _eval_claim, "converted", _own_report, "EEEEEooooEEooooo", folder=False),
    "deploy": Writer(
        "policies/deploy.py (no --overwrite)",
        lambda d, b: claim(d, Kind.POLICY, inputs=[b / "policy_in", b / "converted"], flag="--output"),
        "policy_in", lambda b: b / "policy", "EEEEEEEoEEERREEo"),
    "view": Writer(
        "scripts/view.py view_cli (.mp4)",
        lambda d, b: claim_files([d], is_ours=lambda p: p.suffix.lower() == ".mp4"),
        "converted", _own_video, "EEEEEEEEoEEoEEoo", folder=False),
    "sim-record": Writer(
        "lerobot_env_unidextok/record.py (routed through claim, no --overwrite)",
        lambda d, b: claim(d, Kind.DATASET, flag="--root"),
        None, lambda b: b / "plain", "-EEEEEEoEEERREEo"),
}


def _logging_claim(dest: Path, base: Path):
    from lerobot_unidextok.conversion.sharded import _check_logging_dir

    return _check_logging_dir(dest, [base / "raw", base / "out"], overwrite=True)


def destination(writer: Writer, column: str, base: Path) -> Path:
    """The path a cell gives the writer, after making the state the column names."""
    if column == "input":
        return base / writer.input
    if column == "own":
        return writer.own(base)
    named = {"dataset": "plain", "converted": "converted2", "checkpoint": "policy", "run": "run", "logging": "logs",
             "user": "user", "empty": "empty"}  # fmt: skip
    if column in named:
        return base / named[column]
    if column == "read-only parent":
        return base / "ro" / "new"
    if column == "file as parent":
        return base / "afile" / "new"
    if column.startswith("dead run's leftovers"):  # this writer killed between the two renames of its replacing `new`
        own = writer.own(base) if writer.folder else base / "converted2"
        shutil.copytree(own, base / f".new.old-{DEAD}-abcd1234")
        shutil.copytree(own, base / f".new.tmp-{DEAD}-abcd1234")
        (base / f".new.tmp-{DEAD}-abcd1234" / "written_by_the_new_run").write_bytes(b"the new one")
        if column.endswith("root made empty"):  # then a script's `mkdir -p new`
            (base / "new").mkdir()
        return base / "new"
    if column == "live run's leftovers":  # a run writing `new` now: this test's parent started before it
        (base / f".new.tmp-{os.getppid()}-abcd1234").mkdir()
        return base / "new"
    if column == "live run's lock":  # a run that claimed `new` and still reads its inputs: no temp folder yet
        _LIVE_LOCKS.append(_hold_lock(base / "new"))
        return base / "new"
    if column == "dead run's lock":  # the lock file of a run killed after its claim (nothing holds it)
        lock_path(base / "new").write_text(str(DEAD))
        return base / "new"
    raise AssertionError(column)


_LIVE_LOCKS: list[int] = []  # lock file descriptors held by "another run" (another open file: flock conflicts)


def _hold_lock(target: Path) -> int:
    """Hold the lock of `target` as another writer would (its own open file), naming this test's parent's pid."""
    import fcntl

    fd = os.open(lock_path(target), os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.pwrite(fd, str(os.getppid()).encode(), 0)
    return fd


CELLS = [(name, column) for name in WRITERS for column in COLUMNS]


def test_the_table_has_one_letter_per_column():
    assert all(len(w.expected) == len(COLUMNS) and set(w.expected) <= set("EoR-") for w in WRITERS.values())


def run_cell(name: str, column: str, base: Path, dest: Path) -> str:
    """"ok" or "error: <message>" for one cell, calling the writer's claim."""
    try:
        WRITERS[name].claim(dest, base)
    except DestinationError as exc:
        return f"error: {exc}"
    finally:
        while _LIVE_LOCKS:
            os.close(_LIVE_LOCKS.pop())
    if WRITERS[name].folder:  # the claim took the lock, which the writer releases when its output is in place
        assert lock_path(dest.expanduser().resolve()).read_text() == str(os.getpid())
        release(dest)
        assert not lock_path(dest.expanduser().resolve()).exists()
    return "ok"


@pytest.mark.parametrize("name, column", CELLS, ids=[f"{n}|{c}" for n, c in CELLS])
def test_cell(name, column, tmp_path):
    writer = WRITERS[name]
    expected = writer.expected[COLUMNS.index(column)]
    if expected == "-":
        pytest.skip(f"{name} has no {column}")
    base = tmp_path / "sandbox"
    base.mkdir()
    build_sandbox(base)
    dest = destination(writer, column, base)
    before = tree_hash(base)
    if column == "read-only parent":
        outcome = _run_read_only(name, column, base, dest)
    else:
        outcome = run_cell(name, column, base, dest)
    after = tree_hash(base)
    if expected in "ER":
        assert outcome.startswith("error: ") and "\n" not in outcome, outcome
        flags = {"eval output": "--output", "view": "--output", "deploy": "--output",
                 "train run folder": "--output_dir", "logging dir": "--executor.logging_dir"}  # fmt: skip
        flag = flags.get(name, "--root")
        assert outcome.startswith(f"error: {flag} "), outcome  # names the flag the user gave
    else:
        assert outcome == "ok", outcome
    if column.startswith("dead run's leftovers") and writer.folder:
        # the set-aside folder is back in place, the finished new one kept beside it, nothing deleted
        assert (base / "new").is_dir() and not (base / "new" / "written_by_the_new_run").exists()
        assert (base / f"new.unfinished-{DEAD}" / "written_by_the_new_run").read_bytes() == b"the new one"
        if column.endswith("root made empty"):
            del before["new"]  # the empty folder made after the kill gave way to the restored one
        assert sorted(after.values()) == sorted(before.values())
        assert not [p for p in base.iterdir() if p.name.startswith(".new.")]
    elif column == "dead run's lock":  # taken over, then released: the dead run's lock file is gone, nothing else
        assert after == {k: v for k, v in before.items() if k != ".new.lock"} or not writer.folder
    else:
        assert after == before  # refused: nothing changed; passed: a claim changes nothing (replaced at the end)
    if column == "live run's lock" and expected == "E":
        assert f"being written by another run now: pid {os.getppid()}" in outcome, outcome


# ---------------------------------------------------------------------------------------------
# a read-only parent
# ---------------------------------------------------------------------------------------------
def _run_read_only(name: str, column: str, base: Path, dest: Path) -> str:
    ro = base / "ro"
    if os.geteuid() != 0:
        ro.chmod(0o555)
        try:
            return run_cell(name, column, base, dest)
        finally:
            ro.chmod(0o755)
    if shutil.which("unshare") is None:
        pytest.skip("running as root without unshare: no way to make a read-only folder here")
    script = (f"mount --bind '{ro}' '{ro}' && mount -o remount,bind,ro '{ro}' && "
              f"exec '{sys.executable}' '{__file__}' '{name}' '{column}' '{base}' '{dest}'")  # fmt: skip
    proc = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True, timeout=120)
    if "mount" in proc.stderr and proc.returncode != 0 and "error:" not in proc.stdout:
        pytest.skip(f"cannot mount a read-only folder here: {proc.stderr.strip()[:200]}")
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip().splitlines()[-1]


# ---------------------------------------------------------------------------------------------
# the real commands, a representative subset
# ---------------------------------------------------------------------------------------------
def _main(module: str, argv: list[str], monkeypatch, capsys) -> tuple[int, list[str]]:
    main = importlib.import_module(f"lerobot_unidextok.scripts.{module}").main
    monkeypatch.setattr(sys, "argv", [f"unidextok-{module}", *argv])
    try:
        main()
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    from lerobot_unidextok.samples import write_samples

    return write_samples(tmp_path_factory.mktemp("raw"), sources=["lerobot"], episodes_per_source=2,
                         frames_per_episode=20)["lerobot"]  # fmt: skip


def test_the_real_commands(raw, tmp_path, monkeypatch, capsys):
    """The CLIs end in one `error:` line and exit 2 with nothing changed, or in the right result."""
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS

    base = tmp_path / "sandbox"
    base.mkdir()
    build_sandbox(base)
    shutil.rmtree(base / "raw")
    shutil.copytree(raw, base / "raw")
    opts = json.dumps(SAMPLE_SOURCE_OPTIONS["lerobot"])
    convert = ["--source=lerobot", f"--input={base / 'raw'}", f"--source_options={opts}", "--repo_id=t/g1"]
    shutil.rmtree(base / "converted")  # a real conversion (mix reads its input before it claims)
    assert _main("convert", [*convert, f"--root={base / 'converted'}"], monkeypatch, capsys) == (0, [])
    (base / f".new.tmp-{os.getppid()}-abcd1234").mkdir()  # a live run writing `new`
    refused = [
        ("convert", [*convert, f"--root={base / 'raw'}", "--overwrite=true"], "is, holds or sits inside the input"),
        ("convert", [*convert, f"--root={base / 'afile' / 'new'}"], "is a file, not a folder"),
        ("convert", [*convert, f"--root={base / 'new'}"], f"being written by another run now: pid {os.getppid()}"),
        ("convert", [*convert, f"--root={base / 'out'}", "--overwrite=true", "--executor.type=local",
                     f"--executor.logging_dir={base / 'converted'}"], "holds a dataset written by unidextok-convert"),
        ("mix", [f"--inputs=[{base / 'converted'}]", f"--root={base / 'user'}", "--overwrite=true"],
         "holds other files"),
        ("eval", [f"--checkpoint={base / 'run'}", f"--datasets=[{base / 'converted'}]", f"--output={base / 'run'}/"],
         "the report unidextok-train wrote"),
    ]  # fmt: skip
    if importlib.util.find_spec("datatrove") is None:  # an optional extra: the sharded row needs it
        refused = [r for r in refused if "--executor.type=local" not in r[1]]
    for module, argv, message in refused:
        before = tree_hash(base)
        code, errors = _main(module, argv, monkeypatch, capsys)
        assert code == 2 and len(errors) == 1 and message in errors[0], (module, argv, errors)
        assert tree_hash(base) == before, (module, argv)
    shutil.rmtree(base / f".new.tmp-{os.getppid()}-abcd1234")

    # a dead run's leftovers: the next convert restores the set-aside dataset, keeps the finished new one, and
    # (no --overwrite) refuses to replace it, in one line
    (base / "converted").rename(base / f".new.old-{DEAD}-abcd1234")
    shutil.copytree(base / "converted2", base / f".new.tmp-{DEAD}-abcd1234")
    code, errors = _main("convert", [*convert, f"--root={base / 'new'}"], monkeypatch, capsys)
    assert code == 2 and len(errors) == 1 and "already holds a dataset written by unidextok-convert" in errors[0]
    assert (base / "new" / "meta" / "info.json").is_file() and (base / f"new.unfinished-{DEAD}" / "meta").is_dir()
    assert not [p.name for p in base.iterdir() if p.name.startswith(".new.")]
    # and an empty folder made beforehand takes a conversion
    assert _main("convert", [*convert, f"--root={base / 'empty'}"], monkeypatch, capsys) == (0, [])
    assert (base / "empty" / "meta" / "unidextok_conversion.json").is_file()


# lerobot-train is LeRobot's writer: the plugin checks its --output_dir flag (policies/train_output.py) against the
# same kinds of folder, at them and inside them; an existing folder that is none of them is LeRobot's own refusal
# (its FileExistsError), a new one LeRobot's to make. E = refused by the plugin, o = left to LeRobot.
TRAIN_OUTPUT = {"converted": "E", "plain": "E", "policy": "E", "run/best": "E", "mixed": "E", "run": "o", "logs": "o",
                "user": "o", "empty": "o", "new": "o"}  # fmt: skip


@pytest.mark.parametrize("inside", [False, True], ids=["at", "inside"])
def test_lerobot_train_output_dir_is_held_to_the_units_at_and_inside(inside, tmp_path):
    from lerobot_unidextok.policies.train_output import refuse_training_into_a_unit

    base = tmp_path / "sandbox"
    base.mkdir()
    build_sandbox(base)
    _dataset(base / "mixed", "mix")
    before = tree_hash(base)
    for name, expected in TRAIN_OUTPUT.items():
        dest = base / name / "runs" / "a" if inside else base / name
        try:
            refuse_training_into_a_unit(["lerobot-train", "--policy.type=act_udt", f"--output_dir={dest}"])
            outcome = "o"
        except DestinationError as exc:
            assert str(exc).startswith(f"--output_dir {dest} ") and "choose an --output_dir outside it" in str(exc)
            outcome = "E"
        assert outcome == expected, (name, inside, outcome)
    assert tree_hash(base) == before  # a check, nothing written


HOLD = """
import sys
from lerobot_unidextok.data.destination import Kind, claim
claim(sys.argv[1], Kind.CONVERTED)
print("claimed", flush=True)
sys.stdin.read()
"""


def test_a_second_writer_is_refused_as_it_starts_and_a_killed_ones_lock_is_taken_over(raw, tmp_path, caplog):
    """Two processes: the first has claimed `out` (it still reads its inputs: no temp folder yet); the real
    `unidextok-convert` into `out` is refused as it starts, naming the first's pid, with nothing written. The first is
    killed (kill -9, its lock file left behind): the next conversion takes the lock over, says so, and converts."""
    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS

    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)  # fmt: skip
    try:
        assert first.stdout.readline().strip() == "claimed"
        convert = [str(Path(sys.executable).parent / "unidextok-convert"), "--source=lerobot", f"--input={raw}",
                   f"--source_options={json.dumps(SAMPLE_SOURCE_OPTIONS['lerobot'])}", f"--root={out}",
                   "--progress=false"]  # fmt: skip
        before = tree_hash(tmp_path)
        second = subprocess.run(convert, capture_output=True, text=True, timeout=300)
        errors = [line for line in second.stderr.splitlines() if line.startswith("error:")]
        assert second.returncode == 2 and len(errors) == 1, second.stderr[-2000:]
        assert errors[0].startswith(f"error: --root {out} is being written by another run now: pid {first.pid}")
        assert tree_hash(tmp_path) == before and not out.exists()
    finally:
        first.kill()
        first.wait()
    assert lock_path(out).read_text() == str(first.pid)  # killed: its lock file stays, the kernel dropped the lock
    from lerobot_unidextok.conversion.pipeline import ConvertOptions
    from lerobot_unidextok.conversion.pipeline import convert as convert_in_process

    with caplog.at_level("WARNING", logger="lerobot_unidextok.data.destination"):  # the next writer, in this process
        convert_in_process(ConvertOptions(source="lerobot", input=raw, root=out, progress=False,
                                          source_options=SAMPLE_SOURCE_OPTIONS["lerobot"]))  # fmt: skip
    assert any(f"took over the lock of pid {first.pid}" in r.getMessage() for r in caplog.records)
    assert (out / "meta" / "unidextok_conversion.json").is_file() and not lock_path(out).exists()


if __name__ == "__main__":  # one cell in a child process (the read-only parent): prints its outcome
    print(run_cell(sys.argv[1], sys.argv[2], Path(sys.argv[3]), Path(sys.argv[4])))
