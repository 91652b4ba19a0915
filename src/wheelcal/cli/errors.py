"""Errors the CLI turns into exit statuses (CONTRACT: 0 ok, 1 sessions failed, 2 bad usage)."""


class UsageError(ValueError):
    """Bad command-line usage: exit status 2."""


class CommandFailed(RuntimeError):
    """The command failed — some recordings failed, already reported one by one: exit status 1."""
