"""Single source of the package version (kept in step with pyproject.toml)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("torquemod")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
