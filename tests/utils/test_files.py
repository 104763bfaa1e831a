"""utils.files: a finished folder replaces the old one in one step; results become plain JSON."""

import json
import math
from pathlib import Path

import numpy as np

from lerobot_unidextok.utils.files import fingerprint, jsonable, replace_folder


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
