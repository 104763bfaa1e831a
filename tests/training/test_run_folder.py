"""Where `unidextok-train` writes: a finished run is continued (--resume) or replaced (--overwrite) only when
asked, and never a dataset; `unidextok-eval` writes its report next to, never inside, what it reads."""

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_main import run_main

from lerobot_unidextok.data.destination import DestinationError
from lerobot_unidextok.errors import CheckpointNotFoundError, ConfigError, InvalidInputError, MissingInputError
from lerobot_unidextok.tokenizer import UniDexTok
from lerobot_unidextok.training import TrainConfig
from lerobot_unidextok.training.run import train_and_evaluate

BIN = Path(sys.executable).parent


def _cfg(dataset: Path, out: Path, **kw) -> TrainConfig:
    base = dict(datasets=[str(dataset)], preset="tiny", steps=4, batch_size=16, warmup_steps=1, eval_every=2,
                progress=False, output_dir=str(out))  # fmt: skip
    return TrainConfig(**{**base, **kw})


def _best(run: Path) -> dict:
    return json.loads((run / "best" / "training_state.json").read_text())


def test_a_finished_run_is_replaced_only_with_overwrite(g1_like, tmp_path):
    """`--output_dir=<a finished run>` without --resume silently replaced best/ and last/ (a 5.36 deg best
    became 13.10 deg); now it is refused with both fixes, and --overwrite=true replaces the whole run."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    first = _best(run)
    with pytest.raises(DestinationError, match=r"already holds a unidextok-train run folder: pass --resume=true to "
                                               r"continue it, --overwrite=true to replace it"):  # fmt: skip
        train_and_evaluate(_cfg(g1_like["root"], run, seed=1))
    assert _best(run) == first
    (run / "folds").mkdir()  # an output of the old run the new one would not write: gone with the old run
    train_and_evaluate(_cfg(g1_like["root"], run, seed=1, overwrite=True))
    assert _best(run)["step"] <= 4 and not (run / "folds").exists()


def test_a_run_folder_inside_or_equal_to_a_dataset_is_refused(g1_like, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(g1_like["root"], data)
    before = sorted(str(p.relative_to(data)) for p in data.rglob("*"))
    for out in (data, data / "runs" / "a"):
        with pytest.raises(DestinationError, match="is, holds or sits inside the input"):
            train_and_evaluate(_cfg(data, out))
    with pytest.raises(DestinationError, match=r"sits inside a dataset written by unidextok-convert"):
        train_and_evaluate(_cfg(g1_like["root"], data / "run"))
    assert sorted(str(p.relative_to(data)) for p in data.rglob("*")) == before


def _eval_in_process(monkeypatch, capsys, *args: str) -> tuple[int, str]:
    """`unidextok-eval args` in this process: (exit status, stderr). Its entry point runs as a subprocess in
    `test_the_eval_command_names_a_set_aside_best_in_one_line`."""
    from lerobot_unidextok.scripts.eval import main

    return run_main(main, "unidextok-eval", list(args), monkeypatch, capsys)


def test_eval_never_writes_its_report_inside_a_dataset_or_a_checkpoint(g1_like, tmp_path, monkeypatch, capsys):
    """`unidextok-eval --output=<dataset>/meta/stats` replaced the dataset's stats.json (--validate still said
    VALID, lerobot-train then failed with a TypeError); now refused in one line. A checkpoint whose config does
    not fit its weights is one line too, not a traceback."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    data = tmp_path / "data"
    shutil.copytree(g1_like["root"], data)
    stats = (data / "meta" / "stats.json").read_bytes()
    eval_args = [f"--checkpoint={run}", f"--datasets=[{g1_like['root']}]"]
    code, err = _eval_in_process(monkeypatch, capsys, *eval_args, f"--output={data / 'meta' / 'stats'}")
    assert code == 2 and err.startswith("error: --output would write"), err[-2000:]
    assert "inside a dataset written by unidextok-convert" in err
    assert (data / "meta" / "stats.json").read_bytes() == stats
    code, err = _eval_in_process(monkeypatch, capsys, *eval_args, f"--output={g1_like['root'] / 'meta' / 'stats'}")
    assert code == 2 and "sits inside the input" in err
    config = json.loads((run / "best" / "config.json").read_text())
    (run / "best" / "config.json").write_text(json.dumps({**config, "hidden_dim": config["hidden_dim"] * 2}))
    code, err = _eval_in_process(monkeypatch, capsys, *eval_args, f"--output={tmp_path / 'report'}")
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert code == 2 and len(errors) == 1 and "does not fit the config.json beside it" in errors[0], err
    assert "Traceback" not in err


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_failing_overwrite_leaves_the_finished_run_as_it_was(g1_like, tmp_path):
    """`--overwrite=true` deleted best/, last/ and the eval report when it started, so a typo in --datasets or
    --preset, or any later failure, left an empty run folder. Now the inputs are checked first and the new run is
    trained beside the old one, moved into place only once it has finished: each failure leaves every byte of
    the old run, and no temp folder beside it."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    before = _files(run)
    failures = [
        (dict(datasets=[str(tmp_path / "g1_lik")]), MissingInputError, r"g1_lik does not exist: pass the root of a"),
        (dict(datasets=[str(run)]), MissingInputError, r"run is not a LeRobotDataset"),
        (dict(preset="tinny"), ConfigError, r"unknown UniDexTok preset 'tinny'"),
        (dict(init_from=str(tmp_path / "nowhere")), CheckpointNotFoundError, r"nowhere"),
        (dict(resume=True), ConfigError, r"--resume=true continues the run, --overwrite=true replaces it: pass one"),
        (dict(folds=4), InvalidInputError, r"folds must be in \[2, 3\]"),  # found after training and evaluating
    ]
    for change, error, message in failures:
        with pytest.raises(error, match=message):
            train_and_evaluate(_cfg(g1_like["root"], run, seed=1, overwrite=True, **change))
        assert _files(run) == before, change
        assert sorted(p.name for p in tmp_path.iterdir()) == ["run"], change
    (tmp_path / ".run.tmp-999999999-abcd" / "best").mkdir(parents=True)  # what a killed overwrite left
    with pytest.raises(InvalidInputError, match=r"folds must be in"):
        train_and_evaluate(_cfg(g1_like["root"], run, overwrite=True, folds=4))
    assert _files(run) == before and sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # and the next run tidied


def test_an_overwrite_replaces_the_run_at_the_end_and_keeps_the_users_files(g1_like, tmp_path):
    """The new run, trained beside the old one, takes its place whole: its report names the checkpoint at
    --output_dir (not the temp folder it was trained in), the old run's outputs are gone, a file the user put
    in the run folder stays, and nothing is left beside it."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    (run / "notes.txt").write_text("why this run")
    (run / "kfold.json").write_text("{}")  # an output of the old run the new one does not write: gone with it
    report, _ = train_and_evaluate(_cfg(g1_like["root"], run, seed=1, steps=6, overwrite=True))
    assert _best(run)["steps"] == 6 and report["scored"]["checkpoint"] == str(run / "best")
    assert json.loads((run / "eval.json").read_text())["scored"]["checkpoint"] == str(run / "best")
    assert (run / "notes.txt").read_text() == "why this run" and not (run / "kfold.json").exists()
    assert f'from_pretrained("{run / "best"}")' in (run / "best" / "README.md").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert sorted(p.name for p in run.iterdir() if p.name.startswith(".")) == []


