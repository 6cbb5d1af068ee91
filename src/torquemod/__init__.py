"""torquemod: the torque-modulation method for wheel-rail friction measurement."""

from ._version import __version__

__all__ = ["__version__"]
