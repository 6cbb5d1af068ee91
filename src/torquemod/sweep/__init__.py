"""``torquemod sweep``: sensitivity studies over the twin's parameters.

:func:`load_sweep` reads ``SWEEP.toml`` (docs/sweep.md) into a :class:`SweepSpec`;
:func:`run_sweep` evaluates its points (in Dask worker processes, or in this process),
resumably, and writes the table ``sweep.parquet``, ``failures.csv``, ``sweep.json``, the
figures and ``report.html``.
"""

from torquemod.sweep.run import SweepResult, run_sweep
from torquemod.sweep.spec import SweepPoint, SweepSpec, load_sweep, parse_sweep

__all__ = ["SweepPoint", "SweepResult", "SweepSpec", "load_sweep", "parse_sweep", "run_sweep"]
