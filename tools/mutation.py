"""Mutation testing of the core modules: inject one-token bugs, run the tests that cover them, count kills.

A tool, not a CI gate. Run from the project root with the project's venv::

    python tools/mutation.py                                  # every core module, every mutant
    python tools/mutation.py --modules processor udhm --max-mutants 60 --seed 0
    python tools/mutation.py --list                           # the modules, their files and test folders
    python tools/mutation.py --max-mutants 30 --seed 0 --combine outputs/mutation-a outputs/mutation-b
                                                              # one report from runs on disjoint modules

How it works (a small harness of our own rather than mutmut, which rewrites the package into a
`mutants/` tree with trampolines that the editable install, LeRobot's plugin discovery and the subprocess
tests of this repository would not see):

1. The package is copied to a temp folder in its installed shape (the checkout's `converters/` and `configs/`
   inside it, as pyproject.toml's package-dir maps them), and that folder goes first on `sys.path` and `PYTHONPATH`, so in-process tests and the subprocesses they start
   (CLIs, `lerobot-train`, worker pools) import the mutated copy; the repository is never modified.
2. One baseline run per module: the module's test folders under coverage with one context per test, which
   gives, for every line, the tests that execute it, and each test's duration. A failing baseline stops
   the run (mutants must be judged against a green suite).
3. Mutants: one token each, found through the AST (so only operators of expressions are touched):
   comparison (`<` <-> `<=`, `==` <-> `!=`, `is` <-> `is not`, `in` <-> `not in`), arithmetic
   (`+` <-> `-`, `*` <-> `/`, `//` -> `/`, `**` -> `*`, `%` -> `/`), augmented assignment, `and` <-> `or`,
   unary `-` and `not` removed, numbers n -> n + 1, `True` <-> `False`, `min` <-> `max` (and argmin/argmax,
   any/all, minimum/maximum, floor/ceil). Not mutated: strings, docstrings, f-strings, type annotations,
   the message of a `raise`, lines with `# pragma: no mutate`, and display code, which changes no behaviour a
   test should pin: logging / print / warning calls, progress-bar text (`set_postfix`, `set_description`),
   the keyword arguments of `tqdm(...)` (its iterable is mutated) and method calls on a bar, and the
   statements that only feed them: `x = tqdm(x, ...)`, an assignment whose names only display code reads,
   an `if` / `with` whose whole body is display (e.g. `if step % 10 == 0: bar.set_postfix(...)`, the test
   included). See `_display_statements`. Also not mutated: the number in a negative size of `reshape(...)`;
   numpy infers any negative size (`reshape(-2, 3)` == `reshape(-1, 3)`: equivalent) and torch raises on it
   (a crash every covering test kills): neither says anything about the tests.
4. Each mutant: the file in the copy is rewritten, a forked child (heavy libraries already imported by the
   parent) runs `pytest -x` on the tests that cover the mutated line, fastest first, and the file is
   restored. Failing tests (or a collection error) = killed; a run longer than `--timeout-factor` x the
   baseline time of those tests = killed (timeout); passing = survived; no covering test = survived
   (no coverage). Mutants that do not compile are dropped.

The report (per module: mutants in the module, mutants run, killed, kill rate; then every survivor as
`file:line original -> mutant`) is printed and written to `--output` (JSON + Markdown). With
`--max-mutants N` at most N mutants per module are drawn (seeded); the overall figure is then each
module's kill rate weighted by its number of mutants, an estimate of the full-run figure.
"""

from __future__ import annotations

import argparse
import ast
import functools
import io
import json
import os
import random
import shutil
import signal
import sys
import tempfile
import time
import tokenize
import tomllib
from collections import defaultdict
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "lerobot_unidextok"

# module name -> (source files relative to the package, test paths relative to the project root)
MODULES: dict[str, tuple[list[str], list[str]]] = {
    "udhm": (["udhm/*.py"], ["tests/udhm"]),
    "hands": (["hands/*.py"], ["tests/hands"]),
    "tokenizer/quantizer": (["tokenizer/quantizer.py"], ["tests/tokenizer"]),
    "training/loop": (["training/loop.py"], ["tests/training"]),
    "conversion/pipeline": (["conversion/pipeline.py"], ["tests/conversion"]),
    "conversion/mapping": (["conversion/mapping.py"], ["tests/conversion"]),
    "processor": (["processor/*.py"], ["tests/processor", "tests/policies"]),
    "evaluation/metrics": (["evaluation/metrics.py"], ["tests/evaluation"]),
}

