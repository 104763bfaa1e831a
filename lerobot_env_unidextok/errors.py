"""The simulator's user errors (kinds of the project's `UserError`, so the CLIs print one `error:` line)."""

from lerobot_unidextok.errors import InvalidInputError


class SimInputError(InvalidInputError):
    """A hand, task, action or option the simulator cannot take; the message names it and the fix."""


__all__ = ["SimInputError"]