def test_a_best_set_aside_by_a_killed_save_is_named_by_readers_and_put_back_by_the_next_run(g1_like, tmp_path):
    """A run killed between the two renames of a save of best/ leaves no best/ (the old one set aside as
    .best.old-<pid>-*). Before, it came back only when a later run saved a new best: eval and push said the
    folder "holds no tokenizer" and a short --resume failed. Now a reader names the folder set aside and the
    fix, and any unidextok-train into the run (here a --resume with nothing left to train) restores it."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    best = _files(run / "best")
    aside = run / ".best.old-999999999-deadbeef"
    (run / "best").rename(aside)
    (run / ".best.tmp-999999999-cafe").mkdir()  # the new best that save was moving into place
    for name in (run, run / "best"):
        with pytest.raises(CheckpointNotFoundError, match=r"best is missing: a unidextok-train run \(pid 999999999\) "
                                                          r"was killed while replacing it, and set it aside as "
                                                          r".*\.best\.old-999999999-deadbeef"):  # fmt: skip
            UniDexTok.from_pretrained(name)
    train_and_evaluate(_cfg(g1_like["root"], run, resume=True))
    assert _files(run / "best") == best
    assert sorted(p.name for p in run.iterdir() if p.name.startswith(".")) == []


def test_the_eval_command_names_a_set_aside_best_in_one_line(g1_like, tmp_path):
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    (run / "best").rename(run / ".best.old-999999999-deadbeef")
    r = subprocess.run([str(BIN / "unidextok-eval"), f"--checkpoint={run}", f"--datasets=[{g1_like['root']}]",
                        f"--output={tmp_path / 'report'}"], capture_output=True, text=True, timeout=300)  # fmt: skip
    errors = [line for line in r.stderr.splitlines() if line.startswith("error: ")]
    assert r.returncode == 2 and len(errors) == 1 and "was killed while replacing it" in errors[0], r.stderr[-2000:]
    assert "--resume=true" in errors[0] and "Traceback" not in r.stderr


def test_a_row_store_dir_that_holds_other_files_an_input_or_a_dataset_is_refused(g1_like, tmp_path):
    """`--row_store_dir` is where the row stores train/ and test/ are rebuilt, replacing what is there: a user's
    folder lost its train/, and a dataset got two folders inside it. Now each is refused before anything is
    written; a folder of row stores (the one a run built) is taken again."""
    user = tmp_path / "mine"
    (user / "train").mkdir(parents=True)
    (user / "train" / "notes.txt").write_text("keep")
    data = tmp_path / "data"
    shutil.copytree(g1_like["root"], data)
    before = _files(data)
    refusals = [(user, r"--row_store_dir .*mine holds train, not only row stores of unidextok-train"),
                (data, r"--row_store_dir .*data is, holds or sits inside the input"),
                (g1_like["root"] / "stores", r"--row_store_dir .*stores sits inside a dataset written by")]
    for folder, message in refusals:
        with pytest.raises(DestinationError, match=message):
            train_and_evaluate(_cfg(data, tmp_path / "run", streaming=True, row_store_dir=str(folder)))
    with pytest.raises(DestinationError, match=r"--output_dir .*run sits inside a dataset"):
        train_and_evaluate(_cfg(g1_like["root"], data / "run", streaming=True, row_store_dir=str(tmp_path / "rs")))
    assert (user / "train" / "notes.txt").read_text() == "keep" and _files(data) == before
    assert not (tmp_path / "run").exists() and not (tmp_path / "rs").exists()
    stores = tmp_path / "stores"
    train_and_evaluate(_cfg(data, tmp_path / "run", streaming=True, row_store_dir=str(stores)))
    train_and_evaluate(_cfg(data, tmp_path / "run2", streaming=True, row_store_dir=str(stores)))
    assert sorted(p.name for p in stores.iterdir()) == ["test", "train"]


@pytest.mark.slow
def test_the_command_refuses_a_typo_and_a_sigterm_leaves_the_old_run(g1_like, tmp_path):
    """The probe's case through the command: `unidextok-train --overwrite=true --output_dir=<finished run>` with a
    typo in --preset is one `error:` line (exit 2); SIGTERM while the new run trains ends with exit 143 and the
    old run as it was, nothing beside it."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    before = _files(run)
    cli = [str(BIN / "unidextok-train"), f"--datasets=[{g1_like['root']}]", f"--output_dir={run}", "--overwrite=true",
           "--batch_size=16", "--warmup_steps=1", "--progress=false"]  # fmt: skip
    r = subprocess.run([*cli, "--preset=tinny"], capture_output=True, text=True, timeout=300)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error: ")]
    assert r.returncode == 2 and len(errors) == 1, r.stderr[-2000:]
    assert errors[0].startswith("error: unknown UniDexTok preset 'tinny'; choose one of [") and "'tiny'" in errors[0]
    proc = subprocess.Popen([*cli, "--preset=tiny", "--steps=1000000", "--save_last_every=1"], stderr=subprocess.PIPE,
                            text=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not any((p / "last").is_dir() for p in tmp_path.glob(".run.tmp-*")):
            assert proc.poll() is None and time.monotonic() < deadline, "the new run did not start training"
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGTERM)
        stderr = proc.communicate(timeout=60)[1]
    assert proc.returncode == 143 and stderr.strip().endswith("nothing half-written was left behind"), stderr[-2000:]
    assert _files(run) == before and sorted(p.name for p in tmp_path.iterdir()) == ["run"]