# calls whose arguments never change behaviour (messages, progress-bar text); their subtrees are not mutated
_QUIET_CALLS = {
    "print", "warn", "debug", "info", "warning", "error", "exception", "critical", "note",
    "set_description", "set_description_str", "set_postfix", "set_postfix_str",
}  # fmt: skip
# progress bars (`progress_bar` is utils/cli.py's tqdm): their keyword arguments and their methods are display
_BAR_FACTORIES = {"tqdm", "trange", "progress_bar"}
_SWAP_NAMES = {
    "min": "max", "max": "min", "argmin": "argmax", "argmax": "argmin", "any": "all", "all": "any",
    "minimum": "maximum", "maximum": "minimum", "floor": "ceil", "ceil": "floor", "amin": "amax", "amax": "amin",
}  # fmt: skip
_BINOP = {
    ast.Add: ("+", "-"), ast.Sub: ("-", "+"), ast.Mult: ("*", "/"), ast.Div: ("/", "*"), ast.FloorDiv: ("//", "/"),
    ast.Pow: ("**", "*"), ast.Mod: ("%", "/"),
}  # fmt: skip
_CMPOP = {
    ast.Lt: ("<", "<="), ast.LtE: ("<=", "<"), ast.Gt: (">", ">="), ast.GtE: (">=", ">"), ast.Eq: ("==", "!="),
    ast.NotEq: ("!=", "=="), ast.Is: ("is", "is not"), ast.IsNot: ("is not", "is"), ast.In: ("in", "not in"),
    ast.NotIn: ("not in", "in"),
}  # fmt: skip


# ---------------------------------------------------------------------------------------------
# mutants
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Mutant:
    module: str
    path: str  # relative to the package
    line: int  # 1-based, where the token starts
    col: int  # 0-based character offset in that line
    end_line: int
    end_col: int
    original: str
    replacement: str

    @property
    def label(self) -> str:
        return f"{PACKAGE}/{self.path}:{self.line} `{self.original}` -> `{self.replacement or '(removed)'}`"

    def apply(self, source: str) -> str:
        lines = source.splitlines(keepends=True)
        start = sum(len(x) for x in lines[: self.line - 1]) + self.col
        end = sum(len(x) for x in lines[: self.end_line - 1]) + self.end_col
        assert source[start:end] == self.original, (self.label, source[start:end])
        return source[:start] + self.replacement + source[end:]


def _char_col(lines: list[str], line: int, byte_col: int) -> int:
    """ast offsets are UTF-8 byte offsets; tokenize and our edits use characters."""
    return len(lines[line - 1].encode()[:byte_col].decode(errors="ignore"))


