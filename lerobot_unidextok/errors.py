"""The user-error hierarchy: mistakes a person fixes from the message, never bugs.

Every error the package raises for bad input (a wrong path, a malformed source file, an option that does not
fit, a checkpoint that is not there) is a `UserError`, and also the builtin type that says what went wrong, so
callers may catch either:

- `InvalidInputError` (a `ValueError`): a value, option, file content or dataset that does not fit;
- `MissingInputError` (a `FileNotFoundError`): a path, dataset or checkpoint that is not there;
- `ExistingOutputError` (a `FileExistsError`): an output that would overwrite something it must not;
- `UnavailableError` (a `RuntimeError`): something needed is out of reach (the Hub offline, a licensed model).

Modules name their own kinds below these (`SourceFormatError`, `SetupError`, `RecordError`, ...). The
command-line tools turn a `UserError` into one `error: <message>` line and exit status 2
(`utils/cli.py: run_cli`); anything else is a bug and keeps its traceback.
"""


class UserError(Exception):
    """A mistake the user can fix from the message (the message names the problem and the fix)."""


class InvalidInputError(UserError, ValueError):
    """A value, option, file content or dataset that does not fit."""


class MissingInputError(UserError, FileNotFoundError):
    """A path, dataset or checkpoint that is not there."""


class ExistingOutputError(UserError, FileExistsError):
    """An output that would overwrite something it must not."""


class UnavailableError(UserError, RuntimeError):
    """Something needed is out of reach: the Hub while offline, a licensed model, a server."""


class ConfigError(InvalidInputError):
    """A command-line flag or config-file value the config refuses (its `__post_init__` says which and why)."""


class SourceFormatError(InvalidInputError):
    """A source dataset's file is missing a field, unreadable or not the format its reader follows."""


class CheckpointNotFoundError(MissingInputError):
    """A tokenizer checkpoint cannot be found: not a folder here, not a shipped id, not in the HF cache or Hub."""


__all__ = [
    "CheckpointNotFoundError",
    "ConfigError",
    "ExistingOutputError",
    "InvalidInputError",
    "MissingInputError",
    "SourceFormatError",
    "UnavailableError",
    "UserError",
]
