"""Score the universal run on data it never trained on and write the shipped package folder + card.

    python experiments/universal_card.py --run=outputs/unidextok_universal --data=outputs/universal_data \
        --cpu_s=<training CPU seconds> --commit=<commit the run trained at> --encoding.method=greedy \
        --encoding.rounds=2 --encoding.changes=16 --encoding.tolerance_deg=0.1
    python experiments/universal_card.py --repo_id=unidextok/universal-small-residual \
        --run=outputs/unidextok_universal_v2 --cpu_s=<...> --commit=<...> --encoding.rounds=0 \
        --train_flags='--preset=small_residual --encoding.rounds=0 --output_dir=outputs/unidextok_universal_v2'

Writes the package folder of shipped id `--repo_id` (`lerobot_unidextok.pretrained.SHIPPED`; default
unidextok/universal-small: lerobot_unidextok/pretrained/universal-small/) with config.json, model.safetensors,
training_state.json, eval.json and README.md from <run>/best, and no other shipped folder; `experiments.universal`
holds the figures. The package's config.json gets the `--encoding.*` settings (its own encoding, `EncodingConfig`);
the figures are measured with them (eval.json `results`, the card's evaluation table) and, for a model with one
stage, with the nearest codes, the paper's encoding (`nearest_codes`); for a residual model (which encodes with the
nearest codes of every stage) with its first stage alone, the paper's 64 symbols (`first_stage`). The in-range
figures cover the hands the checkpoint trained on (hands registered later: experiments/universal_zeroshot.py).
`--train_flags` are the flags given to `unidextok-train --config_path=train/universal` (the card's command).
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
from lerobot_unidextok.pretrained import SHIPPED, UNIVERSAL_SMALL
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
    p.add_argument("--repo_id", default=UNIVERSAL_SMALL, choices=list(SHIPPED), help="the shipped id to write")
    p.add_argument("--run", type=Path, default=Path("outputs/unidextok_universal"))
    p.add_argument("--data", type=Path, default=Path("outputs/universal_data"))
    p.add_argument("--cpu_s", type=float, required=True, help="training CPU time (user + sys), seconds")
    p.add_argument("--commit", default="", help="commit of the code the run trained with (default: HEAD)")
    p.add_argument("--train_flags", default="", help="the run's unidextok-train flags after --config_path")
    p.add_argument("--nice", type=int, default=10, help="the run's nice level (the card's command)")
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
    residual = model.config.residual_stages > 0
    if residual and own.rounds:
        p.error(f"{args.run}/best has {model.config.residual_stages} residual stage(s), which encode with the "
                "nearest codes: pass --encoding.rounds=0")
    hands = model.config.trained_hands or None
    model.with_encoding(NEAREST_CODES)
    if residual:  # the reference: the first stage alone (the paper's N x K symbols), nearest codes
        reference_key, reference = "first_stage", figures(model, datasets, hands, stages=1)
    else:
        reference_key, reference = "nearest_codes", figures(model, datasets, hands)
    model.with_encoding(own)
    results = figures(model, datasets, hands)
    if not own.rounds:
        per_round = ""
    elif own.method == "greedy":
        per_round = f" --encoding.changes={own.changes} --encoding.tolerance_deg={own.tolerance_deg:g}"
    else:
        per_round = f" --encoding.sweeps={own.sweeps}"
    state = json.loads((args.run / "best" / "training_state.json").read_text())
    data_cmd = "python experiments/universal_data.py --out=outputs/universal_data"
    train_cmd = f"nice -n {args.nice} unidextok-train --config_path=train/universal" + (
        f" {args.train_flags}" if args.train_flags else "")  # fmt: skip
    which = "" if args.repo_id == UNIVERSAL_SMALL else f" --repo_id={args.repo_id}"
    flags = f" --nice={args.nice} --train_flags='{args.train_flags}'" if args.train_flags else ""
    commands = {
        "data": data_cmd,
        "train": train_cmd,
        "figures": f"python experiments/universal_card.py{which} --run={args.run.as_posix()} "
        f"--cpu_s={args.cpu_s:.0f} --commit={commit[:12]} "
        + (f"--encoding.method={own.method} " if own.rounds else "")
        + f"--encoding.rounds={own.rounds}{per_round}{flags}",
        "G1 test episodes, same figure": f"unidextok-eval --checkpoint={args.repo_id} "
        "--datasets='[outputs/universal_data/g1_inspire]'",
    }
    about = {
        "commit": commit,
        "training_cpu_s": args.cpu_s,
        "steps": state.get("steps"),
        "best_step": state.get("step"),
        "commands": commands,
        "encoding": encoding(model.config),
        reference_key: reference,
        "in_range": "5000 states per hand, uniform inside its registered ranges, random side, seed 0 "
        "(experiments.universal.in_range_figures)",
    }
    if residual:
        cfg = model.config
        about["symbols_per_hand"] = {"all stages": cfg.symbols_per_hand(), "first stage": cfg.symbols_per_hand(1)}
        encoding_lines = [
            f"This model has {cfg.residual_stages} residual stage(s) (`residual_stages`, preset "
            f"`{state.get('preset')}`; docs/tokenizer.md \"Model\"): each hand-state is {cfg.num_tokens} tokens x "
            f"{cfg.num_groups} groups of the first stage, the paper's factorised codebook, plus as many of each "
            f"residual stage, {cfg.symbols_per_hand()} codes of a {cfg.codebook_size}-entry vocabulary per group "
            f"in all (`config.symbols_per_hand()`). Its config.json sets its encoding to the nearest codes of "
            "every stage (`encoding`: rounds 0): `encode`, the processor step and a `<type>_udt` policy that "
            "uses this tokenizer emit all of them, and the evaluation table above is measured that way, with no "
            "code search. `encode(..., stages=1)` gives the first stage alone, the paper's "
            f"{cfg.symbols_per_hand(1)} symbols, which `decode` reads as well; on the same rows they measure "
            "(`eval.json` `first_stage`):",
        ]
    else:
        encoding_lines = [
            f"This package's config.json sets its encoding (`encoding`: method {own.method}, rounds {own.rounds}, "
            f"{per_round.strip().replace('--encoding.', '').replace(' ', ', ')}): `encode`, and so the processor "
            "step and every `<type>_udt` policy that use this tokenizer, refines each group's nearest code with the "
            "decoder-aware code search (docs/tokenizer.md \"Code search\", its cost per frame and per row; same "
            "tokens, same decoder), and the evaluation table above is measured that way. `encode(..., "
            "encoding=NEAREST_CODES)` (`unidextok-eval --encoding.rounds=0`, `--policy.udt_encoding.rounds=0`) gives "
            "the nearest codes, the paper's encoding; on the same rows they measure (`eval.json` `nearest_codes`):",
        ]
    chosen = (
        "The schedule is `unidextok/universal-small`'s recipe unchanged; the residual stage was chosen against the "
        "plain model at equal training on in-range states of two hands (`python experiments/residual_ab.py`, "
        "docs/tokenizer.md \"Residual stages at equal training\"), never on the figures above."
        if residual else
        "The schedule, and then the code search settings, were chosen among full-length runs and settings on "
        "their selection episodes and on in-range states of another seed than the table's (`python "
        "experiments/universal_screen.py --runs=... [--methods='[sweeps,greedy]' --rounds='[0,1,2]' "
        "--sweeps='[...]' --changes='[...]']`, docs/tokenizer.md \"How the recipe was chosen\"), "
        "never on the figures above."
    )  # fmt: skip
    sections = [
        "## Encoding",
        "",
        " ".join(encoding_lines),
        "",
        "| | rows | mpjae_deg | mpjpe_mm | fingertip_mm |",
        "|---|---|---|---|---|",
        *[f"| {name} | {e['rows']} | {e['mpjae_deg']:.4g} | {e['mpjpe_mm']:.4g} | {e['fingertip_mm']:.4g} |"
          for name, e in reference.items()],
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
        chosen,
        "",
        "The evaluation table above is `eval.json` (`results`): test episodes / held-out recordings of each "
        "converted dataset, and every registered hand on in-range states (" + about["in_range"] + "). "
        "The G1 row equals `" + commands["G1 test episodes, same figure"] + "`.",
        "",
    ]
    target = write_package(args.run / "best", SHIPPED[args.repo_id], args.repo_id, results, about, sections,
                           RECORDINGS, config_overrides={"encoding": dataclasses.asdict(own)})  # fmt: skip
    print(json.dumps(results, indent=2))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