def _call_name(node: ast.Call) -> str:
    func = node.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _display_statements(tree: ast.AST) -> list[ast.stmt]:
    """Statements that only feed progress bars, logs or prints (see "Not mutated" in the module docstring).

    A statement is display-only when it is: a call of a quiet function (logging, print, warnings, progress-bar
    text) or a method call on a progress bar (a name bound to `tqdm(...)`); an import; `x = tqdm(x, ...)`
    (wrapping an iterable in a bar); an assignment to names that display-only code or quiet calls read and
    nothing else reads (names compared module-wide, so a name read anywhere else keeps its assignment
    mutated); or an `if` / `with` whose whole body is display-only (its test is then display too).
    Found as a fixed point: a statement joins the set once what reads its names is display-only.
    """
    bars = {
        t.id
        for node in ast.walk(tree)
        if isinstance(node, ast.Assign)
        and isinstance(node.value, ast.Call)
        and _call_name(node.value) in _BAR_FACTORIES
        for t in node.targets
        if isinstance(t, ast.Name)
    }

    def display_call(node: ast.AST) -> bool:
        if not isinstance(node, ast.Call):
            return False
        func = node.func
        return _call_name(node) in _QUIET_CALLS or (
            isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id in bars
        )

    def names_read(node: ast.AST, display: set[int], into: tuple[set[str], set[str]], shown: bool = False) -> None:
        """Names read by behaviour (into[0]) and by display code (into[1])."""
        shown = shown or id(node) in display or display_call(node)
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load):
            into[shown].add(node.id)
        for child in ast.iter_child_nodes(node):
            names_read(child, display, into, shown)

    def only_display(stmt: ast.stmt, display: set[int], behaviour: set[str], shown: set[str]) -> bool:
        if isinstance(stmt, ast.Import | ast.ImportFrom | ast.Pass):
            return True
        if isinstance(stmt, ast.Expr):
            return display_call(stmt.value)
        if isinstance(stmt, ast.Assign) and all(isinstance(t, ast.Name) for t in stmt.targets):
            names = {t.id for t in stmt.targets}
            value = stmt.value
            if isinstance(value, ast.Call) and _call_name(value) in _BAR_FACTORIES:  # x = tqdm(x, ...)
                return bool(value.args) and isinstance(value.args[0], ast.Name) and {value.args[0].id} == names
            return bool(names & shown) and not names & behaviour
        if isinstance(stmt, ast.If | ast.With):
            return all(id(s) in display for s in [*stmt.body, *getattr(stmt, "orelse", [])])
        return False

    statements = [n for n in ast.walk(tree) if isinstance(n, ast.stmt)]
    display: set[int] = set()
    while True:
        behaviour, shown = set(), set()
        names_read(tree, display, (behaviour, shown))
        new = {id(s) for s in statements if id(s) not in display and only_display(s, display, behaviour, shown)}
        if not new:
            return [s for s in statements if id(s) in display]
        display |= new


def _excluded_nodes(tree: ast.AST) -> set[int]:
    """ids of nodes whose subtree is not mutated (messages, display code, annotations, TYPE_CHECKING blocks)."""
    skip: set[int] = set()

    def mark(node: ast.AST | None) -> None:
        if node is not None:
            skip.update(id(n) for n in ast.walk(node))

    for stmt in _display_statements(tree):
        mark(stmt)

    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            mark(node)
        elif isinstance(node, ast.Raise):
            mark(node.exc)
        elif isinstance(node, ast.Assert):
            mark(node.msg)
        elif isinstance(node, ast.Call):
            name = _call_name(node)
            if name in _QUIET_CALLS:
                mark(node)
            elif name in _BAR_FACTORIES:  # tqdm(iterable, desc=..., disable=...): the iterable is behaviour
                for kw in node.keywords:
                    mark(kw)
            elif name == "reshape":  # numpy reads any negative size as "infer": -1 -> -2 is equivalent
                for arg in node.args:
                    if isinstance(arg, ast.UnaryOp) and isinstance(arg.op, ast.USub):
                        skip.add(id(arg.operand))
        elif isinstance(node, ast.arg | ast.AnnAssign):
            mark(node.annotation)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            mark(node.returns)
        elif isinstance(node, ast.keyword) and node.arg == "strict":  # zip(..., strict=True): a guard, no result
            mark(node)
        elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            mark(node)
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            mark(node)
    return skip


