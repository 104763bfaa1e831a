"""The real-data fixture: absent folder = skip, incomplete folder = failure naming the missing files."""

import os
import subprocess
import sys
from pathlib import Path

from real_data import REAL_DATA_FILES, missing_real_data

REPO_ROOT = Path(__file__).resolve().parents[1]
PROBE = """
def test_probe(real_data_dir):
    pass
"""


def _run_probe(tmp_path: Path, real_data: Path) -> subprocess.CompletedProcess:
    """Run a one-test file that asks for `real_data_dir`, with this repository's conftest, in a subprocess."""
    probe = tmp_path / "probe" / "test_probe.py"
    probe.parent.mkdir(parents=True)
    probe.write_text(PROBE)
    (probe.parent / "conftest.py").write_text((REPO_ROOT / "tests" / "conftest.py").read_text())
    (probe.parent / "fixtures").symlink_to(REPO_ROOT / "tests" / "fixtures")
    env = {**os.environ, "UNIDEXTOK_REAL_DATA": str(real_data)}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", str(probe)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, check=False)  # fmt: skip


def test_absent_folder_skips_incomplete_folder_fails(tmp_path):
    """Catches: a copy of ../shared with a file missing skipped the tests that need it instead of failing."""
    absent = _run_probe(tmp_path / "a", tmp_path / "does-not-exist")
    assert absent.returncode == 0 and "1 skipped" in absent.stdout, absent.stdout
    assert "real hand recordings not found" in absent.stdout

    partial = tmp_path / "partial"
    for name in REAL_DATA_FILES[1:]:  # everything but the first file
        (partial / name).parent.mkdir(parents=True, exist_ok=True)
        (partial / name).write_text("x")
    assert missing_real_data(partial) == [REAL_DATA_FILES[0]]
    broken = _run_probe(tmp_path / "b", partial)
    assert broken.returncode == 1 and "1 error" in broken.stdout, broken.stdout
    assert "present but incomplete" in broken.stdout and REAL_DATA_FILES[0] in broken.stdout

    (partial / REAL_DATA_FILES[0]).parent.mkdir(parents=True, exist_ok=True)
    (partial / REAL_DATA_FILES[0]).write_text("x")
    complete = _run_probe(tmp_path / "c", partial)
    assert complete.returncode == 0 and "1 passed" in complete.stdout, complete.stdout
