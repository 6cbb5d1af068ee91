"""torquemod: the torque-modulation method for wheel-rail friction measurement.

The library in five calls (see the README's "Python API")::

    import torquemod as tm
    exp = tm.read_experiment("experiment.toml")
    res = tm.process(exp, phase_method="sinefit")
    ana = tm.analyze(res)
    tm.save(res, ana, "results/"); res, ana = tm.load("results/")

The digital twin lives under ``tm.twin`` (imported on first use).
"""

from ._version import __version__
from .analysis import FitOptions
from .analysisresult import Analysis
from .api import analyze, load, process, read_experiment, run, save
from .config import ProcessingConfig
from .data import Experiment, Recording
from .errors import InputError, OutputError, ProcessingError, TorquemodError
from .pipeline import ProcessResult

__all__ = ["Analysis", "Experiment", "FitOptions", "InputError", "OutputError",
           "ProcessResult", "ProcessingConfig", "ProcessingError", "Recording",
           "TorquemodError", "__version__", "analyze", "load", "process", "read_experiment",
           "run", "save", "twin"]


def __getattr__(name: str):
    """``tm.twin``: the simulator (numba) is imported only when asked for."""
    if name == "twin":
        import importlib
        return importlib.import_module(".twin", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
