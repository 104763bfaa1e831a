"""CLI output: one-line errors, the one-line torchcodec note, tqdm throttled off a terminal."""

import logging
import subprocess
import sys

import pytest
from linkerhand_udhm import subprocess_env

from lerobot_unidextok.utils import cli


def test_run_cli_turns_user_mistakes_into_one_line(capsys, monkeypatch):
    monkeypatch.delenv("UNIDEXTOK_TRACEBACK", raising=False)

    def bad() -> None:
        raise FileNotFoundError("data/x not found: convert it first")

    with pytest.raises(SystemExit) as info:
        cli.run_cli(bad)
    assert info.value.code == 2
    assert capsys.readouterr().err.splitlines()[0] == "error: data/x not found: convert it first"
    monkeypatch.setenv("UNIDEXTOK_TRACEBACK", "1")
    with pytest.raises(FileNotFoundError):
        cli.run_cli(bad)
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        cli.run_cli(lambda: 1 / 0)


def test_torchcodec_warning_becomes_one_note(caplog):
    """Without FFmpeg every LeRobotDataset printed ~100 lines of torchcodec tracebacks."""
    cli.quiet_torchcodec_warning()
    cli._TorchcodecNote.shown = False
    logger = logging.getLogger("lerobot.utils.import_utils")
    wall = "Could not load libtorchcodec.\n" + "Traceback ...\n" * 100
    with caplog.at_level(logging.INFO, logger="lerobot.utils.import_utils"):
        for _ in range(3):
            logger.warning(
                f"{wall}\n'torchcodec' is installed but cannot be loaded (see the error above). Falling back"
            )
        logger.warning("an unrelated warning")
    messages = [r.getMessage() for r in caplog.records]
    assert messages == [cli.TORCHCODEC_NOTE, "an unrelated warning"]


def test_progress_bars_throttle_when_not_on_a_terminal():
    """tqdm wrote every update into non-terminal logs (a make demo log was megabytes)."""
    code = (
        "import time, lerobot_unidextok\n"  # the package import throttles every bar imported after it
        "from tqdm import tqdm\n"
        "for _ in tqdm(range(100)): time.sleep(0.01)\n"
    )
    env = subprocess_env()
    env.pop("TQDM_MININTERVAL", None)
    r = subprocess.run([sys.executable, "-c", code], env=env, check=False, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("%|") <= 3  # first and last refresh, not one per update
    r = subprocess.run([sys.executable, "-c", code.replace(", lerobot_unidextok", "")], env=env,
                       check=False, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert r.stderr.count("%|") > 3  # without it: a refresh every 0.1 s
