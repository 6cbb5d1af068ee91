"""The on-board (on-train) measurement: the friction along a train run from an axle's torque
and speed, with its uncertainty.

Users call :func:`torquemod.ontrain` (the function, :func:`torquemod.api.onboard`); this
package holds its stages: windows (:mod:`.window`), the estimator (:mod:`.estimator`), the
run over chunks of a recording (:mod:`.run`, :mod:`.chunks`), the result and its folder.
"""

from torquemod.ontrain.estimator import TRACK_COLUMNS, MuTracker, OnboardEstimator
from torquemod.ontrain.onboardconfig import OnboardConfig
from torquemod.ontrain.result import OnboardResult
from torquemod.ontrain.run import estimate_axle, run_onboard
from torquemod.ontrain.window import (
           WindowResult,
           damping_from_ratio,
           load_impedance,
           measure_window,
)

__all__ = ["TRACK_COLUMNS", "MuTracker", "OnboardConfig", "OnboardEstimator", "OnboardResult",
           "WindowResult", "damping_from_ratio", "estimate_axle", "load_impedance",
           "measure_window",
           "run_onboard"]
