"""tools/mutation.py: which code gets mutants (display code is skipped, logic is not) and that a mutant applies.

Runs `find_mutants` on small sources written here; no tests are run under mutation.
"""

import sys
from pathlib import Path

import pytest
from tool_module import tool_module

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def mutation():
    with tool_module("mutation.py", "unidextok_mutation_tool") as module:
        yield module


def _mutated_lines(mutation, source: str) -> dict[int, set[tuple[str, str]]]:
    found: dict[int, set[tuple[str, str]]] = {}
    for m in mutation.find_mutants("demo", "demo.py", source):
        found.setdefault(m.line, set()).add((m.original, m.replacement))
    return found


SOURCE = """\
import logging
from tqdm import tqdm

logger = logging.getLogger(__name__)


def train(steps, items, progress):
    total = 0
    bar = tqdm(range(steps - 1), disable=not progress, total=steps + 1)
    for step in bar:
        total += step * 2
        if step % 10 == 0:
            shown = total / 3
            bar.set_postfix(loss=shown - 1)
        if total > 100:
            logger.info("big %d", total + 1)
    wrapped = items
    show = progress if progress is not None else len(items) > 4
    if show:
        wrapped = tqdm(wrapped, desc="items")
    for item in wrapped:
        total -= item
    limit = total - 7
    if limit > 0:
        logger.warning("limit %d", limit)
    return total, limit
"""


def test_display_code_gets_no_mutants_and_logic_keeps_them(mutation):
    """The display rule: progress-bar keywords and methods, logging calls, values that only they read, and
    `if` blocks that only display are skipped; the bar's iterable, the loop's arithmetic, and a value that
    is also returned keep their mutants. Catches a rule that skips real logic (e.g. everything inside
    `tqdm(...)`, or a whole `if` that also returns) or that leaves display mutants in (survivors that no
    test should kill)."""
    lines = _mutated_lines(mutation, SOURCE)
    # behaviour: the iterable of the bar (steps - 1), the accumulation, the loop test, the returned limit
    assert ("-", "+") in lines[9]  # range(steps - 1)
    assert ("+", "-") not in lines[9]  # total=steps + 1 is a bar keyword
    assert ("not", "") not in lines[9]  # disable=not progress
    assert {("+=", "-="), ("*", "/"), ("2", "3")} <= lines[11]
    assert ("-=", "+=") in lines[22]
    assert {("-", "+"), ("7", "8")} <= lines[23]  # `limit` is returned: behaviour
    # display: the postfix block (its test, the value only it reads), the `if`s that only log (their tests
    # too, though `limit` itself is behaviour), the bar wrapping and the value that only decides it
    for line in (12, 13, 14, 15, 16, 18, 19, 20, 24, 25):
        assert line not in lines, (line, lines.get(line))


def test_if_that_only_logs_is_display_only_when_its_body_is(mutation):
    """`if x: logger.info(...)` has no behaviour (its test is skipped); `if x: logger.info(...); return`
    does (its test keeps its mutants). Catches a rule that looks at the first statement only."""
    source = (
        "import logging\nlogger = logging.getLogger(__name__)\n\n\n"
        "def f(x):\n"
        "    if x > 1:\n"
        "        logger.info('big')\n"
        "    if x > 2:\n"
        "        logger.info('bigger')\n"
        "        return 0\n"
        "    return x\n"
    )
    lines = _mutated_lines(mutation, source)
    assert 6 not in lines
    assert {(">", ">="), ("2", "3")} <= lines[8]


def test_a_value_read_by_logic_and_by_a_log_stays_mutated(mutation):
    """An assignment is display-only only when nothing but display code reads the name; a value that also
    reaches the result keeps its mutants. Catches a rule that drops assignments read by any log call."""
    source = (
        "import logging\nlogger = logging.getLogger(__name__)\n\n\n"
        "def f(x):\n"
        "    y = x * 2\n"
        "    logger.info('y %s', y)\n"
        "    z = x + 1\n"
        "    logger.info('z %s', z)\n"
        "    return y\n"
        "\n\n"
        "def g(x):\n"
        "    unused = x - 1\n"  # a dead store is not display code: kept (and reported if it survives)
        "    return x\n"
    )
    lines = _mutated_lines(mutation, source)
    assert ("*", "/") in lines[6]
    assert 8 not in lines
    assert ("-", "+") in lines[14]


