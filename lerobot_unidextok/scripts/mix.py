"""`unidextok-mix`: mix converted datasets of different robots and people into one LeRobot v3 dataset.

    unidextok-mix --inputs='[data/g1_udhm, data/l10_udhm]' --root=data/g1_l10_mix --repo_id=lab/g1_l10_mix
    unidextok-mix --inputs='[data/g1_udhm, data/human_udhm]' --weights='[3, 1]' --action_ahead=1 --root=...
    unidextok-mix --inputs='[...]' --keep=all --name_map='{"kLeftShoulderPitch": "left_shoulder_pitch"}' --root=...

Then `lerobot-train --config_path=$(unidextok-config lerobot/act_udt_cpu) --dataset.root=<root> ...` with the
printed `--dataset.episodes` flag, and `unidextok-deploy` to bind the checkpoint to each robot (docs/lerobot.md,
"One policy, several robots").
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging

from lerobot_unidextok.conversion.mix import MixOptions
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap


@wrap()
def mix_cli(cfg: MixOptions) -> None:
    from lerobot_unidextok.conversion.card import lerobot_train_episodes_flag  # with the mix, not for --help
    from lerobot_unidextok.conversion.mix import format_report, mix

    report = mix(cfg)
    print(format_report(report))
    flag = lerobot_train_episodes_flag(report.num_episodes, report.test_episodes)
    print(f"lerobot-train without the {len(report.test_episodes)} test episodes: {flag}")


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", force=True)
    run_cli(mix_cli)


if __name__ == "__main__":
    main()
