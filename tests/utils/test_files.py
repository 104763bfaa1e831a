"""utils.files: a finished folder replaces the old one in one step, what a killed writer left is restored or
tidied, never lost; results become plain JSON."""

import json
import math
import os
from pathlib import Path

import numpy as np

from lerobot_unidextok.utils.files import fingerprint, jsonable, recover_folder, replace_folder


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
    for name in (f".ds.tmp-{DEAD}-cccc", f".ds.old-{DEAD}-dddd", f".ds.tmp-{live}-eeee", f".other.tmp-{DEAD}-ffff"):
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
