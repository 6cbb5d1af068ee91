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

import numpy as np

from torquemod.analysis.contact.polach import swing_nodes

__all__ = ["FitModel"]

_TWO_OVER_PI = 2.0 / np.pi


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
            self._sgn = None
            self._x = np.abs(xi)
        else:
            # node-major (n_nodes, n): the Jacobian's period average is then a reduction over
            # the leading axis (the nodes added one after the other, as numpy's mean over
            # the middle axis of the point-major (n, n_nodes, 3) array adds them)
            nodes = (xi[..., None] + np.abs(np.asarray(swing, dtype=float))[..., None]
                     * swing_nodes()).T.copy()
            self._sgn = np.sign(nodes)
            self._x = np.abs(nodes)
        self._cx = _TWO_OVER_PI * self._x  # (2/pi)*|x|, the factor of two derivatives
        self._lateral = lateral
        self._mu = None  # the friction of self._eps
        self._eps = None
        self._key = None  # the parameters of the intermediates below
        self._state: tuple = ()

    def _at(self, th) -> tuple:
        """The curve's intermediates at ``th``: (a, s, |x|/mu, kA*s*|x|/mu, 1 + its
        square, kS*s*|x|/mu, arctan of it, signed mean CoA, its magnitude, the model)."""
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
        ke = a * eps
        den = ke * ke
        den += 1.0
        u = s * eps
        at = np.arctan(u)
        v = ke / den
        v += at
        v *= _TWO_OVER_PI
        v *= mu
        if self._sgn is None:
            signed = v
            f = v
        else:
            v *= self._sgn
            # point-major for the mean over the nodes: numpy's pairwise sum along a
            # contiguous axis, as in swing_average
            signed = np.add.reduce(v.T.copy(), axis=-1)
            signed /= v.shape[0]
            f = np.abs(signed)
        m = np.hypot(f, self._lateral)
        self._key = key
        self._state = (a, s, eps, ke, den, u, at, signed, f, m)
        return self._state

    def model(self, th) -> np.ndarray:
        """``hypot(CoA_mean, lateral)`` at ``th = (mu, kA*s, kS*s)`` [-] (kept for the
        Jacobian: not to be modified)."""
        return self._at(th)[-1]

    def jacobian(self, th, sigma: np.ndarray, full: bool = True) -> np.ndarray:
        """d model/d theta divided by ``sigma[:, None]``: shape (n, 3), or with ``full``
        False (n, 2) without the column of mu (a new C-ordered array)."""
        a, s, eps, ke, den, u, at, signed, f, m = self._at(th)
        r = 1.0 / den
        with np.errstate(over="ignore"):  # far on the curve u^2 overflows: h1 -> 0
            h1 = u * u
        h1 += 1.0
        h1 = 1.0 / h1
        g1 = 2.0 * r
        g1 -= 1.0
        g1 *= r
        k = 3 if full else 2
        out = np.empty((*self._x.shape, k))
        if full:
            col0 = ke * r
            col0 += at
            w = a * g1
            w += s * h1
            w *= eps
            col0 -= w
            col0 *= _TWO_OVER_PI
            out[..., 0] = col0
        np.multiply(self._cx, g1, out=out[..., k - 2])
        np.multiply(self._cx, h1, out=out[..., k - 1])
        if self._sgn is not None:
            out *= self._sgn[..., None]
            out = np.add.reduce(out, axis=0)
            out /= self._sgn.shape[0]
            out *= np.sign(signed)[:, None]
        ratio = np.divide(f, m, out=np.ones_like(f), where=m > 0)
        out *= ratio[:, None]
        out /= sigma[:, None]
        return out
