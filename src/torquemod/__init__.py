"""torquemod: the torque-modulation method for wheel-rail friction measurement.

The library in five calls (see the README's "Python API")::

    import torquemod as tm
    exp = tm.read_experiment("experiment.toml")
    res = tm.process(exp, phase_method="sinefit")
    ana = tm.analyze(res)
    tm.save(res, ana, "results/"); res, ana = tm.load("results/")

and the same for a train run::

    run = tm.read_run("run.toml")
    ob = tm.onboard(run)                  # OnboardResult: report(), plot_*(), to_frame()
    ob.save("onboard/"); ob = tm.load_onboard("onboard/")

The digital twin lives under ``tm.twin`` (imported on first use).
"""

from torquemod._version import __version__
from torquemod.errors import InputError, OutputError, ProcessingError, TorquemodError

# the public names and the modules they live in: imported on first use (PEP 562), so that
# `import torquemod` -- and every command, the twin's included -- does not pay for scipy,
# pandas and matplotlib before it needs them
_LAZY = {"FitOptions": "torquemod.analysis.analyzer", "Analysis": "torquemod.analysis.result",
         "analyze": "torquemod.api", "load": "torquemod.api", "process": "torquemod.api",
         "read_experiment": "torquemod.api", "run": "torquemod.api", "save": "torquemod.api",
         "read_run": "torquemod.api", "onboard": "torquemod.api",
         "load_onboard": "torquemod.api", "OnboardResult": "torquemod.ontrain.result",
         "Run": "torquemod.io.run", "ProcessingConfig": "torquemod.io.config",
         "Experiment": "torquemod.io.experiment", "Recording": "torquemod.io.experiment",
         "ProcessResult": "torquemod.processing.pipeline"}

__all__ = ["Analysis", "Experiment", "FitOptions", "InputError", "OnboardResult",
           "OutputError", "ProcessResult", "ProcessingConfig", "ProcessingError", "Recording",
           "Run", "TorquemodError", "__version__", "analyze", "load", "load_onboard",
           "onboard", "process", "read_experiment", "read_run", "run", "save", "twin"]


def __getattr__(name: str):
    """The public names of :data:`_LAZY` and ``tm.twin`` (the simulator, numba), imported
    when first asked for."""
    import importlib
    if name == "twin":
        return importlib.import_module("torquemod.twin")
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
