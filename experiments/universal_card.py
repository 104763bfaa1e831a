"""Score the universal run on data it never trained on and write the shipped package folder + card.

    python experiments/universal_card.py --run=outputs/unidextok_universal --data=outputs/universal_data \
        --cpu_s=<training CPU seconds> --commit=<commit the run trained at> --encoding.method=greedy \
        --encoding.rounds=2 --encoding.changes=16 --encoding.tolerance_deg=0.1

Writes lerobot_unidextok/pretrained/universal-small/ (config.json, model.safetensors, training_state.json,
eval.json, README.md) from <run>/best; `experiments.universal` holds the figures. The package's
config.json gets the `--encoding.*` settings (its own encoding, `EncodingConfig`); the figures are measured with them (eval.json
`results`, the card's evaluation table) and with the nearest codes, the paper's encoding (`nearest_codes`). The
in-range figures cover the hands the checkpoint trained on (hands registered later: experiments/universal_zeroshot.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
from pathlib import Path

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.universal import figures, write_package
from lerobot_unidextok.evaluation.report import encoding
from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, SHIPPED
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig, UniDexTok
from lerobot_unidextok.tokenizer.configuration_unidextok import SEARCH_METHODS

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
    # the package's own encoding (EncodingConfig), written into its config.json
    p.add_argument("--encoding.method", dest="method", default="greedy", choices=SEARCH_METHODS, help="code search")
    p.add_argument("--encoding.rounds", dest="rounds", type=int, default=1, help="code search rounds (0 = nearest)")
    p.add_argument("--encoding.changes", dest="changes", type=int, default=16, help="greedy: changes per round")
    p.add_argument("--encoding.sweeps", dest="sweeps", type=int, default=2, help="sweeps: passes per round")
    p.add_argument("--encoding.tolerance_deg", dest="tolerance_deg", type=float, default=0.0,
                   help="greedy: rows within it stop searching")  # fmt: skip
    args = p.parse_args(argv)
    commit = subprocess.check_output(["git", "-C", str(REPO), "rev-parse", args.commit or "HEAD"], text=True).strip()
    model = UniDexTok.from_pretrained(str(args.run / "best"))
    datasets = {label: str(args.data / name) for label, name in DATA.items()}
    own = EncodingConfig(rounds=args.rounds, method=args.method, sweeps=args.sweeps, changes=args.changes,
                         tolerance_deg=args.tolerance_deg)  # fmt: skip
    hands = model.config.trained_hands or None
    model.with_encoding(NEAREST_CODES)
    nearest = figures(model, datasets, hands)
    model.with_encoding(own)
    results = figures(model, datasets, hands)
    per_round = (f"--encoding.changes={own.changes} --encoding.tolerance_deg={own.tolerance_deg:g}"
                 if own.method == "greedy" else f"--encoding.sweeps={own.sweeps}")  # fmt: skip
    state = json.loads((args.run / "best" / "training_state.json").read_text())
    data_cmd = "python experiments/universal_data.py --out=outputs/universal_data"
    train_cmd = "nice -n 10 unidextok-train --config_path=train/universal"
    commands = {
        "data": data_cmd,
        "train": train_cmd,
        "figures": "python experiments/universal_card.py --run=outputs/unidextok_universal "
        f"--cpu_s={args.cpu_s:.0f} --commit={commit[:12]} --encoding.method={own.method} "
        f"--encoding.rounds={own.rounds} {per_round}",
        "G1 test episodes, same figure": f"unidextok-eval --checkpoint={DEFAULT_TOKENIZER} "
        "--datasets='[outputs/universal_data/g1_inspire]'",
    }
    about = {
        "commit": commit,
        "training_cpu_s": args.cpu_s,
        "steps": state.get("steps"),
        "best_step": state.get("step"),
        "commands": commands,
        "encoding": encoding(model.config),
        "nearest_codes": nearest,
        "in_range": "5000 states per hand, uniform inside its registered ranges, random side, seed 0 "
        "(experiments.universal.in_range_figures)",
    }
    sections = [
        "## Encoding",
        "",
        f"This package's config.json sets its encoding (`encoding`: method {own.method}, rounds {own.rounds}, "
        f"{per_round.replace('--encoding.', '').replace(' ', ', ')}): `encode`, and so the processor step and every "
        "`<type>_udt` policy by default, refines each group's nearest code with the decoder-aware code search "
        "(docs/tokenizer.md \"Code search\", its cost per frame and per row; same tokens, same decoder), and the "
        "evaluation table above is measured that way. `encode(..., encoding=NEAREST_CODES)` (`unidextok-eval "
        "--encoding.rounds=0`, `--policy.udt_encoding.rounds=0`) gives the nearest codes, the paper's encoding; on "
        "the same rows they measure (`eval.json` `nearest_codes`):",
        "",
        "| | rows | mpjae_deg | mpjpe_mm | fingertip_mm |",
        "|---|---|---|---|---|",
        *[f"| {name} | {e['rows']} | {e['mpjae_deg']:.4g} | {e['mpjpe_mm']:.4g} | {e['fingertip_mm']:.4g} |"
          for name, e in nearest.items()],
        "",
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
        "The schedule, and then the code search settings, were chosen among full-length runs and settings on "
        "their selection episodes and on in-range states of another seed than the table's (`python "
        "experiments/universal_screen.py --runs=... [--methods='[sweeps,greedy]' --rounds='[0,1,2]' "
        "--sweeps='[...]' --changes='[...]']`, docs/tokenizer.md \"How the recipe was chosen\"), "
        "never on the figures above.",
        "",
        "The evaluation table above is `eval.json` (`results`): test episodes / held-out recordings of each "
        "converted dataset, and every registered hand on in-range states (" + about["in_range"] + "). "
        "The G1 row equals `" + commands["G1 test episodes, same figure"] + "`.",
        "",
    ]
    target = write_package(args.run / "best", SHIPPED[DEFAULT_TOKENIZER], DEFAULT_TOKENIZER, results, about,
                           sections, RECORDINGS, config_overrides={"encoding": dataclasses.asdict(own)})  # fmt: skip
    print(json.dumps(results, indent=2))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
