"""The project's exception and warning hierarchy.

Every error a user can cause by what they feed in is a :class:`TorquemodError`. The CLI turns
these into one line on stderr and exit code 2. Messages name the file, the channel or key, what
is wrong and what to do next.
"""

from __future__ import annotations


class TorquemodError(Exception):
    """Base class of every error torquemod raises on purpose."""


class InputError(TorquemodError, ValueError):
    """Bad input: a file, a manifest key or a channel that cannot be used as it is."""

    def __init__(self, message: str, *, path: object | None = None, channel: str | None = None,
                 hint: str | None = None) -> None:
        parts = []
        if path is not None:
            parts.append(f"{path}")
        if channel is not None:
            parts.append(f"channel '{channel}'")
        where = ": ".join(parts)
        text = f"{where}: {message}" if where else message
        if hint:
            text = f"{text}; {hint}"
        super().__init__(text)
        self.path = path
        self.channel = channel
        self.hint = hint


class OptionError(InputError, TypeError):
    """A keyword option of a library call (or a field of an options object) has the wrong
    type or value; both ``except TypeError`` and ``except ValueError`` catch it."""


class ManifestError(InputError):
    """The experiment manifest (TOML) is missing, malformed or inconsistent."""


class ProcessingError(TorquemodError, RuntimeError):
    """A processing step cannot produce a trustworthy number from otherwise valid input."""


class OutputError(TorquemodError, OSError):
    """The results folder cannot be written as asked."""
