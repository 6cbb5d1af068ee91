"""The command line's parts, imported by :mod:`torquemod.cli` only: the parser, the
commands, what they print, and SIGTERM handling."""
