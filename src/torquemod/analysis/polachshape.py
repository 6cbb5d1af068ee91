"""The normalised Polach creep-force shape and its inverse (Polach 2005 Eq. 8 with
``x = kS*eps`` and ``r = kA/kS``): ``h(x; r) = (2/pi)*(r*x/(1+(r*x)^2) + arctan(x))``, odd in
x, rising from 0 with slope ``2*(r+1)/pi`` to its first maximum. Used by the family of creep
laws of the friction estimator (:mod:`torquemod.analysis.creeplaws`) and by the synthetic phase
progressions of :mod:`torquemod.testing`; the force itself is
:mod:`torquemod.analysis.contact.polach`'s.
"""

from __future__ import annotations

import numpy as np

from torquemod.analysis.contact.polach import force_function, force_function_slope

__all__ = ["inverse_polach_h", "invert_polach_h", "polach_branch", "polach_h",
           "polach_h_curvature", "polach_h_slope", "slope_ratio_small"]


def polach_h(x, r):
    """Normalised Polach force ``h(x; r) = (2/pi)*(r*x/(1 + (r*x)^2) + arctan(x))``.

    Odd in x: :func:`torquemod.analysis.contact.polach.force_function` with kA = r, kS = 1
    [1]_.

    Parameters
    ----------
    x : float or array_like
        Reduced creepage x = kS*eps [-].
    r : float or array_like
        r = kA/kS [-].

    Returns
    -------
    float or ndarray
        h [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).

    Examples
    --------
    >>> float(polach_h(0.0, 3.0))
    0.0
    >>> round(float(polach_h(1e9, 3.0)), 6)
    1.0
    """
    return force_function(np.asarray(x, dtype=float), k_a=r, k_s=1.0)


def polach_h_slope(x, r):
    """``dh/dx`` of :func:`polach_h`: ``(2/pi)*(r*(1 - (r*x)^2)/(1 + (r*x)^2)^2 + 1/(1 + x^2))``.

    Parameters
    ----------
    x : float or array_like
        Reduced creepage x = kS*eps [-].
    r : float or array_like
        r = kA/kS [-].

    Returns
    -------
    float or ndarray
        dh/dx [-]; ``2*(r + 1)/pi`` at x = 0.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).

    Examples
    --------
    >>> import math
    >>> math.isclose(float(polach_h_slope(0.0, 3.0)), 8 / math.pi)
    True
    """
    return force_function_slope(np.asarray(x, dtype=float), k_a=r, k_s=1.0)


def polach_h_curvature(x, r):
    """``d2h/dx2`` of :func:`polach_h`.

    Parameters
    ----------
    x : float or array_like
        Reduced creepage x = kS*eps [-].
    r : float or array_like
        r = kA/kS [-].

    Returns
    -------
    float or ndarray
        ``(2/pi)*(2*r^2*y*(y^2 - 3)/(1 + y^2)^3 - 2*x/(1 + x^2)^2)``, y = r*x [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    """
    x = np.asarray(x, dtype=float)
    y = r * x
    return (2.0 / np.pi) * (2.0 * r * r * y * (y * y - 3.0) / (1.0 + y * y) ** 3
                            - 2.0 * x / (1.0 + x * x) ** 2)


def polach_branch(r: float) -> tuple[np.ndarray, np.ndarray]:
    """The rising branch of h on a dense grid, up to its first maximum.

    Parameters
    ----------
    r : float
        r = kA/kS [-].

    Returns
    -------
    x : ndarray
        Reduced creepage, 0 and 3000 log-spaced points from 1e-5 to 1e3 [-].
    h : ndarray
        :func:`polach_h` there [-].
    """
    x = np.concatenate([[0.0], np.logspace(-5, 3, 3000)])
    h = polach_h(x, r)
    falling = np.flatnonzero(np.diff(h) <= 0)
    stop = falling[0] + 1 if falling.size else x.size
    return x[:stop], h[:stop]


def invert_polach_h(u, r: float) -> np.ndarray:
    """x with h(x; r) = u on the rising branch, for any scalar r.

    Interpolation on :func:`polach_branch`, then three Newton steps.

    Parameters
    ----------
    u : float or array_like
        h value [-]; the sign is carried over to x.
    r : float
        r = kA/kS [-].

    Returns
    -------
    ndarray
        x [-]; NaN beyond the branch's top.

    Examples
    --------
    >>> round(float(invert_polach_h(polach_h(0.5, 3.0), 3.0)), 9)
    0.5
    """
    xg, hg = polach_branch(r)
    u = np.asarray(u, dtype=float)
    x = np.interp(np.abs(u), hg, xg)
    for _ in range(3):  # Newton polish
        x = x - (polach_h(x, r) - np.abs(u)) / np.maximum(polach_h_slope(x, r), 1e-12)
    x = np.where(np.abs(u) < hg[-1], x, np.nan)
    return np.sign(u) * x


def inverse_polach_h(u, r) -> np.ndarray:
    """x >= 0 with h(x; r) = |u| for r in 1..7.5 (h monotone there), broadcasting u and r.

    Bisection in s = x/(1 + x), then Newton.

    Parameters
    ----------
    u : float or array_like
        h value [-].
    r : float or array_like
        r = kA/kS [-], 1 to 7.5.

    Returns
    -------
    ndarray
        x [-]; NaN where |u| >= 1.

    Examples
    --------
    >>> round(float(inverse_polach_h(polach_h(0.5, 3.0), 3.0)), 9)
    0.5
    """
    u, r = np.broadcast_arrays(np.abs(np.asarray(u, dtype=float)), np.asarray(r, float))
    lo = np.zeros(u.shape)
    hi = np.ones(u.shape)
    for _ in range(34):
        mid = 0.5 * (lo + hi)
        below = polach_h(mid / (1.0 - mid), r) < u
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    s = 0.5 * (lo + hi)
    x = s / (1.0 - s)
    for _ in range(2):
        x = x - (polach_h(x, r) - u) / np.maximum(polach_h_slope(x, r), 1e-300)
    return np.where(u < 1.0, np.maximum(x, 0.0), np.nan)


def slope_ratio_small(coa, mu, r):
    """The small-signal model's reduced creepage and creep-coefficient ratio at a CoA.

    Parameters
    ----------
    coa : float or array_like
        Utilised adhesion [-].
    mu : float
        Friction coefficient [-].
    r : float or array_like
        r = kA/kS [-], 1 to 7.5.

    Returns
    -------
    x : ndarray
        ``h^-1(CoA/mu; r)`` [-].
    ratio : ndarray
        ``h'(0)/h'(x)`` [-]: the initial creep coefficient over the one at CoA.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    """
    x = inverse_polach_h(coa / mu, r)
    return x, 2.0 * (r + 1.0) / np.pi / polach_h_slope(x, r)
