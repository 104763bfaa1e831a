"""utils.files: a finished folder replaces the old one in one step, what a killed writer left is restored or
tidied, never lost; results become plain JSON."""

import json
import math
import os
import subprocess
import time
from pathlib import Path

import numpy as np

from lerobot_unidextok.utils import files
from lerobot_unidextok.utils.files import (
    START_SLACK_S,
    fingerprint,
    jsonable,
    live_writers,
    process_start_s,
    recover_folder,
    replace_folder,
    temp_file_sibling,
    temp_sibling,
    writer_running,
)


def _folder(path: Path, text: str) -> Path:
    path.mkdir()
    (path / "data.txt").write_text(text)
    return path


def test_replace_folder_moves_new_over_old_and_leaves_nothing_else(tmp_path):
    replace_folder(_folder(tmp_path / ".tmp-1", "first"), tmp_path / "out")
    assert (tmp_path / "out" / "data.txt").read_text() == "first"
    replace_folder(_folder(tmp_path / ".tmp-2", "second"), tmp_path / "out")
    assert (tmp_path / "out" / "data.txt").read_text() == "second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temp or renamed-aside folder left


DEAD = 999999999  # no such process


def test_a_kill_between_the_two_renames_restores_the_old_folder_and_keeps_the_new_one(tmp_path):
    """The state an overwrite killed between its renames leaves: the target missing, the old folder set aside,
    the finished new one in its temp folder. Before: the next run removed both. Now the old one is back in
    place and the new one kept beside it, and the notes say so."""
    _folder(tmp_path / f".ds.old-{DEAD}-aaaa", "old dataset")
    _folder(tmp_path / f".ds.tmp-{DEAD}-bbbb", "new dataset")
    notes = recover_folder(tmp_path / "ds")
    assert (tmp_path / "ds" / "data.txt").read_text() == "old dataset"
    assert (tmp_path / f"ds.unfinished-{DEAD}" / "data.txt").read_text() == "new dataset"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", f"ds.unfinished-{DEAD}"]
    assert len(notes) == 2 and "restored" in notes[0] and "kept" in notes[1]
    assert recover_folder(tmp_path / "ds") == []  # nothing left to do


def test_dead_leftovers_are_tidied_and_a_live_run_is_left_alone(tmp_path):
    """A dead run's unfinished temp folder goes; an old folder whose replacement is in place goes (only its
    deletion was cut short); a live run's folders (here this test's parent's pid) and another target's stay. The
    liveness probe is signal 0, which delivers nothing (SIGHUP would end the live process)."""
    live = os.getppid()
    _folder(tmp_path / "ds", "current")
    for name in (f".ds.tmp-{DEAD}-cccc", f".ds.old-{DEAD - 1}-dddd", f".ds.tmp-{live}-eeee",
                 f".other.tmp-{DEAD}-ffff"):
        _folder(tmp_path / name, name)
    notes = recover_folder(tmp_path / "ds")
    assert sorted(p.name for p in tmp_path.iterdir()) == [f".ds.tmp-{live}-eeee", f".other.tmp-{DEAD}-ffff", "ds"]
    assert (tmp_path / "ds" / "data.txt").read_text() == "current" and len(notes) == 2


def test_jsonable_gives_plain_json():
    out = jsonable({1: np.float32(0.5), "a": (np.int64(3), np.bool_(True)), "nan": math.nan, "arr": np.eye(2),
                    "path": Path("x") / "y"})  # fmt: skip
    assert out == {"1": 0.5, "a": [3, True], "nan": None, "arr": [[1.0, 0.0], [0.0, 1.0]], "path": "x/y"}
    assert json.loads(json.dumps(out)) == out


def test_fingerprint_is_one_sha1_over_the_parts():
    import hashlib

    arr = np.arange(4, dtype=np.float32)
    assert fingerprint(b"ab", arr) == hashlib.sha1(b"ab" + arr.tobytes()).hexdigest()[:12]
    assert fingerprint({"b": 1, "a": 2}) == hashlib.sha1(b'{"a": 2, "b": 1}').hexdigest()[:12]  # sorted keys
    assert fingerprint(arr) != fingerprint(arr + 1)


