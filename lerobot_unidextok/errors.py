"""The user-error base: mistakes a person fixes from the message, never bugs.

Every error the package raises for bad input (a wrong path, a malformed source file, an option that does not
fit, a checkpoint that is not there) is a subclass of `UserError` and also of the builtin type that says what
went wrong (`ValueError`, `FileNotFoundError`), so callers may catch either. The command-line tools turn a
`UserError` into one `error: <message>` line and exit status 2 (`utils/cli.py: run_cli`); anything else is a bug
and keeps its traceback.
"""


class UserError(Exception):
    """A mistake the user can fix from the message (the message names the problem and the fix)."""


class CheckpointNotFoundError(UserError, FileNotFoundError):
    """A tokenizer checkpoint cannot be found: not a folder here, not a shipped id, not in the HF cache or Hub."""


__all__ = ["CheckpointNotFoundError", "UserError"]
