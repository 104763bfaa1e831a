"""Start-up cost of the package and its CLIs, each in a fresh process, beside `import torch` in the same run.

Every command runs `--repeats` times in a new interpreter, round-robin (torch, package, ..., torch, ...) so
every command sees the same load on shared cores; the table gives the median wall and CPU seconds (user +
system of the process, from `wait4`) and each median's ratio to `import torch`'s. Targets, judged on CPU
seconds (on shared cores the wall clock mostly measures the other jobs): the package import <= 1.5x
`import torch`; every `unidextok-*` CLI's `--help` <= 2.5 s. The CLIs are read from
`[project.scripts]` in pyproject.toml and run from this interpreter's bin folder (an installed venv).

    .venv/bin/python benchmarks/bench_startup.py
    .venv/bin/python benchmarks/bench_startup.py --repeats 9 --plugin   # + LeRobot's plugin import
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
REFERENCE = "import torch"
IMPORTS = [
    REFERENCE,
    "from lerobot_unidextok import UniDexTok",
    "import lerobot_unidextok.udhm",
    "import lerobot_unidextok.hands",
    "import lerobot_unidextok.tokenizer",
]
PLUGIN = "import lerobot_policy_unidextok"  # what LeRobot's CLIs import: registers the _udt types (LeRobot)
HELP_TARGET_S = 2.5
IMPORT_TARGET_RATIO = 1.5


def cli_names() -> list[str]:
    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    return sorted(scripts)


def run_once(argv: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of one fresh process; raises if it fails."""
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd=REPO)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    stderr = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{stderr[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5, help="fresh processes per command (median)")
    parser.add_argument("--plugin", action="store_true", help=f"also time `{PLUGIN}` (imports LeRobot)")
    args = parser.parse_args()

    commands: dict[str, list[str]] = {code: [sys.executable, "-c", code] for code in IMPORTS}
    if args.plugin:
        commands[PLUGIN] = [sys.executable, "-c", PLUGIN]
    for name in cli_names():
        commands[f"{name} --help"] = [str(BIN / name), "--help"]

    for argv in commands.values():  # warm the OS file cache and __pycache__ once, untimed
        run_once(argv)
    wall: dict[str, list[float]] = {k: [] for k in commands}
    cpu: dict[str, list[float]] = {k: [] for k in commands}
    for _ in range(args.repeats):
        for label, argv in commands.items():
            w, c = run_once(argv)
            wall[label].append(w)
            cpu[label].append(c)

    ref_wall, ref_cpu = statistics.median(wall[REFERENCE]), statistics.median(cpu[REFERENCE])
    print(f"{args.repeats} fresh processes per command, medians; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores; python {sys.version.split()[0]}")  # fmt: skip
    print()
    print("| command | wall s | x torch (wall) | CPU s | x torch (CPU) | target |")
    print("|---|---|---|---|---|---|")
    for label in commands:
        w, c = statistics.median(wall[label]), statistics.median(cpu[label])
        if label == REFERENCE:
            target = "reference"
        elif label.endswith("--help"):
            target = f"<= {HELP_TARGET_S} s: {'ok' if c <= HELP_TARGET_S else 'MISSED'}"
        elif label == PLUGIN:
            target = "(LeRobot)"
        else:
            target = f"<= {IMPORT_TARGET_RATIO}x: {'ok' if c <= IMPORT_TARGET_RATIO * ref_cpu else 'MISSED'}"
        print(f"| `{label}` | {w:.2f} | {w / ref_wall:.2f} | {c:.2f} | {c / ref_cpu:.2f} | {target} |")


if __name__ == "__main__":
    main()
