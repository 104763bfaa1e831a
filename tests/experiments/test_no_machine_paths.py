"""No absolute machine paths in code, configs, notebooks or docs (tests' temporary folders aside): the real
data is `../shared/...` beside the checkout, figures cite scripts in the repository."""

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MACHINE_PATH = re.compile(r"(?<![\w.])(/work/|/tmp\b|/home/\w|/root/|/Users/\w)")


def _tracked_files() -> list[str]:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "ls-files"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [f for f in out.splitlines() if not f.startswith("tests/") and (ROOT / f).is_file()]


def test_no_machine_paths_outside_tests():
    hits = {}
    for name in _tracked_files():
        if Path(name).suffix in (".png", ".parquet", ".safetensors"):
            continue
        text = (ROOT / name).read_text(errors="ignore")
        found = sorted({m.group(0) for m in MACHINE_PATH.finditer(text)})
        if found:
            hits[name] = found
    assert not hits, f"machine paths (use ../shared/..., a config field or a repo script): {hits}"


def test_no_merge_conflict_markers():
    """A conflict block committed by a merge (it happened once, in docs/architecture.md) fails here."""
    marker = re.compile(r"^(<{7} |>{7} |={7}$)", re.M)
    hits = [name for name in _tracked_files() if Path(name).suffix in (".py", ".md", ".yaml", ".toml", ".cfg", ".txt")
            and marker.search((ROOT / name).read_text(errors="ignore"))]  # fmt: skip
    assert not hits, f"merge conflict markers in {hits}"
