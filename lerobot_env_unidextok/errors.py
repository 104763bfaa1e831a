"""The simulator's user errors (kinds of the project's `UserError`, so the CLIs print one `error:` line)."""

from lerobot_unidextok.errors import InvalidInputError


class SimInputError(InvalidInputError):
    """A hand, task, action or option the simulator cannot take; the message names it and the fix."""


class SimHandError(SimInputError):
    """A hand the simulator cannot run (unknown, or no model for it); the message lists the ones it can."""


class SimBuildError(SimInputError):
    """A URDF the builder cannot turn into a model (unreadable, cut short, a joint without finite limits); the
    message names the file and, where one is to blame, the joint."""


__all__ = ["SimBuildError", "SimHandError", "SimInputError"]
