"""Kalker's creepage coefficients c11, c22, c23 of the linear theory of rolling contact.

The values are Kalker's table (J.J. Kalker, *Three-dimensional elastic bodies in rolling
contact*, Kluwer 1990, Table E.3, as tabulated in the CONTACT program); see FACTS.md §3.
Rows are contact-ellipse shapes (a = semi-axis in the rolling direction, b = lateral
semi-axis), columns Poisson's ratio nu = 0, 0.25, 0.5.

Interpolation: piecewise linear in ``log(a/b)`` between the five tabulated shapes and linear
in nu between the three columns, so the table nodes are reproduced exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ..errors import InputError

#: Tabulated ellipse shapes as a/b (rows of the table: a/b = 0.1, 0.5, 1; b/a = 0.5, 0.1).
A_OVER_B_NODES: tuple[float, ...] = (0.1, 0.5, 1.0, 2.0, 10.0)
#: Tabulated Poisson ratios.
POISSON_NODES: tuple[float, ...] = (0.0, 0.25, 0.5)

#: c11[row][column]; rows follow :data:`A_OVER_B_NODES`, columns :data:`POISSON_NODES`.
C11_TABLE = np.array([
    [2.51, 3.31, 4.85],
    [2.88, 3.62, 4.83],
    [3.40, 4.12, 5.20],
    [4.37, 5.10, 6.11],
    [10.7, 11.7, 12.9],
])
C22_TABLE = np.array([
    [2.51, 2.52, 2.53],
    [2.88, 3.01, 3.14],
    [3.40, 3.67, 3.98],
    [4.37, 4.90, 5.56],
    [10.7, 12.8, 16.0],
])
C23_TABLE = np.array([
    [0.334, 0.473, 0.731],
    [0.827, 0.929, 1.07],
    [1.33, 1.47, 1.63],
    [2.35, 2.62, 2.96],
    [12.2, 14.6, 18.0],
])


@dataclass(frozen=True)
class KalkerCoefficients:
    """Kalker's creepage coefficients [-]: longitudinal ``c11``, lateral ``c22``, spin ``c23``."""

    c11: float
    c22: float
    c23: float


def _interp_table(table: np.ndarray, x_log: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``table`` in (log(a/b), nu); exact at the nodes."""
    grid = (np.log(np.asarray(A_OVER_B_NODES)), np.asarray(POISSON_NODES))
    interp = RegularGridInterpolator(grid, table, method="linear")
    xb, nb = np.broadcast_arrays(x_log, nu)
    return interp(np.stack([xb.ravel(), nb.ravel()], axis=-1)).reshape(xb.shape)


def kalker_coefficients(a_over_b, poisson_ratio=0.25):
    """Kalker's c11, c22, c23 [-] for ellipse shape ``a_over_b`` and Poisson ratio nu.

    Kalker (1990) Table E.3 (FACTS.md §3), interpolated linearly in ``log(a/b)`` and in nu.
    ``a_over_b`` must lie in [0.1, 10] and ``poisson_ratio`` in [0, 0.5]; outside the table
    an :class:`~torquemod.errors.InputError` is raised rather than extrapolating.

    Returns a :class:`KalkerCoefficients` of floats for scalar input, of arrays otherwise.

    >>> kalker_coefficients(1.0, 0.25).c11
    4.12
    """
    g = np.asarray(a_over_b, dtype=float)
    nu = np.asarray(poisson_ratio, dtype=float)
    lo, hi = A_OVER_B_NODES[0], A_OVER_B_NODES[-1]
    if np.any(~np.isfinite(g)) or np.any(g < lo * (1 - 1e-12)) or np.any(g > hi * (1 + 1e-12)):
        raise InputError(f"a/b = {a_over_b} is outside Kalker's table [{lo}, {hi}]",
                         hint="the contact ellipse is too elongated for the tabulated values")
    if np.any(~np.isfinite(nu)) or np.any(nu < 0.0) or np.any(nu > 0.5):
        raise InputError(f"Poisson ratio {poisson_ratio} is outside [0, 0.5]")
    x_log = np.log(np.clip(g, lo, hi))
    vals = [_interp_table(t, x_log, nu) for t in (C11_TABLE, C22_TABLE, C23_TABLE)]
    if np.ndim(g) == 0 and np.ndim(nu) == 0:
        return KalkerCoefficients(*(float(v) for v in vals))
    return KalkerCoefficients(*vals)
