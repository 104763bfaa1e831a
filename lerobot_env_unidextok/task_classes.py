"""Every task's class by its gym id's task part (`columns.TASKS` names the same tasks without MuJoCo): what the env
builds (`env.py`). The two first tasks live in `tasks.py` with the `Task` base; each later one in a module of its
own."""

from __future__ import annotations

from lerobot_env_unidextok.chord_press import ChordPress
from lerobot_env_unidextok.finger_sequence import FingerSequence
from lerobot_env_unidextok.pinch_lift import PinchLift
from lerobot_env_unidextok.pinch_place import PinchPlace
from lerobot_env_unidextok.tasks import FingerPress, GraspLift, Task

TASKS: dict[str, type[Task]] = {t.name: t for t in (GraspLift, FingerPress, FingerSequence, PinchPlace, ChordPress,
                                                    PinchLift)}

__all__ = ["TASKS", "Task"]
