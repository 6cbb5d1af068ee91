"""The lumped Polach creep-force curve that :func:`torquemod.analysis.fit.fit_polach` fits
(Polach 2005, Eqs. 3, 8 and 9): its value and slope for the fit's internal parameter vector,
and its mean over a modulation's creepage swing. The model and its parameters are described
in :mod:`torquemod.analysis.fit`.
"""

from __future__ import annotations

import numpy as np

from torquemod.analysis.contact.polach import (
    force_function,
    force_function_slope,
    friction_coefficient,
    swing_average,
)
from torquemod.errors import InputError

__all__ = ["longitudinal_mean", "polach_coa", "polach_slope"]


def polach_coa(xi, theta, *, speed_m_s=None):
    """Coefficient of adhesion of the lumped Polach model,
    ``CoA = mu*force_function(|xi|/mu; kA*s, kS*s)``.

    Parameters
    ----------
    xi : float or array_like
        Creepage [-]; its magnitude is used.
    theta : sequence of float
        ``(mu, kA*s, kS*s)`` [-] (constant friction) or ``(mu0, kA*s, kS*s, A, B)``
        [-, -, -, -, s/m] (friction falling with slip velocity ``w = |xi|*V``).
    speed_m_s : float or array_like, optional
        Rolling speed V [m/s]; required with five parameters.

    Returns
    -------
    ndarray
        CoA [-], non-negative.

    Raises
    ------
    InputError
        Five parameters without ``speed_m_s``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8) and (9).

    Examples
    --------
    >>> float(polach_coa(0.0, (0.3, 40.0, 10.0)))
    0.0
    """
    xi = np.abs(np.asarray(xi, dtype=float))
    mu = theta[0]
    if len(theta) == 5:
        if speed_m_s is None:
            raise InputError("the velocity-dependent model needs speed_m_s")
        mu = friction_coefficient(xi * np.asarray(speed_m_s, dtype=float), mu0=theta[0],
                                  a_ratio=theta[3], b_s_m=theta[4])
    mu = np.maximum(mu, 1e-12)
    return mu * force_function(xi / mu, k_a=theta[1], k_s=theta[2])


def polach_slope(xi, theta, *, speed_m_s=None):
    """Creep coefficient k = dCoA/dxi of :func:`polach_coa` at ``|xi|``.

    Analytic for constant friction; a central difference for the velocity-dependent model.

    Parameters
    ----------
    xi : float or array_like
        Creepage [-].
    theta : sequence of float
        As for :func:`polach_coa`.
    speed_m_s : float or array_like, optional
        Rolling speed V [m/s] (velocity-dependent model).

    Returns
    -------
    ndarray
        k [-]; ``2*(kA*s + kS*s)/pi`` at xi = 0.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8), differentiated.

    Examples
    --------
    >>> import math
    >>> math.isclose(polach_slope(0.0, (0.3, 40.0, 10.0)), 2 * 50.0 / math.pi)
    True
    """
    xi = np.abs(np.asarray(xi, dtype=float))
    if len(theta) == 3:
        mu, a, s = (float(v) for v in theta)
        return force_function_slope(xi / mu, k_a=a, k_s=s)
    h = np.maximum(1e-7, 1e-4 * xi)
    lo = np.maximum(xi - h, 0.0)
    hi = xi + h
    f_hi = polach_coa(hi, theta, speed_m_s=speed_m_s)
    f_lo = polach_coa(lo, theta, speed_m_s=speed_m_s)
    return (f_hi - f_lo) / (hi - lo)


def longitudinal_mean(xi, theta, swing=None, speed_m_s=None):
    """Mean longitudinal CoA at creepage ``xi``: the static curve, or its period average
    over a sinusoidal creepage swing (the mean of a modulated step, ``CoA_mean`` of
    :mod:`torquemod.analysis.fit`, via
    :func:`torquemod.analysis.contact.polach.swing_average` of the signed curve).

    Parameters
    ----------
    xi : float or array_like
        Mean creepage [-].
    theta : sequence of float
        As for :func:`polach_coa`.
    swing : float or array_like, optional
        Creepage swing amplitude a [-]; None for the static curve.
    speed_m_s : float or array_like, optional
        Rolling speed V [m/s] per point for the velocity-dependent model (slip velocity
        ``|xi + a*cos(theta)|*V``).

    Returns
    -------
    ndarray
        Mean CoA [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8) and (9).

    Examples
    --------
    >>> import math
    >>> th = (0.3, 40.0, 10.0)
    >>> math.isclose(longitudinal_mean(0.01, th, swing=0.0), polach_coa(0.01, th))
    True
    """
    if swing is None:
        return polach_coa(xi, theta, speed_m_s=speed_m_s)
    spd = None if speed_m_s is None else np.asarray(speed_m_s, dtype=float)[..., None]

    def signed(x):
        return np.sign(x) * polach_coa(np.abs(x), theta, speed_m_s=spd)
    return np.abs(swing_average(signed, xi, swing))


def _mean_slope(xi, theta, swing=None, speed_m_s=None):
    """d CoA_mean/d xi [-] of :func:`longitudinal_mean` at ``xi`` [-]: the static slope
    without swing, else a central difference of the period average
    (:mod:`torquemod.analysis.fit`)."""
    if swing is None:
        return polach_slope(xi, theta, speed_m_s=speed_m_s)
    xi = np.abs(np.asarray(xi, dtype=float))
    h = np.maximum(1e-7, 1e-4 * xi)
    x_lo, x_hi = np.maximum(xi - h, 0.0), xi + h
    return ((longitudinal_mean(x_hi, theta, swing, speed_m_s)
             - longitudinal_mean(x_lo, theta, swing, speed_m_s)) / (x_hi - x_lo))
