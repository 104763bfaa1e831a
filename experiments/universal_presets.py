"""The shipped universal tokenizer on the LinkerHand vendor preset poses (real hand-tuned poses for the hardware,
never trained on): `linkerhand-ros2-sdk/<model>_positions.yaml`, both sides, for the models the registry has.
Hands added by a YAML spec only (zero-shot, the unknown-hand embedding): experiments/universal_zeroshot.py.

    python experiments/universal_presets.py [--real=../shared/data/real] [--nearest]   # --nearest: the nearest codes
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from lerobot_unidextok import hands
from lerobot_unidextok.evaluation.report import evaluate_tokenizer
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES, UniDexTok
from lerobot_unidextok.training import HandStates
from lerobot_unidextok.utils.shared_data import real_data_dir

REPO = Path(__file__).resolve().parents[1]
SIDES = {"RIGHT_HAND": "right", "LEFT_HAND": "left"}


def preset_states(real: Path) -> HandStates:
    parts = []
    for path in sorted((real / "linkerhand-ros2-sdk").glob("*_positions.yaml")):
        name = "linkerhand_" + path.stem.split("_")[0].lower()
        if name not in hands.names():
            continue
        spec, data = hands.get(name), yaml.safe_load(path.read_text())
        for key, side in SIDES.items():
            for preset in data.get(key) or []:
                q = np.asarray(spec.to_udhm(np.asarray(preset["POSITION"], dtype=np.float64), side=side))[None]
                parts.append(HandStates(q, [name], spec.mask("semantic")[None]))
    return HandStates.concat(parts)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--real", type=Path, default=real_data_dir(REPO))
    p.add_argument("--nearest", action="store_true", help="the nearest codes (default: the package's encoding)")
    args = p.parse_args()
    model = UniDexTok.from_pretrained(UNIVERSAL_SMALL, encoding=NEAREST_CODES if args.nearest else None)
    report = evaluate_tokenizer(model, preset_states(args.real))
    print(f"encoding: {report['model']['encoding']}")
    print("| hand | presets (both sides) | MPJAE (deg) | MPJPE (mm) | fingertip (mm) |\n|---|---|---|---|---|")
    for hand, e in report["per_hand"].items():
        print(f"| {hand} | {e['rows']} | {e['mpjae_deg']:.3f} | {e['mpjpe_mm']:.3f} | {e['fingertip_mm']:.3f} |")


if __name__ == "__main__":
    main()
