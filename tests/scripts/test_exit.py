"""How the commands end, as a user sees it in a terminal: the real console scripts in subprocesses. A user
mistake is one `error:` line and exit 2, --help exits 0, and nothing is printed at interpreter exit."""

import sys
from pathlib import Path

import pytest
from linkerhand_udhm import subprocess_env

BIN = Path(sys.executable).parent


def _run(args: list[str], tmp_path) -> tuple[int, str]:
    import subprocess

    r = subprocess.run([str(BIN / args[0]), *args[1:]], capture_output=True, text=True, timeout=180, cwd=tmp_path,
                       env=subprocess_env(HF_HUB_OFFLINE="1", HF_HOME=str(tmp_path / "hf")))  # fmt: skip
    return r.returncode, r.stderr


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, code, first_line",
    [
        (["unidextok-train", "--help"], 0, None),
        (["unidextok-train", "--config_path=nope.yaml"], 2, "error: --config_path nope.yaml not found"),
        (["unidextok-train", "--datasets=[./missing]"], 2, "error: dataset folder missing does not exist"),
        (["unidextok-train", "--datasets=[lab/uncached]"], 2, "error: dataset 'lab/uncached' is not on this machine"),
        (["unidextok-eval", "--checkpoint=./missing", "--datasets=[lab/x]"], 2, "error: "),
        (["unidextok-train", "--stepz=3"], 2, None),  # argparse: the usage, then its one error line
    ],
)
def test_commands_end_with_one_line_and_nothing_at_exit(args, code, first_line, tmp_path):
    """`unidextok-train` exiting before torch was imported printed "Exception ignored in atexit callback:
    _leave_process_group ... can't register atexit after shutdown"; a missing config or dataset a traceback."""
    rc, err = _run(args, tmp_path)
    assert rc == code, err[-2000:]
    assert "Traceback" not in err and "Exception ignored" not in err, err[-2000:]
    if first_line is not None:
        assert err.startswith(first_line), err[:500]
    elif code == 2:
        assert err.rstrip().splitlines()[-1] == "unidextok-train: error: unrecognized arguments: --stepz=3"
