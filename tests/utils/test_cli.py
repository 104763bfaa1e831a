"""CLI output: one-line errors, the one-line torchcodec note, progress bars throttled off a terminal."""

import logging
import re
import time

import pytest

from lerobot_unidextok.errors import ExistingOutputError, InvalidInputError, MissingInputError, UnavailableError
from lerobot_unidextok.utils import cli


def test_run_cli_turns_user_mistakes_into_one_line(capsys, monkeypatch):
    monkeypatch.delenv("UNIDEXTOK_TRACEBACK", raising=False)

    def bad() -> None:
        raise MissingInputError("data/x not found: convert it first")

    with pytest.raises(SystemExit) as info:
        cli.run_cli(bad)
    assert info.value.code == 2
    assert capsys.readouterr().err.splitlines()[0] == "error: data/x not found: convert it first"
    monkeypatch.setenv("UNIDEXTOK_TRACEBACK", "1")
    with pytest.raises(FileNotFoundError):  # a MissingInputError is a FileNotFoundError for callers
        cli.run_cli(bad)
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        cli.run_cli(lambda: 1 / 0)


def test_builtin_errors_are_bugs_only_user_errors_are_one_line(capsys, monkeypatch):
    """ValueError / KeyError / FileNotFoundError counted as user mistakes, so bugs lost their tracebacks: only
    `lerobot_unidextok.errors.UserError` is one line now."""
    monkeypatch.delenv("UNIDEXTOK_TRACEBACK", raising=False)
    for bug in (ValueError("shapes (3,) and (4,) not aligned"), KeyError("step"), FileNotFoundError("x")):

        def raise_it(exc=bug):
            raise exc

        with pytest.raises(type(bug)):
            cli.run_cli(raise_it)
    for mistake in (InvalidInputError("bad value"), UnavailableError("offline"), ExistingOutputError("exists")):

        def raise_it(exc=mistake):
            raise exc

        with pytest.raises(SystemExit) as info:
            cli.run_cli(raise_it)
        assert info.value.code == 2 and capsys.readouterr().err.startswith(f"error: {mistake}")


def test_a_runtime_error_is_a_bug_and_a_user_error_is_one_line(capsys, monkeypatch):
    """RuntimeError counted as a user mistake, so real bugs (e.g. replicas drifting apart) lost their traceback."""
    monkeypatch.delenv("UNIDEXTOK_TRACEBACK", raising=False)

    def bug() -> None:
        raise RuntimeError("step 10: model replicas differ")

    def offline_push() -> None:
        raise UnavailableError("HF_HUB_OFFLINE is set: unset it (or set HF_HUB_OFFLINE=0) to push")

    with pytest.raises(RuntimeError, match="replicas differ"):
        cli.run_cli(bug)
    with pytest.raises(SystemExit) as info:
        cli.run_cli(offline_push)
    assert info.value.code == 2
    assert (
        capsys.readouterr().err.splitlines()[0]
        == "error: HF_HUB_OFFLINE is set: unset it (or set HF_HUB_OFFLINE=0) to push"
    )


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


def _refreshes(text: str, total: int) -> list[tuple[int, str]]:
    """(counter, postfix) of every refresh a tqdm bar wrote: `desc: 40%|#### | 60/150 [00:01<00:02, 50it/s, loss=59]`,
    refreshes separated by carriage returns (or newlines)."""
    found = re.findall(rf"(\d+)/{total} \[([^\]]*)\]", text)
    return [(int(n), ", ".join(p for p in inside.split(", ") if "=" in p)) for n, inside in found]


def test_progress_bar_refreshes_every_30_s_off_a_terminal(tmp_path, monkeypatch):
    """Conversion wrote 92 bar updates in 2 s and training 213 in 3 minutes into a log file, with the step
    counter frozen while the loss postfix changed: tqdm's set_postfix refreshes on every call."""
    monkeypatch.delenv("TQDM_MININTERVAL", raising=False)
    log = tmp_path / "log.txt"
    with log.open("w") as f:  # a file, as when stderr is redirected
        bar = cli.progress_bar(range(150), file=f, desc="loop")
        for i in bar:
            time.sleep(0.004)
            bar.set_postfix(loss=i)
    refreshes = _refreshes(log.read_text(), 150)
    assert [n for n, _ in refreshes] == [0, 150]  # the start and the end, nothing in between (< 30 s)
    assert refreshes[-1][1] == "loss=149"  # the last postfix, written with the final counter


def test_progress_bar_honours_tqdm_mininterval_and_writes_counter_with_postfix(tmp_path, monkeypatch):
    monkeypatch.setenv("TQDM_MININTERVAL", "0.05")
    log = tmp_path / "log.txt"
    with log.open("w") as f:
        bar = cli.progress_bar(range(150), file=f, desc="loop")
        for i in bar:
            time.sleep(0.004)
            bar.set_postfix(loss=i)
    refreshes = _refreshes(log.read_text(), 150)
    assert 5 < len(refreshes) < 40  # ~0.6 s of updates at one refresh per 0.05 s, not one per update (150)
    counters = [n for n, _ in refreshes]
    assert counters == sorted(counters) and counters[-1] == 150
    # every refresh after the first shows the postfix of the step it counts (loss = step index)
    assert all(postfix == f"loss={n - 1}" for n, postfix in refreshes[1:]), refreshes


@pytest.mark.parametrize("program", ["lerobot-train", "my_script.py"])
def test_user_errors_inside_a_lerobot_cli_end_in_one_line(tmp_path, program):
    """The plugin's hook: in a LeRobot CLI a UserError that reaches the top is one `error:` line and exit 2
    after the exit handlers ran; a bug keeps its traceback; any other program keeps Python's own hook."""
    import subprocess
    import sys

    script = tmp_path / program
    script.write_text(
        "import atexit, sys\n"
        "from lerobot_unidextok.utils.cli import user_errors_in_lerobot_clis\n"
        "from lerobot_unidextok.errors import InvalidInputError\n"
        "user_errors_in_lerobot_clis()\n"
        "atexit.register(lambda: print('exit handler ran'))\n"
        "if sys.argv[1] == 'bug': 1 / 0\n"
        "if sys.argv[1] == 'wrapped':  # draccus: a config's refusal as the cause of its ParsingError\n"
        "    try:\n"
        "        raise InvalidInputError('data/x is not a converted dataset: convert it first')\n"
        "    except InvalidInputError as err:\n"
        "        raise RuntimeError('Could not instantiate the config') from err\n"
        "if sys.argv[1] == 'bug_while_handling':\n"
        "    try:\n"
        "        raise InvalidInputError('data/x is not a converted dataset: convert it first')\n"
        "    except InvalidInputError:\n"
        "        1 / 0\n"
        "raise InvalidInputError('data/x is not a converted dataset: convert it first')\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "UNIDEXTOK_TRACEBACK"}
    for what in ("mistake", "wrapped", "bug", "bug_while_handling"):
        r = subprocess.run([sys.executable, str(script), what], capture_output=True, text=True, env=env, timeout=60)
        assert "exit handler ran" in r.stdout
        if what in ("mistake", "wrapped") and program.startswith("lerobot-"):
            assert r.returncode == 2 and "Traceback" not in r.stderr
            assert r.stderr.splitlines()[0] == "error: data/x is not a converted dataset: convert it first"
        else:
            assert r.returncode == 1 and "Traceback" in r.stderr