def test_mutant_applies_one_token(mutation):
    """Each mutant changes exactly its token, so the mutated file differs from the original in one place."""
    source = "def f(a, b):\n    return a - b if a < b else max(a, b)\n"
    mutants = mutation.find_mutants("demo", "demo.py", source)
    assert {(m.original, m.replacement) for m in mutants} == {("-", "+"), ("<", "<="), ("max", "min")}
    for m in mutants:
        mutated = m.apply(source)
        assert mutated != source
        compile(mutated, "demo.py", "exec")
    swap = next(m for m in mutants if m.original == "max")
    assert swap.apply(source) == "def f(a, b):\n    return a - b if a < b else min(a, b)\n"


def test_reshape_placeholder_is_not_bumped_but_its_sign_is_removed(mutation):
    """numpy reads any negative size in `reshape` as "infer", so `-1 -> -2` there is an equivalent mutant
    (skipped); dropping the minus (`reshape(1, 3)`) is a real one (kept), and so are other numbers."""
    source = "def f(x):\n    return x.reshape(-1, 3) + 1\n"
    found = {(m.original, m.replacement) for m in mutation.find_mutants("demo", "demo.py", source)}
    assert found == {("-", ""), ("3", "4"), ("+", "-"), ("1", "2")}
    assert sum(1 for m in mutation.find_mutants("demo", "demo.py", source) if m.original == "1") == 1


def test_combined_report_weights_module_rates_by_mutants(mutation, tmp_path, capsys):
    """`--combine` joins runs on disjoint modules into one report; with a sample, the overall figure is each
    module's kill rate weighted by its number of mutants: (0.8 x 100 + 0.9 x 50) / 150 = 83.3 %, not the
    pooled 51 / 60 = 85.0 %. A module in two reports is an error."""
    import json

    def run(folder: str, module: str, total: int, killed: int):
        (tmp_path / folder).mkdir()
        result = mutation.ModuleResult(module, ["x.py"], mutants_total=total, run=30, killed=killed)
        (tmp_path / folder / "report.json").write_text(json.dumps([mutation.asdict(result)]))

    run("a", "udhm", 100, 24)
    run("b", "hands", 50, 27)
    assert mutation.main(["--max-mutants", "30", "--combine", str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "| `udhm` | 1 | 100 | 30 | 24 | 0 | 0 | 80.0 % |" in out
    assert "| `hands` | 1 | 50 | 30 | 27 | 0 | 0 | 90.0 % |" in out
    assert "**83.3 %**" in out
    with pytest.raises(SystemExit):
        mutation.main(["--combine", str(tmp_path / "a"), str(tmp_path / "a")])


def test_the_copy_has_the_installed_shape_and_imports_from_itself(mutation):
    """The copy holds the checkout's top-level converters/ and configs/ where an install puts them, and a fresh
    interpreter with the copy first on PYTHONPATH imports the readers and the configs from the copy."""
    import shutil
    import subprocess

    src_root = mutation.make_copy()
    try:
        package = src_root / "lerobot_unidextok"
        assert (package / "converters" / "dexycb.py").is_file() and (package / "configs" / "train" / "small.yaml").is_file()
        code = ("import lerobot_unidextok.converters.dexycb as d, lerobot_unidextok.configs as c; "
                "print(d.__file__); print(c.shipped_config('train/small'))")  # fmt: skip
        out = subprocess.run([sys.executable, "-c", code], env={"PYTHONPATH": str(src_root), "PATH": ""},
                             capture_output=True, text=True, check=True, cwd=src_root).stdout.split()  # fmt: skip
        assert all(Path(p).is_relative_to(src_root) for p in out), out
    finally:
        shutil.rmtree(src_root)
