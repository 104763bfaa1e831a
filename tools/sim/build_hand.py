"""Write hands' built MJCF into the package, with the URDF's licence beside each, so that the simulator runs them
without the URDF.

    UNIDEXTOK_URDF_DIR=../shared/data/urdf python tools/sim/build_hand.py --hand allegro leap xhand1
    UNIDEXTOK_URDF_DIR=../shared/data/urdf python tools/sim/build_hand.py --shipped   # rebuild every shipped one

The simulator builds any hand spec's model from its URDF on first use (`lerobot_env_unidextok/urdf_model.py`) and
caches it outside the repository; a model written here, `lerobot_env_unidextok/assets/<embodiment>/
<embodiment>_right.xml`, is the one used where `$UNIDEXTOK_URDF_DIR` is not set. Ship only a hand whose URDF's
licence permits redistribution (MIT, BSD-3-Clause, Apache-2.0: ../shared/data/urdf/README.md). The licence is
copied from beside the URDF: its own `LICENSE.<name>` (dex-urdf's per-hand files), else the folder's `LICENSE` as
`LICENSE.<folder>`. `tests/lerobot_env_unidextok/test_urdf_model.py` rebuilds every shipped model from its URDF
and compares the bytes.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from lerobot_env_unidextok.urdf_model import SHIPPED_DIR, build_mjcf, shipped_path, urdf_path
from lerobot_unidextok import hands


def licence_of(urdf: Path) -> tuple[Path, str]:
    """(the licence file beside `urdf`, the name it ships under)."""
    stem = urdf.name.removesuffix(".urdf").rsplit("_", 1)[0]  # leap_hand_right.urdf -> leap_hand
    own = urdf.parent / f"LICENSE.{stem}"
    if own.is_file():
        return own, own.name
    folder = urdf.parent / "LICENSE"
    if folder.is_file():
        return folder, f"LICENSE.{urdf.parent.name}"
    raise SystemExit(f"error: no licence beside {urdf} (LICENSE.{stem} or LICENSE): a built model ships only with "
                     "its URDF's licence")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hand", nargs="*", default=[], help="registered hand specs with a URDF")
    ap.add_argument("--shipped", action="store_true", help="every hand whose built model ships already")
    args = ap.parse_args()
    names = list(args.hand) + [n for n in hands.names() if args.shipped and shipped_path(hands.get(n))]
    if not names:
        ap.error("name hands with --hand, or pass --shipped")
    for name in dict.fromkeys(names):
        spec = hands.get(name)
        path = urdf_path(spec, "right")
        if path is None:
            raise SystemExit(f"error: no URDF found for {name}: set UNIDEXTOK_URDF_DIR to the folder holding "
                             f"{spec.urdf.files['right'] if spec.urdf else 'it'}")  # fmt: skip
        folder = SHIPPED_DIR / spec.embodiment
        folder.mkdir(parents=True, exist_ok=True)
        out = folder / f"{spec.embodiment}_right.xml"
        out.write_text(build_mjcf(path.read_text(), spec, "right", source=str(path)))
        licence, licence_name = licence_of(path)
        shutil.copyfile(licence, folder / licence_name)
        print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KB) and {licence_name}")


if __name__ == "__main__":
    main()
