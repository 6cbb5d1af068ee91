"""The phase fits of the twin's ground truth: the phase of the wheel speed behind the shaft torque
over whole modulation periods, by a plain sine fit or with the speed loop's wobble fitted out.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.twins.vtrack.rig.dynamics import wobble_basis


@numba.njit(cache=True, nogil=True)
def _sine_fit_sums(x, y, n, dw, gram, rhs):
    """Normal equations of the fit of ``cos(k*dw)``, ``sin(k*dw)``, 1 to ``x[:n]`` and
    ``y[:n]``: ``gram`` (3, 3) and ``rhs`` (3, 2). The basis is rotated sample by sample
    (exact sin/cos every 1024 samples); each signal is taken relative to its first sample
    (absorbed by the DC term) to keep the sums well conditioned."""
    cr, sr = math.cos(dw), math.sin(dw)
    gram[:] = 0.0
    rhs[:] = 0.0
    c, s = 1.0, 0.0
    x0, y0 = x[0], y[0]
    for k in range(n):
        if k % 1024 == 0:
            c, s = math.cos(k * dw), math.sin(k * dw)
        gram[0, 0] += c * c
        gram[0, 1] += c * s
        gram[0, 2] += c
        gram[1, 1] += s * s
        gram[1, 2] += s
        u, v = x[k] - x0, y[k] - y0
        rhs[0, 0] += u * c
        rhs[1, 0] += u * s
        rhs[2, 0] += u
        rhs[0, 1] += v * c
        rhs[1, 1] += v * s
        rhs[2, 1] += v
        c, s = c * cr - s * sr, s * cr + c * sr
    gram[1, 0] = gram[0, 1]
    gram[2, 0] = gram[0, 2]
    gram[2, 1] = gram[1, 2]
    gram[2, 2] = n


def sine_fit_phase_deg(torque: np.ndarray, speed: np.ndarray, fs_hz: float,
                       frequency_hz: float) -> float:
    """Phase of a speed behind a torque by three-parameter sine fits.

    A least-squares fit of cos, sin and DC at ``frequency_hz`` to each signal over the
    largest whole number of periods [1]_, solved by its 3x3 normal equations.

    Parameters
    ----------
    torque : ndarray
        Torque [N*m].
    speed : ndarray
        Speed [rad/s].
    fs_hz : float
        Sample rate [Hz].
    frequency_hz : float
        Frequency [Hz].

    Returns
    -------
    float
        Phase [deg] in [-180, 180), positive when the speed lags.

    Raises
    ------
    ValueError
        Less than one whole period.

    References
    ----------
    .. [1] IEEE Std 1057-2017, "IEEE Standard for Digitizing Waveform Recorders"
       (three-parameter sine fit).
    """
    n = int(np.floor(torque.size / fs_hz * frequency_hz) * fs_hz / frequency_hz)
    if n < 3 or speed.size < n:
        raise ValueError("sine fit needs one whole period of both signals")
    gram, rhs = np.empty((3, 3)), np.empty((3, 2))
    _sine_fit_sums(np.asarray(torque, dtype=np.float64), np.asarray(speed, dtype=np.float64),
                   n, 2.0 * np.pi * frequency_hz / fs_hz, gram, rhs)
    coef = np.linalg.solve(gram, rhs)
    ang = np.angle(coef[0] - 1j * coef[1])  # x = A cos(w + phi) -> a = A cos phi, b = -A sin phi
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


#: the wobble-aware truth fit uses every 8th sample (2 kHz at 16 670 Hz): every simulated line
#: (modulation, its harmonics, the 15-100 Hz load and torsional lines) lies far below the
#: decimated Nyquist frequency, so no alias lands on the modulation frequency
WOBBLE_FIT_STRIDE = 8


def _phase_from_basis(x: np.ndarray, torque: np.ndarray, speed: np.ndarray) -> float:
    """Phase [deg] of ``speed`` behind ``torque`` from a least-squares fit of the basis ``x``
    whose first two columns are cos and sin at the modulation frequency."""
    # normal equations solved by SVD: two wobble lines closer than the window resolves are
    # near-collinear, which leaves the modulation's coefficients (orthogonal to them) intact
    coef = np.linalg.lstsq(x.T @ x, x.T @ np.column_stack([torque, speed]), rcond=1e-12)[0]
    ang = np.angle(coef[0] - 1j * coef[1])  # x = A cos(w + phi) -> a = A cos phi, b = -A sin phi
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


def wobble_free_phase_deg(torque: np.ndarray, speed: np.ndarray, theta_rad: np.ndarray,
                          fs_hz: float, frequency_hz: float, wobble: np.ndarray, *,
                          t0_s: float = 0.0) -> float:
    """:func:`sine_fit_phase_deg` with the speed loop's wobble (rows of
    :func:`~torquemod.twins.vtrack.rig.dynamics.wobble_table`) fitted alongside: cos, sin and DC at
    ``frequency_hz`` plus cos and sin at every wobble line (band rows at their rate in time
    from ``t0_s`` [s], revolution rows at their order of the platform angle ``theta_rad``), so
    that the wobble's leakage into the modulation line (up to 0.5 deg over three revolutions at
    the default 0.2 % RMS, measured) stays out of the truth. Linear least squares on every
    ``WOBBLE_FIT_STRIDE``-th sample of the same whole modulation periods; without wobble rows
    it is :func:`sine_fit_phase_deg`.

    Parameters
    ----------
    torque : ndarray
        Torque [N*m].
    speed : ndarray
        Speed [rad/s].
    theta_rad : ndarray
        Platform angle [rad].
    fs_hz : float
        Sample rate [Hz].
    frequency_hz : float
        Modulation frequency [Hz].
    wobble : ndarray
        The wobble rows.
    t0_s : float
        Time of the first sample [s]. Default 0.

    Returns
    -------
    float
        Phase [deg], positive when the speed lags.
    """
    if wobble.shape[0] == 0:
        return sine_fit_phase_deg(torque, speed, fs_hz, frequency_hz)
    n = int(np.floor(torque.size / fs_hz * frequency_hz) * fs_hz / frequency_hz)
    idx = np.arange(0, n, WOBBLE_FIT_STRIDE)
    t = t0_s + idx / fs_hz
    w = 2.0 * np.pi * frequency_hz
    x = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones(idx.size),
                         wobble_basis(wobble, t, theta_rad[idx])])
    return _phase_from_basis(x, torque[idx], speed[idx])
