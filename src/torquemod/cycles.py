"""Splitting a recording into cycles: one cycle is one revolution of the platform."""

from __future__ import annotations

import itertools

import numpy as np
from scipy import integrate


def revolution_bounds(platform_speed_rad_s: np.ndarray, fs_hz: float) -> list[tuple[int, int]]:
    """Index ranges [start, stop) of whole platform revolutions.

    The platform angle is the cumulative trapezoidal integral of the angular velocity
    [rad/s]; revolution k ends at the first sample whose angle reaches ``2*pi*k`` (the nearer
    of the two samples around the crossing). A trailing part shorter than a revolution is
    not returned.
    """
    omega = np.asarray(platform_speed_rad_s, dtype=np.float64)
    angle = integrate.cumulative_trapezoid(omega, dx=1.0 / fs_hz, initial=0.0)
    if angle[-1] < 2 * np.pi:
        return []
    n_rev = int(np.floor(angle[-1] / (2 * np.pi)))
    targets = 2 * np.pi * np.arange(1, n_rev + 1)
    idx = np.searchsorted(angle, targets)
    idx = np.minimum(idx, angle.size - 1)
    before = np.maximum(idx - 1, 0)
    nearer = np.where(np.abs(angle[before] - targets) < np.abs(angle[idx] - targets), before, idx)
    edges = np.concatenate([[0], nearer])
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]
