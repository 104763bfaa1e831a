"""The checkout's Markdown files are documents, not the output of a script gone wrong.

Commit abaf657 rewrote experiments/README.md from 72 lines to 18,680 (4.5 MB): two table rows written between
every character of the file, as `text.replace("", rows)` does when the anchor meant to be replaced is empty. It
landed because nothing looked at the file's shape. These checks would have failed on it."""

import collections
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SKIPPED = {".venv", "outputs", "build", "dist", ".git", ".pytest_cache", "node_modules"}
MAX_BYTES = 200_000  # the largest document today is about 70 kB
MAX_REPEATS = 100  # a line (not blank, not a table rule) written this often is a loop's output, not prose


def markdown_files() -> list[Path]:
    return sorted(p for p in REPO.rglob("*.md") if not SKIPPED & set(p.relative_to(REPO).parts))


def repeated_lines(text: str) -> list[tuple[str, int]]:
    """Lines that occur more than MAX_REPEATS times, ignoring blank lines and table rules (`|---|`)."""
    lines = [line for line in text.splitlines() if line.strip() and not set(line.strip()) <= set("|-: ")]
    return [(line, n) for line, n in collections.Counter(lines).most_common() if n > MAX_REPEATS]


def problems(path: Path) -> list[str]:
    size = path.stat().st_size
    found = [f"{size:,} bytes (more than {MAX_BYTES:,})"] if size > MAX_BYTES else []
    found += [f"{line[:80]!r}... {n:,} times" for line, n in repeated_lines(path.read_text(errors="replace"))[:3]]
    return found


def test_there_are_documents_to_check():
    names = {p.relative_to(REPO).as_posix() for p in markdown_files()}
    assert {"README.md", "experiments/README.md", "docs/lerobot.md", "benchmarks/RESULTS.md"} <= names


@pytest.mark.parametrize("path", markdown_files(), ids=lambda p: p.relative_to(REPO).as_posix())
def test_a_document_is_not_oversized_and_repeats_no_line(path):
    assert problems(path) == [], f"{path.relative_to(REPO)} looks written by a broken script: {problems(path)}"


def test_the_check_catches_the_abaf657_damage(tmp_path):
    rows = "| `python x.py` (a run) | 1 s | 1 s |\n| `python y.py` | 2 s | 2 s |\n"
    good = "# Experiments\n\n" + "Some prose about what each script measures.\n" * 40
    broken = tmp_path / "README.md"
    broken.write_text(good.replace("", rows))  # what rewrote experiments/README.md
    assert any("times" in p for p in problems(broken))
    fine = tmp_path / "FINE.md"
    fine.write_text(good.replace("# Experiments\n", "# Experiments\n" + rows))
    assert problems(fine) == []
