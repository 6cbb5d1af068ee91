"""The on-board estimator (issue 10): the friction along a train run from torque and axle
speed, with honest uncertainty."""

from .estimator import TRACK_COLUMNS, MuTracker, OnboardConfig, OnboardEstimator
from .run import OnboardResult, estimate_axle, run_onboard
from .window import WindowResult, damping_from_ratio, load_impedance, measure_window

__all__ = ["TRACK_COLUMNS", "MuTracker", "OnboardConfig", "OnboardEstimator", "OnboardResult",
           "WindowResult", "damping_from_ratio", "estimate_axle", "load_impedance",
           "measure_window",
           "run_onboard"]
