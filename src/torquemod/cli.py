# PYTHON_ARGCOMPLETE_OK
"""The ``torquemod`` command line. The only module that parses arguments or prints.

Every :class:`~torquemod.errors.TorquemodError` ends as one line on stderr and exit code 2;
anything else is a bug: one line, exit code 3, and ``--debug`` shows the traceback. Ctrl-C
ends with 130, SIGTERM with 143. Shell completion comes from argcomplete
(``eval "$(register-python-argcomplete torquemod)"``), loaded only while completing.
"""

from __future__ import annotations

import contextlib
import os
import sys

from torquemod._cli.exits import (
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
)
from torquemod._cli.output import one_line, os_error_line
from torquemod._cli.parser import build_parser
from torquemod._cli.signals import TERMINATED, Terminated, terminate_as_interrupt
from torquemod.errors import TorquemodError

__all__ = ["build_parser", "main"]


def _quick_exit() -> None:
    """Have the interpreter's exit skip its collections over everything imported: run at
    exit (after the other exit handlers, before the modules are torn down), it moves every
    object to the collector's permanent generation, which the final collections leave
    alone. Objects are still freed as their references go; what a cycle still holds is
    left to the operating system. Measured on ``torquemod sweep`` (pandas, scipy, Dask,
    matplotlib imported): 0.28 -> 0.05 s from the last exit handler to the process's end."""
    import gc
    gc.freeze()


_EXIT_HOOKED = False


def main(argv: list[str] | None = None) -> int:
    """The ``torquemod`` command.

    Parameters
    ----------
    argv : list of str or None
        The arguments; None: ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status: 0, 2 for bad input (one line, no traceback), or the codes for a
        broken pipe, an interrupt, a termination or an internal error.
    """
    global _EXIT_HOOKED
    if not _EXIT_HOOKED:  # once per process (a caller may run several commands)
        import atexit
        atexit.register(_quick_exit)
        _EXIT_HOOKED = True
    parser = build_parser()
    if "_ARGCOMPLETE" in os.environ:  # the shell asks for completions; exits when done
        import argcomplete
        argcomplete.autocomplete(parser)
    args = parser.parse_args(argv)
    try:
        with terminate_as_interrupt():
            return int(args.func(args) or 0)
    except TorquemodError as exc:
        print(f"torquemod: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to say
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt as exc:  # Ctrl-C: 128 + SIGINT; kill: 128 + SIGTERM
        if isinstance(exc, Terminated) or TERMINATED.is_set():
            print("torquemod: terminated", file=sys.stderr)
            return EXIT_TERMINATED
        print("torquemod: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:
        from torquemod._util.fsutil import environment_error
        env = environment_error(exc)  # full disk, read-only, no permission, ... (also deep
        if env is not None:           # inside numpy/pandas/h5py writes): the system's fault
            print(f"torquemod: error: {os_error_line(env, args)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        if args.debug:  # a bug: say so in one line unless asked for the traceback
            raise
        print(f"torquemod: internal error: {type(exc).__name__}: {one_line(exc)} (rerun "
              "with --debug and report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
