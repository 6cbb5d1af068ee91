"""Single source of the package version.

pyproject.toml reads ``__version__`` from here (setuptools ``dynamic`` version, ``attr``, read
from this file's text without importing the package), so the installed metadata and
``torquemod.__version__`` cannot disagree. A plain string: asking ``importlib.metadata`` at
import cost ~35 ms of every process's start-up.
"""

__version__ = "0.1.0"
