"""The constant-friction model of :func:`torquemod.analysis.fit.fit_polach` at the fit's points,
with its Jacobian, evaluated for the optimisers that call it thousands of times per fit.

The model is ``hypot(CoA_mean(xi; theta), lateral)`` with ``theta = (mu, kA*s, kS*s)`` and
``CoA_mean`` the static lumped Polach curve (Polach 2005, Eqs. 3 and 8) or its period average
over a creepage swing (:func:`torquemod.analysis.polachcurve.longitudinal_mean`). The values
are those of :func:`~torquemod.analysis.polachcurve.longitudinal_mean` and
:func:`~torquemod.analysis.polachcurve.longitudinal_mean_jacobian` to the last bit: the same
floating-point operations in the same order on arrays of the same shape, with what does not
depend on ``theta`` (the swing's creepages, their signs and magnitudes) computed once, the
creepage over friction ``|xi|/mu`` kept while ``mu`` stays (a profile-likelihood solve holds
it fixed), and the curve's intermediates at the last parameters reused by the Jacobian that
the solvers ask for next at the same parameters.
"""

from __future__ import annotations

import numba
import numpy as np

from torquemod.analysis.contact.polach import swing_nodes
from torquemod.dsp import numpyblas

__all__ = ["FitModel"]

_TWO_OVER_PI = 2.0 / np.pi
# IEEE arithmetic as numpy's: no fast-math (no reassociation, no fused multiply-add)
_EXACT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}


@numba.njit(**_EXACT)
def _sign(x: float) -> float:
    """numpy's sign of a float (0 for both zeros, NaN for NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x


@numba.njit(**_EXACT)
def _mean_kernel(eps, at, sgn, a: float, mu: float, average: bool, out):
    """Signed CoA per point: the static curve (one node) or the mean over the swing's nodes,
    as numpy's ``mean(sign*mu*(2/pi)*(ke/(1 + ke^2) + arctan(u)), axis=-1)``."""
    n, m = eps.shape
    row = np.empty(m)
    for i in range(n):
        for k in range(m):
            ke = a * eps[i, k]
            den = ke * ke
            den += 1.0
            v = ke / den
            v += at[i, k]
            v *= _TWO_OVER_PI
            v *= mu
            row[k] = v * sgn[i, k] if average else v
        if average:
            out[i] = (0.0 + numpyblas.pairwise_leaf(row, 0, m)) / m
        else:
            out[i] = row[0]


@numba.njit(**_EXACT)
def _jacobian_kernel(eps, at, sgn, cx, a: float, s: float, full: bool, average: bool,
                     signed, f, mod, sigma, out):
    """d model/d theta / sigma per point into ``out`` (n, 3) or (n, 2) without mu's column:
    the closed form of :func:`torquemod.analysis.polachcurve.polach_coa_jacobian` at each
    node, averaged over the nodes (numpy's sequential sum over a middle axis) with the sign
    of the mean, through the hypotenuse with the lateral CoA."""
    n, m = eps.shape
    k0 = 1 if full else 0
    for i in range(n):
        acc0 = 0.0
        acc1 = 0.0
        acc2 = 0.0
        for k in range(m):
            e = eps[i, k]
            ke = a * e
            den = ke * ke
            den += 1.0
            r = 1.0 / den
            u = s * e
            h1 = u * u
            h1 += 1.0
            h1 = 1.0 / h1
            g1 = 2.0 * r
            g1 -= 1.0
            g1 *= r
            c1 = cx[i, k] * g1
            c2 = cx[i, k] * h1
            c0 = 0.0
            if full:
                c0 = ke * r
                c0 += at[i, k]
                w = a * g1
                w += s * h1
                w *= e
                c0 -= w
                c0 *= _TWO_OVER_PI
            if average:
                sg = sgn[i, k]
                acc0 += c0 * sg
                acc1 += c1 * sg
                acc2 += c2 * sg
            else:
                acc0, acc1, acc2 = c0, c1, c2
        if average:
            sm = _sign(signed[i])
            acc0 = acc0 / m * sm
            acc1 = acc1 / m * sm
            acc2 = acc2 / m * sm
        ratio = f[i] / mod[i] if mod[i] > 0.0 else 1.0
        if full:
            out[i, 0] = acc0 * ratio / sigma[i]
        out[i, k0] = acc1 * ratio / sigma[i]
        out[i, k0 + 1] = acc2 * ratio / sigma[i]


