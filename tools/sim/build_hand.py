"""Write a hand's built MJCF into the package, so that the simulator runs it without the URDF (the Allegro's).

    UNIDEXTOK_URDF_DIR=../shared/data/urdf python tools/sim/build_hand.py --hand allegro

The simulator builds any hand spec's model from its URDF on first use (`lerobot_env_unidextok/urdf_model.py`) and
caches it outside the repository; a model written here, `lerobot_env_unidextok/assets/<embodiment>/
<embodiment>_right.xml`, is the one used where the URDF is not found. Keep the URDF's licence beside it
(`assets/allegro/LICENSE.allegro_hand`). `tests/lerobot_env_unidextok/test_urdf_model.py` rebuilds the shipped
model from the URDF and compares the bytes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lerobot_env_unidextok.urdf_model import SHIPPED_DIR, build_mjcf, urdf_path
from lerobot_unidextok import hands


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hand", required=True, help="a registered hand spec with a URDF")
    ap.add_argument("--out", type=Path, default=None, help="output file (default: the package's assets)")
    args = ap.parse_args()
    spec = hands.get(args.hand)
    path = urdf_path(spec, "right")
    if path is None:
        raise SystemExit(f"error: no URDF found for {args.hand}: set UNIDEXTOK_URDF_DIR to the folder holding "
                         f"{spec.urdf.files['right'] if spec.urdf else 'it'}")  # fmt: skip
    out = args.out or SHIPPED_DIR / spec.embodiment / f"{spec.embodiment}_right.xml"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(build_mjcf(path.read_text(), spec, "right"))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
