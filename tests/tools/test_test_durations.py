"""tools/test_durations.py sums a JUnit report per test file, longest first; tests/durations.json, which the
suite's conftest orders the test files by, names only test files this checkout has."""

import json
from pathlib import Path

import pytest
from tool_module import tool_module

ROOT = Path(__file__).resolve().parents[2]

REPORT = """<?xml version="1.0" encoding="utf-8"?><testsuites><testsuite name="pytest" tests="4">
<testcase classname="tests.a.test_short" name="test_one" time="1.25" />
<testcase classname="tests.b.test_long" name="test_one" time="3.0" />
<testcase classname="tests.a.test_short" name="test_two" time="0.5" />
<testcase classname="tests.b.test_long" name="test_two[x]" time="4.04" />
</testsuite></testsuites>"""


@pytest.fixture(scope="module")
def durations():
    with tool_module("test_durations.py", "unidextok_test_durations_tool") as module:
        yield module


def test_a_report_is_summed_per_file_longest_first(durations, tmp_path):
    (tmp_path / "junit.xml").write_text(REPORT)
    got = durations.file_durations(tmp_path / "junit.xml")
    assert list(got.items()) == [("tests/b/test_long.py", 7.0), ("tests/a/test_short.py", 1.8)]


def test_a_report_of_no_tests_or_not_of_this_suite_is_refused(durations, tmp_path):
    (tmp_path / "empty.xml").write_text("<testsuites><testsuite /></testsuites>")
    with pytest.raises(ValueError, match="no test cases"):
        durations.file_durations(tmp_path / "empty.xml")
    (tmp_path / "other.xml").write_text(REPORT.replace("tests.b.test_long", "pkg.test_long"))
    with pytest.raises(ValueError, match="'pkg.test_long' is not a module under tests/"):
        durations.file_durations(tmp_path / "other.xml")


def test_the_committed_durations_name_test_files_of_this_checkout():
    listed = json.loads((ROOT / "tests" / "durations.json").read_text())
    assert list(listed.values()) == sorted(listed.values(), reverse=True)
    gone = [f for f in listed if not (ROOT / f).is_file()]
    assert not gone, f"renamed or removed test files: rerun tools/test_durations.py (its docstring): {gone}"
    slow = {f for f, s in listed.items() if s >= 60}
    assert {"tests/policies/test_udt.py", "tests/test_wheel.py"} <= slow  # the long files are listed as long
