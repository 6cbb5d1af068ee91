"""The on-board estimator (issue 10): the friction along a train run from torque and axle
speed, with honest uncertainty.

The package is also the API call ``tm.onboard(run, **options)``: importing a subpackage
makes it the parent's attribute of that name, so ``torquemod.onboard`` is this package once
anything imported it; calling it runs :func:`torquemod.api.onboard`.
"""

import sys
import types

from .estimator import TRACK_COLUMNS, MuTracker, OnboardConfig, OnboardEstimator
from .result import OnboardResult
from .run import estimate_axle, run_onboard
from .window import WindowResult, damping_from_ratio, load_impedance, measure_window

__all__ = ["TRACK_COLUMNS", "MuTracker", "OnboardConfig", "OnboardEstimator", "OnboardResult",
           "WindowResult", "damping_from_ratio", "estimate_axle", "load_impedance",
           "measure_window",
           "run_onboard"]


class _CallablePackage(types.ModuleType):
    """This package, callable as :func:`torquemod.api.onboard`."""

    def __call__(self, run, *, axle=None, config=None, **options):
        from ..api import onboard
        return onboard(run, axle=axle, config=config, **options)


sys.modules[__name__].__class__ = _CallablePackage
