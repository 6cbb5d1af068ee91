"""The net delay between a run's torque and speed signals, measured from the run itself.

A drive's torque estimated from motor current is filtered, a speed from counting encoder
pulses is half a gate late, loggers put channels on different messages. A net delay tau of
the torque behind the speed rotates the measured torque-to-speed ratio by ``exp(-j*Omega*tau)``
and biases the creep coefficient (on a 4 Hz modulation by ~4 % per ms); the manifest can
declare it (:meth:`torquemod.io.run.Vehicle.sensor_response`), but a hidden run may not.

What fixes it (derived for this model): the impedance G the wheelset meets beyond its own
inertia (:func:`~torquemod.ontrain.window.load_impedance`) is the contact damping D in series
with the vehicle, ``1/G = 1/D + 1/Z_v``. D is real and changes with every operating point
(it is what the method measures); the vehicle's impedance Z_v (its mass, the running
resistance's slope) does not. So over windows at different D::

    Im(1/G_i) = Im(1/Z_v)          the same for every window, at the right delay,

while a wrong delay ``dtau`` rotates 1/G_i by ``Omega*dtau`` and adds ``Omega*dtau*Re(1/G_i)``
to it: a line in ``Re(1/G_i)`` whose slope is the delay error. :class:`DelayCalibrator` keeps,
for every delay of a grid, the weighted least-squares sums of ``Im(1/G)`` on ``Re(1/G)``
(constant memory; windows in order, so a live system and the batch agree) and reports the
delay where the slope crosses zero, with its standard error from the slope's. It is trusted
only when the windows spread D enough (the standard error below ``max_se_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from torquemod.io.run import Vehicle
from torquemod.ontrain.window import load_impedance


@dataclass(frozen=True)
class DelayEstimate:
    """The net delay of the torque signal behind the speed's, measured from a run.

    Attributes
    ----------
    delay_s : float
        Net delay of the torque behind the speed beyond what the manifest declares [s]; 0
        while not ``trusted``.
    se_s : float
        Its standard error [s]; NaN when the slope did not cross zero once.
    windows : int
        Steady windows the estimate used [-].
    trusted : bool
        The standard error is at most the calibrator's ``max_se_s``.
    """

    delay_s: float
    se_s: float
    windows: int
    trusted: bool


class DelayCalibrator:
    """Running estimate of the net torque-to-speed delay from a run's steady windows.

    For every candidate delay the weighted least-squares sums of ``Im(1/G)`` on ``Re(1/G)``
    are kept (constant memory); the estimate is the delay where that slope crosses zero
    (module docstring).

    Parameters
    ----------
    vehicle : torquemod.io.run.Vehicle
        The vehicle (for G, :func:`~torquemod.ontrain.window.load_impedance`).
    frequency_hz : float
        Modulation frequency [Hz].
    grid_s : ndarray
        Candidate delays, ascending [s] (:func:`delay_grid`).
    min_windows : int
        Fewest windows before an estimate [-]. Default 40 (``OnboardConfig.delay_min_windows``).
    max_se_s : float
        The estimate is trusted below this standard error [s]. Default 5e-4
        (``OnboardConfig.delay_max_se_s``).

    Notes
    -----
    A net delay tau rotates the ratio T/w by ``exp(-j*Omega*tau)``. The contact damping D
    (real, different at each operating point) is in series with the vehicle's impedance Z_v
    (the same for all), ``1/G = 1/D + 1/Z_v``, so at the right delay ``Im(1/G_i) = Im(1/Z_v)``
    for every window; a delay error ``dtau`` adds ``Omega*dtau*Re(1/G_i)``, a line whose slope
    is the error. Derived for this model; the slope's standard error is scaled by the
    residual's chi^2 per degree of freedom (at least 1).
    """

    def __init__(self, vehicle: Vehicle, frequency_hz: float, grid_s: np.ndarray, *,
                 min_windows: int = 40, max_se_s: float = 5e-4):
        self.v, self.f = vehicle, float(frequency_hz)
        self.grid = np.asarray(grid_s, dtype=float)
        self.rot = np.exp(2j * math.pi * self.f * self.grid)  # undoes a delay of grid_s
        self.min_windows, self.max_se_s = int(min_windows), float(max_se_s)
        # per candidate: sum w, w*x, w*y, w*x^2, w*x*y, w*y^2
        self.sums = np.zeros((6, self.grid.size))
        self.n = 0

    def add(self, ratio: complex, phase_se_rad: float) -> None:
        """A steady window's measured ratio T/w (declared dynamics already divided out) and
        its phase standard error [rad] (also the relative error of |T/w|)."""
        if not (math.isfinite(phase_se_rad) and phase_se_rad > 0 and np.isfinite(ratio)):
            return
        r = ratio * self.rot
        g = load_impedance(r, self.v, self.f)  # works on arrays too
        if not np.all(np.isfinite(g)) or np.any(g == 0):
            return
        inv = 1.0 / g
        # the error of 1/G from the ratio's: |r| * se / |G|^2 (first order)
        sd = np.abs(r) * phase_se_rad / np.abs(g) ** 2
        w = 1.0 / sd ** 2
        x, y = inv.real, inv.imag
        self.sums += np.array([w, w * x, w * y, w * x * x, w * x * y, w * y * y])
        self.n += 1

    def slopes(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted least-squares slope of Im(1/G) on Re(1/G) at every candidate delay and
        its standard error (scaled by the residual's chi^2 per degree of freedom)."""
        s, sx, sy, sxx, sxy, syy = self.sums
        with np.errstate(invalid="ignore", divide="ignore"):
            sxx_c = sxx - sx * sx / s
            b = (sxy - sx * sy / s) / sxx_c
            rss = np.maximum(syy - sy * sy / s - b * (sxy - sx * sy / s), 0.0)
            chi = rss / max(self.n - 2, 1)
            se = np.sqrt(np.maximum(chi, 1.0) / sxx_c)
        return b, se

    def estimate(self) -> DelayEstimate:
        """The delay where the slope crosses zero (falling; linear between grid points)."""
        if self.n < self.min_windows:
            return DelayEstimate(0.0, math.nan, self.n, False)
        b, se = self.slopes()
        ok = np.isfinite(b)
        cross = np.flatnonzero(ok[:-1] & ok[1:] & (b[:-1] > 0) & (b[1:] <= 0))
        if cross.size != 1:
            return DelayEstimate(0.0, math.nan, self.n, False)
        i = int(cross[0])
        frac = b[i] / (b[i] - b[i + 1])
        tau = float(self.grid[i] + frac * (self.grid[i + 1] - self.grid[i]))
        dbdtau = float((b[i + 1] - b[i]) / (self.grid[i + 1] - self.grid[i]))
        tau_se = float((1 - frac) * se[i] + frac * se[i + 1]) / abs(dbdtau)
        trusted = tau_se <= self.max_se_s
        return DelayEstimate(tau if trusted else 0.0, tau_se, self.n, trusted)


