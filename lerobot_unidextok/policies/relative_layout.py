"""What keeps relative actions from lining up, said exactly: `udt_relative_actions` learns `action - state` column
by column, so the action's columns must be the state's first columns, in order. Showing the first few names of
both lists hid the difference when it came later (a simulator's state puts its task columns between the wrist
and the hand), so the message names the first column that differs and what kind of difference it is."""

from __future__ import annotations

from lerobot_unidextok.constants import OBS_STATE

OFF = "--policy.udt_relative_actions=false"
BIND = (
    "unidextok-deploy --checkpoint=<policy> --robot=<this robot's converted dataset> (--zero_shot=true when its "
    "hand was not in the policy's training data)"
)


def _short(names: list[str], at_most: int = 6) -> str:
    shown = ", ".join(names[:at_most])
    return shown + (f" and {len(names) - at_most} more" if len(names) > at_most else "")


def _in_order(sub: list[str], full: list[str]) -> bool:
    it = iter(full)
    return all(name in it for name in sub)


def relative_layout_problem(action_names: list[str], state_names: list[str], width: int, state_width: int,
                            trained: bool = True) -> str | None:  # fmt: skip
    """Why `action - state` per column is wrong for this layout (one sentence with the fix), or None when the
    action is the state's first `width` columns. `width`: the action the policy is asked to predict (at
    evaluation, the env's); `trained`: False when the layout comes from a checkpoint loaded to run, so a
    difference means the policy runs on a robot it was not bound to."""
    head = f"udt_relative_actions learns action - state per column, so the action must be the first columns of {OBS_STATE}"
    names, state = list(action_names), list(state_names)
    if not trained and names and width != len(names):
        return (
            f"{head}; this policy predicts {len(names)} action columns ({_short(names, 3)}), but the robot or "
            f"simulator it runs on takes a {width}-wide action: it was trained on another robot or hand, or is a "
            f"mix that was never bound. Bind it to this one first: {BIND}"
        )
    if not (names and state):
        if width <= state_width:
            return None
        return f"{head}, but the action is {width} wide and the state {state_width}: set {OFF}"
    if width <= state_width and names == state[:width]:
        return None
    where = next((i for i, (a, s) in enumerate(zip(names, state, strict=False)) if a != s), min(len(names), len(state)))
    at = (f"action column {where} is {names[where]!r} where the state has {state[where]!r}" if where < len(state)
          else f"the action has {len(names)} columns, the state only {len(state)}")  # fmt: skip
    stray = [n for n in names if n not in state]
    if not stray and _in_order(names, state):
        between = [s for s in state[: state.index(names[-1]) + 1] if s not in names]
        fix = (f"the state has {len(between)} column(s) the action lacks among them ({_short(between)}); reordering "
               f"the action cannot fix that: set {OFF}")  # fmt: skip
    elif not stray:
        fix = f"the action holds the same columns in another order: reorder the dataset's action to the state's column order or set {OFF}"
    else:
        fix = f"the action has {len(stray)} column(s) the state lacks ({_short(stray)})"
        fix += f": set {OFF}" if trained else f"; if this robot is not the one the policy was trained on, bind it first: {BIND}"
    return f"{head}, but {at}: {fix}"


__all__ = ["relative_layout_problem"]