def find_mutants(module: str, rel_path: str, source: str) -> list[Mutant]:
    """Every one-token mutant of `source` that still compiles."""
    tree = ast.parse(source)
    lines = source.splitlines(keepends=True)
    tokens = [
        t for t in tokenize.generate_tokens(io.StringIO(source).readline) if t.type in (tokenize.OP, tokenize.NAME)
    ]
    skip = _excluded_nodes(tree)
    no_mutate = {i + 1 for i, text in enumerate(lines) if "pragma: no mutate" in text}
    found: list[tuple[tuple[int, int], tuple[int, int], str, str]] = []

    def pos(node: ast.AST, end: bool = False) -> tuple[int, int]:
        line = node.end_lineno if end else node.lineno
        col = node.end_col_offset if end else node.col_offset
        return line, _char_col(lines, line, col)

    def tokens_between(start: tuple[int, int], stop: tuple[int, int]) -> list[tokenize.TokenInfo]:
        return [t for t in tokens if t.start >= start and t.end <= stop and t.string not in "()"]

    def op_between(left: ast.AST, right: ast.AST, text: str, replacement: str) -> None:
        between = tokens_between(pos(left, end=True), pos(right))
        words = text.split()
        for i in range(len(between) - len(words) + 1):
            if [t.string for t in between[i : i + len(words)]] == words:
                found.append((between[i].start, between[i + len(words) - 1].end, text, replacement))
                return

    for node in ast.walk(tree):
        if id(node) in skip or getattr(node, "lineno", None) in no_mutate:
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOP:
            op_between(node.left, node.right, *_BINOP[type(node.op)])
        elif isinstance(node, ast.Compare):
            for left, op, right in zip([node.left, *node.comparators], node.ops, node.comparators, strict=False):
                if type(op) in _CMPOP:
                    op_between(left, right, *_CMPOP[type(op)])
        elif isinstance(node, ast.BoolOp):
            text = "and" if isinstance(node.op, ast.And) else "or"
            for left, right in zip(node.values, node.values[1:], strict=False):
                op_between(left, right, text, "or" if text == "and" else "and")
        elif isinstance(node, ast.AugAssign) and type(node.op) in _BINOP:
            text, replacement = _BINOP[type(node.op)]
            op_between(node.target, node.value, text + "=", replacement + "=")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.Not):
            first = tokens_between(pos(node), pos(node.operand))
            if first and first[0].string in ("-", "not"):
                found.append((first[0].start, first[0].end, first[0].string, ""))
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float, bool):
            start, end = pos(node), pos(node, end=True)
            text = "".join(lines[start[0] - 1][start[1] : end[1]]) if start[0] == end[0] else None
            if text is None:
                continue
            if isinstance(node.value, bool):
                found.append((start, end, text, str(not node.value)))
            elif isinstance(node.value, int):
                found.append((start, end, text, str(node.value + 1)))
            else:
                found.append((start, end, text, repr(node.value + 1.0)))
        elif isinstance(node, ast.Name | ast.Attribute) and isinstance(getattr(node, "ctx", None), ast.Load):
            name = node.id if isinstance(node, ast.Name) else node.attr
            if name in _SWAP_NAMES:
                last = [t for t in tokens_between(pos(node), pos(node, end=True)) if t.string == name]
                if last:
                    found.append((last[-1].start, last[-1].end, name, _SWAP_NAMES[name]))

    mutants = []
    for (line, col), (end_line, end_col), text, replacement in sorted(set(found)):
        mutant = Mutant(module, rel_path, line, col, end_line, end_col, text, replacement)
        try:
            compile(mutant.apply(source), rel_path, "exec")
        except SyntaxError:
            continue
        mutants.append(mutant)
    return mutants


# ---------------------------------------------------------------------------------------------
# running tests in a forked child
# ---------------------------------------------------------------------------------------------
def _preload() -> None:
    """Import the heavy third-party libraries once in the parent; children are forked from it.
    The HF variables are those of tests/conftest.py, set first because huggingface_hub reads them on import."""
    hf = Path(tempfile.mkdtemp(prefix="unidextok-mutation-hf-"))
    for key, value in {
        "HF_HOME": hf / "hf", "HF_LEROBOT_HOME": hf / "hf" / "lerobot", "HF_DATASETS_CACHE": hf / "hf" / "datasets",
        "HF_HUB_OFFLINE": "1", "MPLBACKEND": "Agg", "HTTPS_PROXY": "http://127.0.0.1:9",
        "HTTP_PROXY": "http://127.0.0.1:9", "NO_PROXY": "127.0.0.1,localhost", "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1", "PYTHONDONTWRITEBYTECODE": "1",
    }.items():  # fmt: skip
        os.environ.setdefault(key, str(value))
    sys.dont_write_bytecode = True
    import numpy  # noqa: F401
    import pytest  # noqa: F401
    import scipy.optimize  # noqa: F401
    import torch

    torch.set_num_threads(1)
    import lerobot.datasets  # noqa: F401
    import lerobot.policies  # noqa: F401
    import lerobot.processor  # noqa: F401


