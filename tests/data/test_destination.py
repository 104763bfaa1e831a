"""data.destination: what a folder holds, and which writer may write where (the rules every writer shares)."""

import json
import os
from pathlib import Path

import pytest

from lerobot_unidextok.data.destination import DestinationError, Kind, claim, claim_files, is_json_with, kind_of


def _dataset(root: Path, source: str | None) -> Path:
    (root / "meta").mkdir(parents=True)
    (root / "meta" / "info.json").write_text("{}")
    if source is not None:
        (root / "meta" / "unidextok_conversion.json").write_text(json.dumps({"source": source}))
    return root


def _checkpoint(root: Path, policy: bool) -> Path:
    root.mkdir(parents=True)
    for name in ("config.json", "model.safetensors", *(["policy_preprocessor.json"] if policy else [])):
        (root / name).write_text("{}")
    return root


@pytest.fixture
def folders(tmp_path) -> dict[Kind, Path]:
    run = tmp_path / "run"
    _checkpoint(run / "best", policy=False)
    return {
        Kind.CONVERTED: _dataset(tmp_path / "converted", "lerobot"),
        Kind.MIX: _dataset(tmp_path / "mix", "mix"),
        Kind.DATASET: _dataset(tmp_path / "plain", None),
        Kind.TOKENIZER: _checkpoint(tmp_path / "tok", policy=False),
        Kind.POLICY: _checkpoint(tmp_path / "policy", policy=True),
        Kind.TOKENIZER_RUN: run,
    }


def test_each_kind_is_recognised(folders, tmp_path):
    assert {kind: kind_of(path) for kind, path in folders.items()} == {kind: kind for kind in folders}
    (tmp_path / "other").mkdir()
    assert kind_of(tmp_path / "other") is None and kind_of(tmp_path / "missing") is None


def test_a_writer_replaces_only_its_own_kind_and_only_when_asked(folders, tmp_path):
    for writes in (Kind.CONVERTED, Kind.MIX):
        for kind, path in folders.items():
            if kind == writes:
                with pytest.raises(DestinationError, match="already holds .* pass --overwrite=true"):
                    claim(path, writes)
                assert claim(path, writes, overwrite=True) == path.resolve()
            else:
                with pytest.raises(DestinationError, match=f"holds {kind.value}, not {writes.value}"):
                    claim(path, writes, overwrite=True)
    assert claim(folders[Kind.TOKENIZER_RUN], Kind.TOKENIZER_RUN, resume=True)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert claim(empty, Kind.MIX) == empty.resolve()  # an empty folder made beforehand is as good as none
    (tmp_path / "file").write_text("x")
    with pytest.raises(DestinationError, match="is a file, not a folder"):
        claim(tmp_path / "file", Kind.MIX)


def test_nothing_is_written_inside_a_dataset_or_a_checkpoint(folders):
    for kind in (Kind.CONVERTED, Kind.MIX, Kind.DATASET, Kind.TOKENIZER, Kind.POLICY):
        with pytest.raises(DestinationError, match=f"sits inside {kind.value}"):
            claim(folders[kind] / "sub" / "out", Kind.MIX)
        with pytest.raises(DestinationError, match=f"inside {kind.value}"):
            claim_files([folders[kind] / "report.json"])
    # a run folder is not one unit: a report beside its checkpoints is where unidextok-train puts its own
    assert claim_files([folders[Kind.TOKENIZER_RUN] / "eval.json"])


def test_files_are_replaced_only_when_this_writer_wrote_them(tmp_path):
    ours, theirs = tmp_path / "eval.json", tmp_path / "notes.json"
    ours.write_text(json.dumps({"per_hand": {}, "overall": {}}))
    theirs.write_text(json.dumps({"todo": 1}))
    is_report = is_json_with("per_hand", "overall")
    assert claim_files([ours], is_ours=is_report)
    with pytest.raises(DestinationError, match="a file this command did not write"):
        claim_files([theirs], is_ours=is_report)


def test_a_file_where_a_parent_folder_should_be_is_refused_before_the_work(tmp_path):
    """Issue 45 Q1: every writer ended in a FileExistsError / NotADirectoryError traceback after its work. Now
    `claim` and `claim_files` refuse it first, naming the file."""
    (tmp_path / "notes").write_text("a file")
    for where in (tmp_path / "notes" / "ds", tmp_path / "notes" / "a" / "b" / "ds"):
        with pytest.raises(DestinationError, match=f"cannot be made: {tmp_path / 'notes'} is a file, not a folder"):
            claim(where, Kind.MIX)
        with pytest.raises(DestinationError, match="is a file, not a folder"):
            claim_files([where / "eval.json"])
    assert (tmp_path / "notes").read_text() == "a file"


def test_a_destination_a_live_run_is_writing_is_refused_naming_its_pid(tmp_path):
    """Issue 45 Q1: a convert and a train started 3 s apart into one new root: the second wrote into what the
    first was writing. A live writer's temp folder beside the root (here one of this test's parent, a process
    that started before the folder was made) now refuses the second writer, naming the first's pid."""
    live = os.getppid()
    busy = tmp_path / f".ds.tmp-{live}-abcd1234"
    busy.mkdir()
    with pytest.raises(DestinationError, match=f"being written by another run now: pid {live} .*wait for it"):
        claim(tmp_path / "ds", Kind.CONVERTED)
    assert busy.is_dir() and not (tmp_path / "ds").exists()
    assert claim(tmp_path / "ds2", Kind.CONVERTED)  # another root is free
