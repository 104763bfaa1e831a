"""Where `unidextok-train` writes: a finished run is continued (--resume) or replaced (--overwrite) only when
asked, and never a dataset; `unidextok-eval` writes its report next to, never inside, what it reads."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_unidextok.data.destination import DestinationError
from lerobot_unidextok.training import TrainConfig
from lerobot_unidextok.training.run import train_and_evaluate

BIN = Path(sys.executable).parent


def _cfg(dataset: Path, out: Path, **kw) -> TrainConfig:
    return TrainConfig(datasets=[str(dataset)], preset="tiny", steps=4, batch_size=16, warmup_steps=1, eval_every=2,
                       progress=False, output_dir=str(out), **kw)  # fmt: skip


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


def test_eval_never_writes_its_report_inside_a_dataset_or_a_checkpoint(g1_like, tmp_path):
    """`unidextok-eval --output=<dataset>/meta/stats` replaced the dataset's stats.json (--validate still said
    VALID, lerobot-train then failed with a TypeError); now refused in one line. A checkpoint whose config does
    not fit its weights is one line too, not a traceback."""
    run = tmp_path / "run"
    train_and_evaluate(_cfg(g1_like["root"], run))
    data = tmp_path / "data"
    shutil.copytree(g1_like["root"], data)
    stats = (data / "meta" / "stats.json").read_bytes()
    eval_cli = [str(BIN / "unidextok-eval"), f"--checkpoint={run}", f"--datasets=[{g1_like['root']}]"]
    r = subprocess.run([*eval_cli, f"--output={data / 'meta' / 'stats'}"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.startswith("error: --output would write"), r.stderr[-2000:]
    assert "inside a dataset written by unidextok-convert" in r.stderr
    assert (data / "meta" / "stats.json").read_bytes() == stats
    r = subprocess.run([*eval_cli, f"--output={g1_like['root'] / 'meta' / 'stats'}"], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert r.returncode == 2 and "sits inside the input" in r.stderr
    config = json.loads((run / "best" / "config.json").read_text())
    (run / "best" / "config.json").write_text(json.dumps({**config, "hidden_dim": config["hidden_dim"] * 2}))
    r = subprocess.run([*eval_cli, f"--output={tmp_path / 'report'}"], capture_output=True, text=True, timeout=300)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error: ")]
    assert r.returncode == 2 and len(errors) == 1 and "does not fit the config.json beside it" in errors[0], r.stderr
    assert "Traceback" not in r.stderr
