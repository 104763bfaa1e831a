"""Write tests/durations.json, each test file's time in seconds, from a pytest JUnit report.

`make test` spreads whole test files over its worker processes (pytest-xdist `--dist loadfile`); the suite's
conftest hands the files out longest first (tests/conftest.py), so the last file to finish is a short one.
Refresh the figures after a large change to the suite (a stale or missing entry only costs balance, never a
test):

    .venv/bin/python -m pytest -q -n 2 --dist loadfile --junitxml=outputs/junit.xml
    .venv/bin/python tools/test_durations.py outputs/junit.xml
"""

from __future__ import annotations

import argparse
import json
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUTPUT = REPO / "tests" / "durations.json"


def file_durations(junit_xml: Path) -> dict[str, float]:
    """{"tests/<...>/test_x.py": seconds summed over its test cases (set-up, call and tear-down)}, longest first."""
    seconds: dict[str, float] = defaultdict(float)
    for case in ET.parse(junit_xml).getroot().iter("testcase"):
        module = case.get("classname", "")  # tests.policies.test_udt (a class adds ".TestX": no test file has one)
        if not module.startswith("tests."):
            raise ValueError(f"{junit_xml}: test case classname {module!r} is not a module under tests/")
        seconds["/".join(module.split(".")) + ".py"] += float(case.get("time", 0.0))
    if not seconds:
        raise ValueError(f"{junit_xml}: no test cases; pass the report of a full run (pytest --junitxml=...)")
    return {f: round(s, 1) for f, s in sorted(seconds.items(), key=lambda kv: (-kv[1], kv[0]))}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("junit_xml", type=Path, help="the report of a full run: pytest --junitxml=<this>")
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    durations = file_durations(args.junit_xml)
    missing = [f for f in durations if not (REPO / f).is_file()]
    if missing:
        raise SystemExit(f"error: the report names test files this checkout does not have: {missing[:5]}")
    args.output.write_text(json.dumps(durations, indent=1) + "\n")
    shown = args.output.relative_to(REPO) if args.output.is_relative_to(REPO) else args.output
    print(f"{shown}: {len(durations)} files, {sum(durations.values()) / 60:.1f} test-minutes in all")


if __name__ == "__main__":
    main()