def _run_child(src_root: Path, args: list[str], make_plugin: Callable[[], object]) -> int:
    """Fork; in the child, import the package from `src_root` and run pytest. Returns the child's pid."""
    pid = os.fork()
    if pid:
        return pid
    code = 3
    try:
        os.setsid()  # its own process group, so a timeout kills the subprocesses it started too
        sys.path.insert(0, str(src_root))
        os.environ["PYTHONPATH"] = os.pathsep.join([str(src_root), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        import pytest

        # `pythonpath = ["."]` (pyproject, for `experiments.*`) would put the checkout's package ahead of the copy:
        # the copy first, then the checkout root
        sys.path.insert(1, str(ROOT))
        base = ["-p", "no:cacheprovider", "-q", "-o", "addopts=--import-mode=importlib", "-o", "pythonpath="]
        code = int(pytest.main([*base, *args], plugins=[make_plugin()]))
    finally:
        os._exit(code)


class _Select:
    """pytest plugin for a mutant: run only `tests` (node ids), in that order."""

    def __init__(self, tests: list[str]) -> None:
        self.order = {t: i for i, t in enumerate(tests)}

    def pytest_collection_modifyitems(self, items, config):  # noqa: ANN001
        keep = sorted((i for i in items if i.nodeid in self.order), key=lambda i: self.order[i.nodeid])
        items[:] = keep


class _Recorder:
    """pytest plugin for the baseline: per-test coverage contexts and durations."""

    def __init__(self, result_file: Path, cov_files: list[str]) -> None:
        import coverage

        self.result_file = result_file
        self.cov = coverage.Coverage(data_file=None, include=cov_files, branch=False)
        self.cov.start()
        self.durations: dict[str, float] = defaultdict(float)
        self.failed: list[str] = []

    def pytest_runtest_protocol(self, item):  # noqa: ANN001
        self.cov.switch_context(item.nodeid)
        self._t0 = time.perf_counter()

    def pytest_runtest_logreport(self, report):  # noqa: ANN001
        self.durations[report.nodeid] += report.duration
        if report.failed:
            self.failed.append(report.nodeid)

    def pytest_sessionfinish(self, session):  # noqa: ANN001
        self.cov.stop()
        data = self.cov.get_data()
        lines: dict[str, dict[int, list[str]]] = {}
        for path in data.measured_files():
            by_line = data.contexts_by_lineno(path)
            lines[path] = {n: sorted(c for c in ctx if c) for n, ctx in by_line.items()}
        self.result_file.write_text(json.dumps({"lines": lines, "durations": self.durations, "failed": self.failed}))


def _wait(pid: int, timeout_s: float) -> tuple[int | None, float]:
    """(exit code or None on timeout, seconds)."""
    t0 = time.monotonic()
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status), time.monotonic() - t0
        if time.monotonic() - t0 > timeout_s:
            try:
                os.killpg(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)
            return None, time.monotonic() - t0
        time.sleep(0.05)


# ---------------------------------------------------------------------------------------------
# main
# ---------------------------------------------------------------------------------------------
@dataclass
class ModuleResult:
    module: str
    files: list[str]
    mutants_total: int = 0
    run: int = 0
    killed: int = 0
    timeouts: int = 0
    no_coverage: int = 0
    survivors: list[str] = field(default_factory=list)
    baseline_s: float = 0.0
    mutants_s: float = 0.0

    @property
    def kill_rate(self) -> float:
        return self.killed / self.run if self.run else float("nan")


def module_files(module: str) -> list[str]:
    patterns, _ = MODULES[module]
    return sorted(str(p.relative_to(ROOT / PACKAGE)) for pat in patterns for p in (ROOT / PACKAGE).glob(pat))


def make_copy() -> Path:
    """The package as installed, in a temp folder: `lerobot_unidextok/` with the folders pyproject.toml's
    package-dir maps into it (`converters/` as `lerobot_unidextok/converters`, `configs/` likewise)."""
    src_root = Path(tempfile.mkdtemp(prefix="unidextok-mutation-src-"))
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / PACKAGE, src_root / PACKAGE, ignore=ignore)
    package_dir = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    for name, folder in package_dir.items():
        shutil.copytree(ROOT / folder, src_root.joinpath(*name.split(".")), ignore=ignore)
    return src_root


