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
    """Normalised Polach force ``h(x; r) = (2/pi)*(r*x/(1+(r*x)^2) + arctan(x))`` (P05 Eq. 8
    with ``x = kS*eps``, ``r = kA/kS``), odd in x: the library's
    :func:`torquemod.analysis.contact.polach.force_function` with kA = r, kS = 1."""
    return force_function(np.asarray(x, dtype=float), k_a=r, k_s=1.0)


def polach_h_slope(x, r):
    """``dh/dx`` of :func:`polach_h`: ``(2/pi)*(r*(1-(rx)^2)/(1+(rx)^2)^2 + 1/(1+x^2))``
    (:func:`torquemod.analysis.contact.polach.force_function_slope`)."""
    return force_function_slope(np.asarray(x, dtype=float), k_a=r, k_s=1.0)


def polach_h_curvature(x, r):
    """``d2h/dx2`` of :func:`polach_h`: ``(2/pi)*(2 r^2 y (y^2-3)/(1+y^2)^3 - 2x/(1+x^2)^2)``,
    ``y = r*x``."""
    x = np.asarray(x, dtype=float)
    y = r * x
    return (2.0 / np.pi) * (2.0 * r * r * y * (y * y - 3.0) / (1.0 + y * y) ** 3
                            - 2.0 * x / (1.0 + x * x) ** 2)


def polach_branch(r: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, h) on a dense grid of the rising branch of h (up to its first maximum)."""
    x = np.concatenate([[0.0], np.logspace(-5, 3, 3000)])
    h = polach_h(x, r)
    falling = np.flatnonzero(np.diff(h) <= 0)
    stop = falling[0] + 1 if falling.size else x.size
    return x[:stop], h[:stop]


def invert_polach_h(u, r: float) -> np.ndarray:
    """x with h(x; r) = u on the rising branch, any scalar r (NaN beyond the branch's top)."""
    xg, hg = polach_branch(r)
    u = np.asarray(u, dtype=float)
    x = np.interp(np.abs(u), hg, xg)
    for _ in range(3):  # Newton polish
        x = x - (polach_h(x, r) - np.abs(u)) / np.maximum(polach_h_slope(x, r), 1e-12)
    x = np.where(np.abs(u) < hg[-1], x, np.nan)
    return np.sign(u) * x


def inverse_polach_h(u, r) -> np.ndarray:
    """x >= 0 with h(x; r) = |u| for r in 1..7.5 (h monotone there), broadcasting u and r:
    bisection in s = x/(1 + x), then Newton. NaN where
    |u| >= 1."""
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
    """(x, h'(0)/h'(x)): the small-signal model's x = h^-1(CoA/mu; r) and the ratio of the
    initial creep coefficient to the one at CoA (CoA, mu [-])."""
    x = inverse_polach_h(coa / mu, r)
    return x, 2.0 * (r + 1.0) / np.pi / polach_h_slope(x, r)