class FitModel:
    """``hypot(CoA_mean, lateral)`` of the constant-friction lumped Polach curve at fixed
    points, and its derivatives with respect to ``(mu, kA*s, kS*s)``.

    Parameters
    ----------
    xi : ndarray
        Mean creepage per point [-].
    swing : ndarray or None
        Creepage swing amplitude per point [-] (non-negative); None for the static curve.
    lateral : ndarray
        Lateral CoA per point [-] (zeros without it).

    Notes
    -----
    ``CoA = mu*(2/pi)*[kA*s*e/(1 + (kA*s*e)^2) + arctan(kS*s*e)]`` with ``e = |xi|/mu``
    (O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
    limit", Wear 258 (2005) 992-1000, Eqs. 3 and 8); over a swing the mean of the signed
    curve at 32 nodes ``xi + a*cos(theta_k)``
    (:func:`torquemod.analysis.contact.polach.swing_average`).
    """

    def __init__(self, xi: np.ndarray, swing: np.ndarray | None, lateral: np.ndarray):
        xi = np.asarray(xi, dtype=float)
        if swing is None:
            nodes = xi[:, None]
        else:
            nodes = xi[..., None] + np.abs(np.asarray(swing, dtype=float))[..., None] \
                * swing_nodes()
        self._average = swing is not None
        if nodes.shape[-1] > 128:  # pragma: no cover - swing_nodes() gives 32
            raise ValueError("FitModel sums at most 128 nodes as numpy does")
        self._sgn = np.ascontiguousarray(np.sign(nodes))
        self._x = np.ascontiguousarray(np.abs(nodes))
        self._cx = _TWO_OVER_PI * self._x  # (2/pi)*|x|, the factor of two derivatives
        self._lateral = np.ascontiguousarray(lateral, dtype=float)
        self._mu = None  # the friction of self._eps
        self._eps = None
        self._key = None  # the parameters of the state below
        self._state: tuple = ()

    def _at(self, th) -> tuple:
        """The state at ``th``: (a, s, |x|/mu, arctan(kS*s*|x|/mu), signed mean CoA, its
        magnitude, the model)."""
        th = np.asarray(th, dtype=float)
        key = th.tobytes()
        if key == self._key:
            return self._state
        mu = max(float(th[0]), 1e-12)
        a, s = float(th[1]), float(th[2])
        if mu != self._mu:
            self._eps = self._x / mu
            self._mu = mu
        eps = self._eps
        u = s * eps
        at = np.arctan(u, out=u)
        signed = np.empty(eps.shape[0])
        _mean_kernel(eps, at, self._sgn, a, mu, self._average, signed)
        f = np.abs(signed) if self._average else signed
        m = np.hypot(f, self._lateral)
        self._key = key
        self._state = (a, s, eps, at, signed, f, m)
        return self._state

    def model(self, th) -> np.ndarray:
        """``hypot(CoA_mean, lateral)`` at ``th = (mu, kA*s, kS*s)`` [-] (kept for the
        Jacobian: not to be modified)."""
        return self._at(th)[-1]

    def jacobian(self, th, sigma: np.ndarray, full: bool = True) -> np.ndarray:
        """d model/d theta divided by ``sigma[:, None]``: shape (n, 3), or with ``full``
        False (n, 2) without the column of mu (a new C-ordered array)."""
        a, s, eps, at, signed, f, m = self._at(th)
        out = np.empty((eps.shape[0], 3 if full else 2))
        _jacobian_kernel(eps, at, self._sgn, self._cx, a, s, full, self._average, signed, f,
                         m, np.asarray(sigma, dtype=float), out)
        return out
