"""`--executor.logging_dir` is a destination like `--root` (issue 45 #1): claimed before anything is read or
deleted; only a logging folder an earlier run left (its `run_settings.json`) is ever deleted (`--overwrite=true`);
an input, the target, a dataset, a user's folder are refused with one line and left exactly as they were."""

from __future__ import annotations

import hashlib
import shutil
import sys
from pathlib import Path

import pytest

pytest.importorskip(
    "datatrove", reason="datatrove is an optional extra: pip install 'lerobot_policy_unidextok[datatrove]'"
)

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert  # noqa: E402
from lerobot_unidextok.conversion.sharded import ExecutorOptions, convert_with_executor  # noqa: E402
from lerobot_unidextok.data.destination import DestinationError  # noqa: E402
from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS, write_samples  # noqa: E402

SOURCE = "lerobot"


def tree_hash(folder: Path) -> str:
    """One sha1 over every file's relative path and bytes under `folder` (and the empty folders' names)."""
    h = hashlib.sha1()
    for path in sorted(Path(folder).rglob("*")):
        h.update(str(path.relative_to(folder)).encode())
        if path.is_file():
            h.update(path.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    return write_samples(tmp_path_factory.mktemp("raw"), sources=[SOURCE], episodes_per_source=2,
                         frames_per_episode=20)[SOURCE]  # fmt: skip


@pytest.fixture(scope="module")
def converted(raw, tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("conv") / "g1"
    convert(_options(raw, root))
    return root


def _options(raw: Path, root: Path, **kw) -> ConvertOptions:
    return ConvertOptions(source=SOURCE, input=raw, root=root, repo_id="t/g1",
                          source_options=SAMPLE_SOURCE_OPTIONS[SOURCE], progress=False, **kw)  # fmt: skip


def _local(logs: Path) -> ExecutorOptions:
    return ExecutorOptions(type="local", tasks=1, workers=1, logging_dir=str(logs))


@pytest.mark.parametrize("overwrite", [True, False])
@pytest.mark.parametrize("what", ["input", "dataset", "user folder", "target", "holds the target"])
def test_a_logging_dir_that_is_not_a_logging_folder_is_refused_and_left_as_it_was(raw, converted, tmp_path, what,
                                                                                  overwrite):  # fmt: skip
    """Before: `--overwrite=true --executor.logging_dir=<folder>` deleted any folder given there (the input's
    data/ and meta/ were gone before the "would change the input" refusal ran); without --overwrite the logs
    went into a dataset and the run failed late. Now one line, up front, and nothing changed."""
    raw_copy = tmp_path / "raw"
    shutil.copytree(raw, raw_copy)
    root = tmp_path / "out" / "g1"
    if what == "target":  # an existing converted dataset being replaced, given as its own logging folder
        shutil.copytree(converted, root)
    user = tmp_path / "notes"
    user.mkdir()
    (user / "todo.txt").write_text("mine")
    logs = {"input": raw_copy, "dataset": converted, "user folder": user, "target": root,
            "holds the target": tmp_path / "out"}[what]  # fmt: skip
    watched = {p: tree_hash(p) for p in (raw_copy, converted, user, tmp_path / "out") if p.exists()}
    expected = {"input": "the input", "dataset": "holds a dataset written by unidextok-convert",
                "user folder": "holds other files", "target": "is, holds or sits inside",
                "holds the target": "is, holds or sits inside"}[what]  # fmt: skip
    pattern = f"--executor.logging_dir {logs}.* {expected}"
    if what == "target" and not overwrite:  # the existing target is refused first, as it always was
        pattern = f"--root {root}.* already holds"
    with pytest.raises(DestinationError, match=pattern):
        convert_with_executor(_options(raw_copy, root, overwrite=overwrite), _local(logs))
    assert {p: tree_hash(p) for p in watched} == watched


def test_an_earlier_logging_folder_is_replaced_with_overwrite_and_resumed_without(raw, tmp_path, capsys):
    """The folder this writer left (recognised by its run_settings.json) is the one thing it may delete."""
    root, logs = tmp_path / "g1", tmp_path / "logs"
    assert convert_with_executor(_options(raw, root), _local(logs)) == root.resolve()
    assert (logs / "run_settings.json").is_file() and (logs / "merge" / "completions" / "00000").is_file()
    (logs / "stale.txt").write_text("from the first run")
    convert_with_executor(_options(raw, root, overwrite=True), _local(logs))
    assert not (logs / "stale.txt").exists() and (logs / "merge" / "completions" / "00000").is_file()


def test_the_cli_refuses_a_logging_dir_in_one_line_with_exit_2(raw, converted, tmp_path, capsys, monkeypatch):
    from lerobot_unidextok.scripts.convert import main

    before = tree_hash(converted)
    monkeypatch.setattr(sys, "argv", ["unidextok-convert", f"--source={SOURCE}", f"--input={raw}", "--repo_id=t/g1",
                                      f"--root={tmp_path / 'g1'}", "--overwrite=true", "--executor.type=local",
                                      f"--executor.logging_dir={converted}"])  # fmt: skip
    with pytest.raises(SystemExit) as exit_info:
        main()
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_info.value.code == 2 and err[0].startswith("error: --executor.logging_dir")
    assert err[1:] == ["(set UNIDEXTOK_TRACEBACK=1 to see the traceback)"]  # the one error line, and its hint
    assert tree_hash(converted) == before and not (tmp_path / "g1").exists()