def test_an_empty_root_is_not_the_replacement_in_place(tmp_path):
    """Issue 45 #3: the kill-between-renames state, then a script's `mkdir -p <root>`. Before: the empty root was
    taken for the finished replacement, both the set-aside old dataset and the finished new one were deleted, and
    the note said the replacement "is in place". Now the old one is restored and the new one kept."""
    _folder(tmp_path / f".ds.old-{DEAD}-aaaa", "old dataset")
    _folder(tmp_path / f".ds.tmp-{DEAD}-bbbb", "new dataset")
    (tmp_path / "ds").mkdir()
    notes = recover_folder(tmp_path / "ds")
    assert (tmp_path / "ds" / "data.txt").read_text() == "old dataset"
    assert (tmp_path / f"ds.unfinished-{DEAD}" / "data.txt").read_text() == "new dataset"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", f"ds.unfinished-{DEAD}"]
    assert "restored" in notes[0] and not any("in place" in n for n in notes)


def test_a_root_that_holds_something_else_keeps_both_the_old_and_the_new(tmp_path):
    """Killed between the renames (old aside, new finished), then something else took the name: the replacement
    never happened, so nothing is deleted; both folders become visible and are named."""
    _folder(tmp_path / f".ds.old-{DEAD}-aaaa", "old dataset")
    _folder(tmp_path / f".ds.tmp-{DEAD}-bbbb", "new dataset")
    _folder(tmp_path / "ds", "someone else's")
    notes = recover_folder(tmp_path / "ds")
    assert {p.name: (p / "data.txt").read_text() for p in tmp_path.iterdir()} == {
        "ds": "someone else's", f"ds.set-aside-{DEAD}": "old dataset", f"ds.unfinished-{DEAD}": "new dataset"}
    assert len(notes) == 2 and "both are kept" in notes[0]


def test_recovery_is_keyed_by_the_exact_name_never_a_glob(tmp_path):
    """Issue 45 #4: `--root='rec/ds[1]'` restored another root's `.ds1.old-*` (the glob's `[1]` is a character
    class) and never found its own `.ds[1].old-*`. Other roots whose names start like this one's are left alone."""
    _folder(tmp_path / f".ds[1].old-{DEAD}-aaaa", "ds[1] as it was")
    _folder(tmp_path / f".ds1.old-{DEAD}-bbbb", "ds1 as it was")
    _folder(tmp_path / f".ds[1].x.tmp-{DEAD}-cccc", "another root's temp")
    _folder(tmp_path / f".ds[1].old-3.tmp-{DEAD}-dddd", "the temp of a root named ds[1].old-3")
    recover_folder(tmp_path / "ds[1]")
    assert (tmp_path / "ds[1]" / "data.txt").read_text() == "ds[1] as it was"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [f".ds1.old-{DEAD}-bbbb", f".ds[1].x.tmp-{DEAD}-cccc", f".ds[1].old-3.tmp-{DEAD}-dddd", "ds[1]"])
    recover_folder(tmp_path / "ds1")
    assert (tmp_path / "ds1" / "data.txt").read_text() == "ds1 as it was"


def test_an_existing_unfinished_folder_gets_a_free_name_never_a_crash(tmp_path):
    """Issue 45 Q1: the recovery crashed with `OSError: Directory not empty` when `<root>.unfinished-<pid>` was
    already there (kept from an earlier recovery). Now the new one takes the next free name; nothing is deleted."""
    _folder(tmp_path / f"ds.unfinished-{DEAD}", "kept earlier")
    _folder(tmp_path / f".ds.old-{DEAD}-aaaa", "old dataset")
    _folder(tmp_path / f".ds.tmp-{DEAD}-bbbb", "new dataset")
    notes = recover_folder(tmp_path / "ds")
    assert {p.name: (p / "data.txt").read_text() for p in tmp_path.iterdir()} == {
        "ds": "old dataset", f"ds.unfinished-{DEAD}": "kept earlier", f"ds.unfinished-{DEAD}-2": "new dataset"}
    assert f"ds.unfinished-{DEAD}-2" in notes[1]


