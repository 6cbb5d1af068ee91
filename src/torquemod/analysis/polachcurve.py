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
    swing_nodes,
)
from torquemod.errors import InputError

__all__ = ["longitudinal_mean", "longitudinal_mean_jacobian", "polach_coa", "polach_coa_jacobian",
           "polach_slope"]


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


def polach_coa_jacobian(xi, theta):
    """Derivatives of the constant-friction :func:`polach_coa` with respect to its three
    parameters ``(mu, kA*s, kS*s)`` at ``|xi|``, in closed form.

    With ``e = |xi|/mu``, ``g(t) = t/(1 + t^2)`` and ``CoA = (2/pi)*mu*(g(A*e) +
    arctan(S*e))`` (``A = kA*s``, ``S = kS*s``)::

        dCoA/dmu = (2/pi)*(g(A*e) + arctan(S*e) - e*(A*g'(A*e) + S/(1 + (S*e)^2)))
        dCoA/dA  = (2/pi)*|xi|*g'(A*e),      g'(t) = (1 - t^2)/(1 + t^2)^2
        dCoA/dS  = (2/pi)*|xi|/(1 + (S*e)^2)

    Parameters
    ----------
    xi : float or array_like
        Creepage [-]; its magnitude is used.
    theta : sequence of float
        ``(mu, kA*s, kS*s)`` [-].

    Returns
    -------
    ndarray
        Shape ``xi.shape + (3,)``: d CoA/d mu, d CoA/d (kA*s), d CoA/d (kS*s).

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3) and (8), differentiated.
    """
    x = np.abs(np.asarray(xi, dtype=float))
    mu = max(float(theta[0]), 1e-12)
    a, s = float(theta[1]), float(theta[2])
    e = x / mu
    t = a * e
    u = s * e
    with np.errstate(over="ignore"):  # far on the curve t^2 overflows: r -> 0, g' -> 0
        r = 1.0 / (1.0 + t * t)
        h1 = 1.0 / (1.0 + u * u)
    g = t * r
    g1 = r * (2.0 * r - 1.0)  # (1 - t^2)/(1 + t^2)^2
    c = 2.0 / np.pi
    out = np.empty((*x.shape, 3))  # the columns in place (np.stack's values, without it)
    out[..., 0] = c * (g + np.arctan(u) - e * (a * g1 + s * h1))
    out[..., 1] = c * x * g1
    out[..., 2] = c * x * h1
    return out


def longitudinal_mean_jacobian(xi, theta, swing=None):
    """Derivatives of the constant-friction :func:`longitudinal_mean` with respect to
    ``(mu, kA*s, kS*s)``: :func:`polach_coa_jacobian`, or over a swing the period average
    of the signed curve's derivatives (the same quadrature nodes) with the sign of the mean.

    Parameters
    ----------
    xi : float or array_like
        Mean creepage [-].
    theta : sequence of float
        ``(mu, kA*s, kS*s)`` [-].
    swing : float or array_like, optional
        Creepage swing amplitude a [-]; None for the static curve.

    Returns
    -------
    ndarray
        Shape ``xi.shape + (3,)`` [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3) and (8), differentiated.
    """
    if swing is None:
        return polach_coa_jacobian(xi, theta)
    c = swing_nodes()
    x = np.asarray(xi, dtype=float)[..., None] + np.abs(np.asarray(swing, float))[..., None] * c
    sgn = np.sign(x)
    mean = np.mean(sgn * polach_coa(np.abs(x), theta), axis=-1)
    jac = np.mean(sgn[..., None] * polach_coa_jacobian(x, theta), axis=-2)
    return np.sign(mean)[..., None] * jac
