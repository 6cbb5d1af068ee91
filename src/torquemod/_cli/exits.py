"""The exit codes of ``torquemod`` and the error of a wrong command line."""

from torquemod.errors import TorquemodError

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, as a shell reports `torquemod ... | head`


class UsageError(TorquemodError):
    """A command line that cannot be carried out (exit code 2, like bad input)."""