def run_module(module: str, src_root: Path, args: argparse.Namespace, work: Path) -> ModuleResult:
    files = module_files(module)
    result = ModuleResult(module, files)
    _, test_paths = MODULES[module]
    copies = {f: src_root / PACKAGE / f for f in files}

    # baseline: which tests cover which line, and how long each takes
    t0 = time.monotonic()
    baseline_file = work / f"baseline-{module.replace('/', '_')}.json"
    pid = _run_child(
        src_root, list(test_paths), functools.partial(_Recorder, baseline_file, [str(p) for p in copies.values()])
    )
    code, _ = _wait(pid, args.baseline_timeout)
    result.baseline_s = time.monotonic() - t0
    if not baseline_file.is_file():
        raise SystemExit(
            f"{module}: the baseline test run did not finish (exit {code}); run pytest {' '.join(test_paths)}"
        )
    baseline = json.loads(baseline_file.read_text())
    if code != 0 or baseline["failed"]:
        raise SystemExit(f"{module}: the baseline fails ({baseline['failed'][:5]}); mutants need a green suite")
    durations = baseline["durations"]
    print(f"[{module}] baseline: {len(durations)} tests, {result.baseline_s:.0f} s", flush=True)

    mutants = [m for f in files for m in find_mutants(module, f, (ROOT / PACKAGE / f).read_text())]
    result.mutants_total = len(mutants)
    if args.max_mutants is not None and len(mutants) > args.max_mutants:
        mutants = sorted(random.Random(f"{args.seed}:{module}").sample(mutants, args.max_mutants),
                         key=lambda m: (m.path, m.line, m.col))  # fmt: skip

    t0 = time.monotonic()
    for i, mutant in enumerate(mutants, 1):
        covering = baseline["lines"].get(str(copies[mutant.path]), {}).get(str(mutant.line))
        if covering is None:  # no test executes the line
            tests = []
        elif covering:
            tests = sorted(covering, key=lambda t: durations.get(t, 0.0))
        else:  # executed only while importing: every test of the module may depend on it
            tests = sorted(durations, key=lambda t: durations[t])
        result.run += 1
        if not tests:
            result.no_coverage += 1
            result.survivors.append(mutant.label + " (no covering test)")
            verdict = "survived (no coverage)"
        else:
            original = copies[mutant.path].read_text()
            copies[mutant.path].write_text(mutant.apply(original))
            try:
                budget = args.timeout_factor * sum(durations.get(t, 1.0) for t in tests) + 30.0
                files = sorted({t.split("::")[0] for t in tests})
                code, _ = _wait(_run_child(src_root, ["-x", *files], functools.partial(_Select, tests)), budget)
            finally:
                copies[mutant.path].write_text(original)
            if code is None:
                result.killed += 1
                result.timeouts += 1
                verdict = "killed (timeout)"
            elif code == 0:
                result.survivors.append(mutant.label)
                verdict = "survived"
            elif code in (4, 5):  # usage error / no tests collected: a harness problem, not a verdict
                raise SystemExit(f"{module}: pytest exit {code} for {mutant.label}; tests {tests[:3]}...")
            else:
                result.killed += 1
                verdict = "killed"
        if args.verbose or verdict.startswith("survived"):
            print(f"[{module}] {i}/{len(mutants)} {verdict}: {mutant.label}", flush=True)
        elif i % 25 == 0:
            print(f"[{module}] {i}/{len(mutants)} done, {result.killed}/{result.run} killed", flush=True)
    result.mutants_s = time.monotonic() - t0
    return result


