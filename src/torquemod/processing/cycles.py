"""Splitting a recording into cycles: one cycle is one revolution of the platform."""

from __future__ import annotations

import itertools

import numpy as np
from scipy import integrate


def revolution_bounds(platform_speed_rad_s: np.ndarray, fs_hz: float) -> list[tuple[int, int]]:
    """Index ranges of whole platform revolutions.

    The platform angle is the cumulative trapezoidal integral of the angular velocity;
    revolution k ends at the sample boundary nearest to where the angle reaches ``2*pi*k``.
    A trailing part shorter than a revolution is not returned.

    Parameters
    ----------
    platform_speed_rad_s : ndarray
        Platform angular speed [rad/s].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    list of tuple of int
        [start, stop) sample ranges.

    Examples
    --------
    >>> import numpy as np
    >>> revolution_bounds(np.full(25, 2 * np.pi), 10.0)
    [(0, 10), (10, 20)]
    """
    omega = np.asarray(platform_speed_rad_s, dtype=np.float64)
    # angle at the sample instants, plus the end of the last sample's interval: a record of
    # exactly one revolution of samples ends at 2*pi one sample period after its last stamp
    angle = integrate.cumulative_trapezoid(omega, dx=1.0 / fs_hz, initial=0.0)
    angle = np.append(angle, angle[-1] + omega[-1] / fs_hz)
    # a revolution short by less than one sample's angle (noise integrated over the record)
    # is complete to the resolution of the data
    one_sample = abs(omega[-1]) / fs_hz
    n_rev = int(np.floor((angle[-1] + one_sample) / (2 * np.pi)))
    if n_rev < 1:
        return []
    targets = 2 * np.pi * np.arange(1, n_rev + 1)
    idx = np.minimum(np.searchsorted(angle, targets), angle.size - 1)
    before = np.maximum(idx - 1, 0)
    nearer = np.where(np.abs(angle[before] - targets) < np.abs(angle[idx] - targets), before, idx)
    edges = np.concatenate([[0], nearer])
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]
