"""Small compiled kernels shared by the twin's integrator, sensors and truth (numba).

Taylor polynomials of ``sin``, ``cos`` and ``exp`` for small arguments (``|u| <= SMALL``),
accurate to rounding there: the kernels advance slowly varying transcendental terms by small
increments instead of re-evaluating them.
"""

from __future__ import annotations

import numba

# fast-math without the no-NaN/no-inf assumptions, so that the slip check still sees NaN
FLAGS = {"contract", "arcp", "afn", "reassoc", "nsz"}
_FAST = {"fastmath": FLAGS, "cache": True}
#: largest argument of the small-argument polynomials
SMALL = 0.05


@numba.njit(**_FAST)
def sin_small(u):
    """``sin(u)`` for ``|u| <= 0.05``: truncation below u**11/11! < 2e-22."""
    v = u * u
    return u * (1.0 - v / 6.0 * (1.0 - v / 20.0 * (1.0 - v / 42.0 * (1.0 - v / 72.0
                                                                         * (1.0 - v / 110.0)))))


@numba.njit(**_FAST)
def cos_small(u):
    """``cos(u)`` for ``|u| <= 0.05``: truncation below u**12/12! < 1e-24."""
    v = u * u
    return 1.0 - v / 2.0 * (1.0 - v / 12.0 * (1.0 - v / 30.0 * (1.0 - v / 56.0
                                                                  * (1.0 - v / 90.0))))


@numba.njit(**_FAST)
def exp_small(x):
    """``exp(x)`` for ``|x| <= 0.05``: truncation below x**9/9! < 6e-18 relative to 1."""
    return 1.0 + x * (1.0 + x / 2.0 * (1.0 + x / 3.0 * (1.0 + x / 4.0 * (
        1.0 + x / 5.0 * (1.0 + x / 6.0 * (1.0 + x / 7.0 * (1.0 + x / 8.0)))))))
