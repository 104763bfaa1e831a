"""`unidextok-deploy`: bind a policy trained on a mix of robots (`unidextok-mix`) to one robot of the mix.

    unidextok-deploy --checkpoint=outputs/mix_act/checkpoints/last/pretrained_model --robot=data/g1_udhm \
        --output=outputs/mix_act_g1
    python experiments/eval_policy.py --checkpoint=outputs/mix_act_g1 --dataset=data/g1_udhm

The bound checkpoint takes that robot's native `observation.state` (and its converted one) and returns its native
action; LeRobot's stock factory and `lerobot-rollout` load it unchanged (`policies/deploy.py`).
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging
from dataclasses import dataclass

from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap


@dataclass
class DeployConfig:
    # the mixed policy: a lerobot-train checkpoint folder (.../checkpoints/<step>/pretrained_model)
    checkpoint: str = ""
    # the robot: its converted dataset (a folder, or a repo id in the local caches), one of the mix's inputs
    robot: str = ""
    output: str = ""  # the bound checkpoint folder (must not exist unless --overwrite)
    # a robot whose hands were never in the mix: bind it anyway (its hands get no identity the policy knows)
    zero_shot: bool = False
    # what a zero-shot hand drives: "own" (every slot it has) or "nearest" (only the slots of the trained hand
    # nearest it in morphology; its others held at 0 and commanded 0: docs/pooling.md "Zero-shot slots")
    zero_shot_slots: str = "own"
    # the robot's grasp centre (x, y, z m, in its wrist frame) for a policy that learned the wrist in each hand's
    # grasp-centre frame, within 0.3 m of the wrist; default: the robot's converted dataset's record, else the
    # checkpoint's for a known hand (a recorded centre the flag overrides is named in a note)
    grasp_centre_m: list[float] | None = None
    # replace the policy checkpoint at --output (never anything else), once the bound one is written whole
    overwrite: bool = False


@wrap()
def deploy_cli(cfg: DeployConfig) -> None:
    import lerobot_policy_unidextok  # noqa: F401  (registers the <type>_udt policies and steps; not for --help)
    from lerobot_unidextok.data.reader import dataset_folder
    from lerobot_unidextok.policies.deploy import DeployError, check_zero_shot_slots, deploy

    for flag in ("checkpoint", "robot", "output"):
        if not getattr(cfg, flag):
            raise DeployError(f"--{flag} is required (unidextok-deploy --help)")
    check_zero_shot_slots(cfg.zero_shot, cfg.zero_shot_slots)  # a flag's mistake before any path is looked up
    out = deploy(cfg.checkpoint, dataset_folder(cfg.robot), cfg.output, zero_shot=cfg.zero_shot,
                 overwrite=cfg.overwrite, grasp_centre_m=cfg.grasp_centre_m, zero_shot_slots=cfg.zero_shot_slots)
    print(f"wrote {out}: {cfg.checkpoint} bound to the robot of {cfg.robot}")


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", force=True)
    run_cli(deploy_cli)


if __name__ == "__main__":
    main()