def delay_grid(delay_max_s: float, frequency_hz: float, step_s: float = 2.5e-4) -> np.ndarray:
    """The candidate delays of :class:`DelayCalibrator`.

    ``-tau_max .. tau_max`` in steps of ``step_s``, with ``tau_max = min(delay_max_s,
    1/(6*f))``. Both signs: a filtered torque lags the speed, a speed counted over a gate lags
    the torque. At most a sixth of the period (60 degrees at the modulation frequency), so
    that the slope of Im(1/G) on Re(1/G) crosses zero once on the grid.

    Parameters
    ----------
    delay_max_s : float
        Largest delay searched [s] (``OnboardConfig.delay_max_s``).
    frequency_hz : float
        Modulation frequency f [Hz].
    step_s : float
        Grid step [s]. Default 2.5e-4.

    Returns
    -------
    ndarray
        The delays [s], ascending, symmetric about 0.

    Examples
    --------
    >>> delay_grid(0.001, 4.0).tolist()
    [-0.001, -0.00075, -0.0005, -0.00025, 0.0, 0.00025, 0.0005, 0.00075, 0.001]
    """
    tau = min(float(delay_max_s), 1.0 / (6.0 * float(frequency_hz)))
    n = max(1, math.floor(tau / step_s + 1e-9))
    return step_s * np.arange(-n, n + 1, dtype=float)

