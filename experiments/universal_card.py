"""Score the universal run on data it never trained on and write the shipped package folder + card.

    python experiments/universal_card.py --run=outputs/unidextok_universal --data=outputs/universal_data \
        --cpu_s=<training CPU seconds> --commit=<commit the run trained at>

Writes lerobot_unidextok/pretrained/universal-small/ (config.json, model.safetensors, training_state.json,
eval.json, README.md) from <run>/best; `lerobot_unidextok.experiments.universal` holds the figures.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

from lerobot_unidextok.experiments.universal import figures, write_package
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, SHIPPED
from lerobot_unidextok.tokenizer import UniDexTok

REPO = Path(__file__).resolve().parents[1]
DATA = {  # label -> converted dataset (experiments/universal_data.py)
    "G1 Inspire": "g1_inspire",
    "human clip": "human_clip",
    "MediaPipe photos": "mediapipe",
}
RECORDINGS = [
    "- `g1-inspire/` (../shared/data/real): real Unitree G1 teleoperation with two Inspire hands, LeRobot v2.1, "
    "episodes 0-9 of YifanTian07/G1-policy-train; converted with `--source=lerobot`; the converter's test "
    "episodes (2 of 10) were not trained on",
    "- `dex-retargeting/human_joint_right.npy`: 621 frames of one real right hand (MediaPipe world landmarks, "
    "30 fps) cut into ten 2 s segments, `--source=keypoints`; 2 segments held out",
    "- `mediapipe/mediapipe_hand_fixtures.json`: the six HandLandmarker results with world landmarks (real "
    "photos, right hands), one frame each, `--source=keypoints`; 1 held out",
    "- every other registered hand (both sides): states uniform inside its registered joint ranges "
    "(`range_hands: [all]`); the LinkerHand vendor presets and the Allegro home pose have no converter and "
    "are not in the data",
]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", type=Path, default=Path("outputs/unidextok_universal"))
    p.add_argument("--data", type=Path, default=Path("outputs/universal_data"))
    p.add_argument("--cpu_s", type=float, required=True, help="training CPU time (user + sys), seconds")
    p.add_argument("--commit", default="", help="commit of the code the run trained with (default: HEAD)")
    args = p.parse_args(argv)
    commit = args.commit or subprocess.check_output(["git", "-C", str(REPO), "rev-parse", "HEAD"], text=True).strip()
    model = UniDexTok.from_pretrained(str(args.run / "best"))
    datasets = {label: str(args.data / name) for label, name in DATA.items()}
    results = figures(model, datasets)
    state = json.loads((args.run / "best" / "training_state.json").read_text())
    data_cmd = "python experiments/universal_data.py --out=outputs/universal_data"
    train_cmd = "nice -n 10 unidextok-train --config_path=configs/train/universal.yaml"
    commands = {
        "data": data_cmd,
        "train": train_cmd,
        "figures": "python experiments/universal_card.py --run=outputs/unidextok_universal "
        f"--cpu_s={args.cpu_s:.0f} --commit={commit[:12]}",
        "G1 test episodes, same figure": f"unidextok-eval --checkpoint={DEFAULT_TOKENIZER} "
        "--datasets='[outputs/universal_data/g1_inspire]'",
    }
    about = {
        "commit": commit,
        "training_cpu_s": args.cpu_s,
        "steps": state.get("steps"),
        "best_step": state.get("step"),
        "commands": commands,
        "in_range": "5000 states per hand, uniform inside its registered ranges, random side, seed 0 "
        "(lerobot_unidextok.experiments.universal.in_range_figures)",
    }
    sections = [
        "## Recipe",
        "",
        f"Trained at commit `{commit[:12]}` of lerobot-unidextok, {state.get('steps')} steps "
        f"(checkpoint of step {state.get('step')}, chosen on held-out training episodes), "
        f"{args.cpu_s / 60:.1f} CPU-minutes on one thread:",
        "",
        "```bash",
        data_cmd,
        train_cmd,
        commands["figures"],
        "```",
        "",
        "The schedule was chosen among full-length runs on their selection episodes and on in-range states "
        "of another seed than the table's (`python experiments/universal_screen.py --runs=...`, docs/tokenizer.md "
        "\"How the recipe was chosen\"), never on the figures above.",
        "",
        "The evaluation table above is `eval.json` (`results`): test episodes / held-out recordings of each "
        "converted dataset, and every registered hand on in-range states (" + about["in_range"] + "). "
        "The G1 row equals `" + commands["G1 test episodes, same figure"] + "`.",
        "",
    ]
    target = write_package(args.run / "best", SHIPPED[DEFAULT_TOKENIZER], DEFAULT_TOKENIZER, results, about,
                           sections, RECORDINGS)  # fmt: skip
    print(json.dumps(results, indent=2))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
