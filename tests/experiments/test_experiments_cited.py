"""Every experiment a newcomer finds has its table: each runnable script in `experiments/` is named with its
`python experiments/<name>.py` command in the README, benchmarks/RESULTS.md, docs/ or a shipped model's card, and each
module without a `__main__` is imported by an experiment (a helper, not a forgotten study). Issue 55's house rule."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = sorted(p for p in (ROOT / "experiments").glob("*.py") if p.name != "__init__.py")


def _pages() -> dict[str, str]:
    pages = [ROOT / "README.md", ROOT / "benchmarks" / "RESULTS.md", *sorted((ROOT / "docs").glob("*.md")),
             *sorted((ROOT / "lerobot_unidextok" / "pretrained").glob("*/README.md"))]  # fmt: skip
    return {str(p.relative_to(ROOT)): p.read_text(encoding="utf-8") for p in pages}


def _command(name: str) -> re.Pattern[str]:
    return re.compile(rf"python (-m )?experiments[/.]{name}(\.py)?\b")


def _is_script(path: Path) -> bool:
    return "__main__" in path.read_text(encoding="utf-8")


@pytest.mark.parametrize("path", [p for p in EXPERIMENTS if _is_script(p)], ids=lambda p: p.stem)
def test_each_experiment_script_is_named_with_its_command_where_its_results_are(path: Path) -> None:
    command = _command(path.stem)
    pages = [name for name, text in _pages().items() if command.search(text)]
    assert pages, (f"experiments/{path.name} is named with its command in no results page (README.md, "
                   "benchmarks/RESULTS.md, docs/, a model card): cite its table there, or retire it")  # fmt: skip


@pytest.mark.parametrize("path", [p for p in EXPERIMENTS if not _is_script(p)], ids=lambda p: p.stem)
def test_each_experiment_helper_module_is_used_by_an_experiment(path: Path) -> None:
    imported = re.compile(rf"\bexperiments\.{path.stem}\b|from experiments import [^\n]*\b{path.stem}\b")
    users = [p.stem for p in EXPERIMENTS if p != path and imported.search(p.read_text(encoding="utf-8"))]
    assert users, f"experiments/{path.name} has no __main__ and no experiment imports it: delete it"


def test_the_check_fails_on_an_uncited_script() -> None:
    """A mere mention of the file name is not its command."""
    command = _command("orphan")
    assert not command.search("see experiments/orphan.py for details")
    assert command.search("`python experiments/orphan.py --seed=1`")
    assert command.search("python -m experiments.orphan")
