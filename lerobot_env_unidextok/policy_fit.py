"""Whether the checkpoint `lerobot-eval --policy.path` names fits the simulator it is asked to run on, read from
its config.json before anything runs (no weights, no MuJoCo): `--env.type=unidextok`'s config calls it.

A `<type>_udt` checkpoint records what it takes: its converted state's column names (`udt_state_names`, which
hold the simulator task's columns, and the fingertips' when it was recorded with them), whether it is a mix of hands never bound to one (`udt_hand_vocabulary`
without `udt_fixed_hand_ids`), and the hand whose native state it reads (`udt_native_state_layout.hands`).
Each misfit is one line naming what differs and the fix; before, a policy of another task was told at its
first step that it "was trained on another robot or hand", and an unbound mix ended in a KeyError traceback.
Anything this cannot read (a Hub id, a stock policy) is left to run and to LeRobot's own checks.
"""

from __future__ import annotations

import json
from pathlib import Path

from lerobot_env_unidextok.columns import FINGERTIP_COLUMNS, TASK_COLUMNS
from lerobot_env_unidextok.errors import SimInputError

CLOSED_LOOP_DOCS = "docs/lerobot.md, 'Closed-loop evaluation'"


def check_policy_fits(policy_path: str | None, task: str, hand: str, fingertips: bool = False) -> None:
    """Refuse (SimInputError) a local `<type>_udt` checkpoint at `policy_path` that was trained on another
    task, with the fingertips' columns when the env has none (or without them when it has), is a mix never bound to
    a hand, or reads another hand's native state than `hand`."""
    config = _config(policy_path)
    if config is None:
        return
    names = config.get("udt_state_names") or []
    trained = [t for t, columns in TASK_COLUMNS.items() if set(columns) <= set(names)]
    if trained and task not in trained:
        raise SimInputError(
            f"the policy {policy_path} was trained on the simulator's {trained[0]} task (its state holds that task's "
            f"columns {', '.join(TASK_COLUMNS[trained[0]])}), but --env.task={task}: pass --env.task={trained[0]}, "
            f"or a policy trained on {task} (unidextok-sim-record --task={task}, then unidextok-convert and "
            f"lerobot-train; {CLOSED_LOOP_DOCS})"
        )
    trained_tips = set(FINGERTIP_COLUMNS) <= set(names)
    if trained and trained_tips != fingertips:
        raise SimInputError(
            f"the policy {policy_path} was trained {'with' if trained_tips else 'without'} the fingertips' columns "
            f"(tip_<finger>_x/y/z, unidextok-sim-record --fingertips={str(trained_tips).lower()}), but "
            f"--env.fingertips={str(fingertips).lower()}: pass --env.fingertips={str(trained_tips).lower()}"
        )
    bind = (
        f"unidextok-deploy --checkpoint={policy_path} --robot=<a converted dataset of {hand}: unidextok-sim-record "
        f"--hand={hand}, then unidextok-convert> --output=<folder>"
    )
    vocabulary = config.get("udt_hand_vocabulary") or []
    if vocabulary and not config.get("udt_fixed_hand_ids"):
        zero_shot = "" if hand in vocabulary else " --zero_shot=true (it never had this hand)"
        raise SimInputError(
            f"the policy {policy_path} is a mix of hands ({', '.join(vocabulary)}) never bound to one, and the "
            f"simulator runs one hand, --env.hand={hand}: bind it to that hand first, {bind}{zero_shot}, then "
            f"--policy.path=<folder> ({CLOSED_LOOP_DOCS})"
        )
    layout = config.get("udt_native_state_layout")
    hands = [h.get("hand") for h in layout.get("hands", []) if isinstance(h, dict)] if isinstance(layout, dict) else []
    if hands and hand not in hands:
        raise SimInputError(
            f"the policy {policy_path} reads the native state of {', '.join(map(str, hands))}: it was trained on "
            f"another robot or hand than --env.hand={hand} (or bound to one). Pass --env.hand={hands[0]}, or bind it "
            f"to this one: {bind} (--zero_shot=true when {hand} was not in its training data)"
        )


def _config(policy_path: str | None) -> dict | None:
    config = Path(policy_path) / "config.json" if policy_path else None
    if config is None or not config.is_file():
        return None
    try:
        data = json.loads(config.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return None  # not a config LeRobot can load either: it says so itself
    return data if isinstance(data, dict) else None


__all__ = ["check_policy_fits"]