def report(results: list[ModuleResult], args: argparse.Namespace, cpu_s: float, wall_s: float) -> str:
    total = sum(r.mutants_total for r in results)
    run = sum(r.run for r in results)
    killed = sum(r.killed for r in results)
    weighted = sum(r.kill_rate * r.mutants_total for r in results if r.run) / max(
        1, sum(r.mutants_total for r in results if r.run)
    )
    sampled = args.max_mutants is not None
    rows = [
        "| module | files | mutants | run | killed | of which timeouts | no covering test | kill rate |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in results:
        rows.append(f"| `{r.module}` | {len(r.files)} | {r.mutants_total} | {r.run} | {r.killed} | {r.timeouts} | "
                    f"{r.no_coverage} | {100 * r.kill_rate:.1f} % |")  # fmt: skip
    rows.append(f"| **all** | {sum(len(r.files) for r in results)} | {total} | {run} | {killed} | "
                f"{sum(r.timeouts for r in results)} | {sum(r.no_coverage for r in results)} | "
                f"**{100 * (weighted if sampled else killed / max(run, 1)):.1f} %** |")  # fmt: skip
    head = (
        f"Mutation kill rate {'(sample of at most ' + str(args.max_mutants) + ' mutants per module, seed ' + str(args.seed) + '; overall = per-module rates weighted by mutants)' if sampled else '(every mutant)'}; "
        f"{run} mutants run in {wall_s / 60:.1f} min wall, {cpu_s / 60:.1f} min CPU (parent + children)."
    )
    survivors = [f"- {s}" for r in results for s in r.survivors]
    return "\n".join([head, "", *rows, "", f"Survivors ({len(survivors)}):", "", *survivors, ""])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--modules", nargs="*", default=list(MODULES), help=f"subset of {list(MODULES)}")
    parser.add_argument("--max-mutants", type=int, default=None, help="at most this many mutants per module (sampled)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the mutant sample")
    parser.add_argument(
        "--timeout-factor", type=float, default=4.0, help="mutant run budget = factor x baseline + 30 s"
    )
    parser.add_argument("--baseline-timeout", type=float, default=1800.0, help="seconds for one module's baseline")
    parser.add_argument("--output", type=Path, default=ROOT / "outputs" / "mutation", help="report folder")
    parser.add_argument("--list", action="store_true", help="list modules, files, test paths and mutant counts")
    parser.add_argument("--verbose", action="store_true", help="print every mutant's verdict")
    parser.add_argument(
        "--combine", type=Path, nargs="+", default=None, metavar="FOLDER",
        help="report folders of runs on disjoint modules (same --max-mutants and --seed): print one report",
    )  # fmt: skip
    args = parser.parse_args(argv)
    unknown = sorted(set(args.modules) - set(MODULES))
    if unknown:
        parser.error(f"unknown module(s) {unknown}; choose from {list(MODULES)}")
    if args.combine:
        results = [
            ModuleResult(**r) for folder in args.combine for r in json.loads((folder / "report.json").read_text())
        ]
        if len({r.module for r in results}) != len(results):
            parser.error("--combine: a module appears in more than one report")
        results.sort(key=lambda r: list(MODULES).index(r.module))
        wall = sum(r.baseline_s + r.mutants_s for r in results)  # per-module time; CPU is per run (not stored)
        text = report(results, args, float("nan"), wall).replace("nan min CPU (parent + children)", "CPU: see each run")
        print(text)
        return 0
    if args.list:
        for module in args.modules:
            files = module_files(module)
            n = sum(len(find_mutants(module, f, (ROOT / PACKAGE / f).read_text())) for f in files)
            print(f"{module}: {n} mutants in {', '.join(files)}; tests {' '.join(MODULES[module][1])}")
        return 0
    try:
        import coverage  # noqa: F401
    except ImportError:
        parser.error("coverage is needed for the baseline: pip install -e '.[dev]'")

    t_wall, t_cpu = time.monotonic(), os.times()
    os.chdir(ROOT)  # test node ids are relative to the project root
    _preload()
    src_root = make_copy()
    work = Path(tempfile.mkdtemp(prefix="unidextok-mutation-"))
    try:
        results = [run_module(m, src_root, args, work) for m in args.modules]
    finally:
        shutil.rmtree(src_root, ignore_errors=True)
    cpu = os.times()
    cpu_s = sum(getattr(cpu, k) - getattr(t_cpu, k) for k in ("user", "system", "children_user", "children_system"))
    text = report(results, args, cpu_s, time.monotonic() - t_wall)
    print("\n" + text)
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "report.md").write_text(text)
    (args.output / "report.json").write_text(json.dumps([asdict(r) for r in results], indent=1))
    print(f"written to {args.output / 'report.md'} and report.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