def test_a_live_writers_set_aside_folder_is_reported_not_ignored(tmp_path):
    """Issue 45 #9: an `.old-<pid>` whose pid runs was never restored nor mentioned. A writer that started before
    the folder was set aside (here this test's parent) is left alone, and the note names the folder and the fix."""
    live = os.getppid()
    _folder(tmp_path / f".ds.old-{live}-aaaa", "old dataset")
    notes = recover_folder(tmp_path / "ds")
    assert (tmp_path / f".ds.old-{live}-aaaa").is_dir() and not (tmp_path / "ds").exists()
    assert len(notes) == 1 and f".ds.old-{live}-aaaa" in notes[0] and f"pid {live}, which still runs" in notes[0]
    assert [x.pid for x in live_writers(tmp_path / "ds")] == [live]


def test_a_reused_pid_is_told_from_the_writer_by_its_start_time(tmp_path):
    """A process that started after the leftover was last changed cannot have written it: the pid was reused and
    the writer is gone. Measured, not assumed: the process below starts 1.3 s after the folder is made."""
    leftover = _folder(tmp_path / ".ds.old-1-aaaa", "old")
    time.sleep(START_SLACK_S + 0.3)
    later = subprocess.Popen(["sleep", "30"])
    try:
        started = process_start_s(later.pid)
        assert started is not None and abs(started - time.time()) < 1.0
        assert not writer_running(later.pid, leftover)  # started after: a reused pid
        assert writer_running(os.getppid(), leftover)  # started before: could be the writer
    finally:
        later.kill()
        later.wait()
    assert not writer_running(later.pid, leftover)  # ended


def test_a_reused_pids_leftover_is_recovered(tmp_path, monkeypatch):
    """recover_folder treats a leftover whose pid now belongs to a later process as a dead writer's. The later
    process is this test's parent, made "later" by moving the slack (the timing itself is measured above)."""
    monkeypatch.setattr(files, "START_SLACK_S", -1e9)
    _folder(tmp_path / f".ds.old-{os.getppid()}-aaaa", "old dataset")
    notes = recover_folder(tmp_path / "ds")
    assert (tmp_path / "ds" / "data.txt").read_text() == "old dataset" and "restored" in notes[0]


def test_temp_names_carry_the_pid_and_a_random_part(tmp_path):
    names = {temp_sibling(tmp_path / "ds").name for _ in range(20)}
    assert len(names) == 20 and all(n.startswith(f".ds.tmp-{os.getpid()}-") for n in names)
    file = temp_file_sibling(tmp_path / "clip.mp4")
    assert file.name.startswith(f".clip.tmp-{os.getpid()}-") and file.suffix == ".mp4"


def test_a_replacement_names_the_old_folder_with_the_tag_of_the_new_one(tmp_path, monkeypatch):
    """The two folders of one replacement carry one tag: `.old-<tag>` set aside for `.tmp-<tag>`."""
    tmp = temp_sibling(tmp_path / "ds")
    _folder(tmp_path / "ds", "old")
    _folder(tmp, "new")
    tag = tmp.name.removeprefix(".ds.tmp-")
    real_rename = Path.rename
    seen = []

    def rename(self, dest):  # record the names, then rename for real
        seen.append(Path(dest).name)
        return real_rename(self, dest)

    monkeypatch.setattr(Path, "rename", rename)
    replace_folder(tmp, tmp_path / "ds")
    assert seen == [f".ds.old-{tag}", "ds"] and (tmp_path / "ds" / "data.txt").read_text() == "new"
