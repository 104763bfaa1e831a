"""Hand registry command line.

    python -m lerobot_unidextok.hands [name ...]                     # native joints and UDHM slots
    python -m lerobot_unidextok.hands check SPEC [--urdf FILE]       # kinematic check, per-joint verdicts
    python -m lerobot_unidextok.hands check all                      # every registered hand with a URDF
    python -m lerobot_unidextok.hands skeleton SPEC [--write]        # robot skeleton from the URDF

SPEC is a registered hand name or a path to a hand YAML. Without --urdf the spec's ``urdf.file`` is looked
up under --urdf-dir (default: $UNIDEXTOK_URDF_DIR, else ../shared/data/urdf from the current directory).
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from lerobot_unidextok.constants import FINGERS
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.hands.registry import describe
from lerobot_unidextok.utils.shared_data import urdf_dir


def _default_urdf_dir() -> Path:
    return urdf_dir()


def _load(spec_arg: str):
    from lerobot_unidextok.hands import get, load_spec, names

    if spec_arg in names():
        return get(spec_arg)
    path = Path(spec_arg)
    if not path.is_file():
        raise MissingInputError(f"{spec_arg!r} is neither a registered hand ({', '.join(names())}) nor a YAML file")
    return load_spec(path)


def _urdf_path(spec, side: str, urdf: str | None, urdf_dir: str | None) -> Path:
    if urdf is not None:
        return Path(urdf)
    if spec.urdf is None:
        raise InvalidInputError(
            f"hand {spec.name!r} has no `urdf:` block; pass --urdf and add the keypoint map (docs/hands.md)"
        )
    return Path(urdf_dir) / spec.urdf.files[side] if urdf_dir else _default_urdf_dir() / spec.urdf.files[side]


def _check(args) -> int:
    from lerobot_unidextok.hands import all_specs
    from lerobot_unidextok.hands.check import check_spec

    if args.spec == "all":  # every registered hand with a URDF: one summary line per hand and side
        total = agree = 0
        for spec in (s for s in all_specs() if s.urdf is not None):
            for side in spec.sides if args.side == "both" else (args.side,):
                path = _urdf_path(spec, side, None, args.urdf_dir)
                if not path.is_file():  # a hand whose URDF is not in this folder: said, not counted
                    print(f"{spec.name} ({side}): skipped, {path} not found (get {spec.urdf.source})")
                    continue
                report = check_spec(spec, path, side, num_random=args.random)
                print(report.summary())
                for j in report.disagreements:
                    print(f"    {j.joint}: {j.verdict} (strongest {j.found_slot} {j.found_sign:+d})")
                total, agree = total + len(report.mapped), agree + len(report.mapped) - len(report.disagreements)
        print(f"total: {agree}/{total} mapped (hand, side, joint) entries agree with the robots' kinematics")
        return 0 if agree == total else 1
    spec = _load(args.spec)
    sides = spec.sides if args.side == "both" else (args.side,)
    bad = 0
    for side in sides:
        report = check_spec(spec, _urdf_path(spec, side, args.urdf, args.urdf_dir), side, num_random=args.random)
        print(report.table(), end="\n\n")
        if args.verbose:
            for j in report.joints:
                cells = ", ".join(f"{r.pose}: {r.slot or '-'} {r.sign:+d} x{r.gain:.2f}" for r in j.readings)
                print(f"  {j.joint} [{j.mode}] {cells}")
            print()
        bad += len(report.disagreements)
    return 1 if bad else 0


def skeleton_yaml(spec, skeleton, source: str) -> str:
    """The `skeleton:` block of a hand YAML holding a measured skeleton."""
    import numpy as np

    off = np.asarray(skeleton.palm_offsets_m)
    bones = np.asarray(skeleton.bone_lengths_m)
    lines = [
        "skeleton:",
        f"  source: {source}",
        "  palm_offsets_m:  # thumb CMC / finger MCP from the wrist, canonical frame",
    ]
    lines += [f"    {f}: [{', '.join(f'{v:.4f}' for v in off[i])}]" for i, f in enumerate(FINGERS)]
    lines += ["  bone_lengths_m:  # joint centre to joint centre, MANO-21 order"]
    lines += [f"    {f}: [{', '.join(f'{v:.4f}' for v in bones[i])}]" for i, f in enumerate(FINGERS)]
    return "\n".join(lines) + "\n"


def _skeleton(args) -> int:
    from lerobot_unidextok.hands.urdf import UrdfHand, measure_skeleton

    spec = _load(args.spec)
    side = "right" if "right" in spec.sides else spec.sides[0]
    path = _urdf_path(spec, side, args.urdf, args.urdf_dir)
    hand = UrdfHand.load(path, spec.urdf.keypoints[side])
    source = f"{spec.urdf.source if args.urdf is None else path.name} ({side}), measured by `python -m lerobot_unidextok.hands skeleton {spec.name} --write`"
    block = skeleton_yaml(spec, measure_skeleton(hand, side), source)
    if not args.write:
        print(block, end="")
        return 0
    if spec.path is None:
        raise SystemExit("--write needs a spec loaded from a YAML file")
    text = spec.path.read_text(encoding="utf-8")
    pattern = re.compile(r"^skeleton:\n(?:[ #].*\n|\n)*", re.MULTILINE)
    text = (
        pattern.sub(block, text, count=1) if pattern.search(text) else text.replace("\njoints:", f"\n{block}joints:", 1)
    )
    spec.path.write_text(text, encoding="utf-8")
    print(f"wrote the measured skeleton into {spec.path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in ("check", "skeleton"):
        parser = argparse.ArgumentParser(prog="python -m lerobot_unidextok.hands " + argv[0], description=__doc__,
                                         formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
        parser.add_argument("spec", help="registered hand name, path to a hand YAML, or 'all' (check only)")
        parser.add_argument("--urdf", help="the URDF file (default: the spec's urdf.file under --urdf-dir)")
        parser.add_argument("--urdf-dir", help="folder the spec's urdf.file paths are relative to")
        if argv[0] == "check":
            parser.add_argument("--side", default="both", choices=["right", "left", "both"])
            parser.add_argument("--random", type=int, default=12, help="random poses besides rest and mid")
            parser.add_argument("--verbose", action="store_true", help="print every pose's reading")
        else:
            parser.add_argument("--write", action="store_true", help="replace the spec YAML's skeleton: block")
        args = parser.parse_args(argv[1:])
        return _check(args) if argv[0] == "check" else _skeleton(args)
    print(describe(argv or None))
    return 0


if __name__ == "__main__":
    from lerobot_unidextok.utils.cli import run_cli

    run_cli(main)  # a bad spec or a missing URDF: one `error:` line, exit 2
