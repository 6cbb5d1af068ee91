"""Kalker's creepage coefficients c11, c22, c23 of the linear theory of rolling contact.

The values are Kalker's full table (J.J. Kalker, *Three-dimensional elastic bodies in rolling
contact*, Kluwer 1990, Table E.3; all 19 ellipse shapes and the three Poisson ratios, as
tabulated in the CONTACT program's ``linrol`` routine). Rows are
contact-ellipse shapes (a = semi-axis in the rolling direction, b = lateral semi-axis):
a/b = 0.1 ... 1.0 in steps of 0.1, then b/a = 0.9 ... 0.1; columns are Poisson's ratio
nu = 0, 0.25, 0.5. (One widely copied port of CONTACT's table reads c23 = 1.15 at a/b = 0.8,
nu = 0.25; the table and CONTACT's own source give 1.25, which also continues the row's
steps of about 0.11.)

Interpolation (the usual practice for this table): linear in g within each half of the table,
g = a/b for a <= b and g = b/a for a > b (rows 0.1 apart), then quadratic (Lagrange) through
the three nu columns. Both are exact at the table's nodes; between rows the linear rule errs
by well under the table's own 3-digit rounding where the columns are smooth, more towards
b/a = 0.1 where c23 grows fastest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from torquemod.errors import InputError

#: Tabulated shapes g of each half (a/b for a <= b, b/a for a > b).
G_NODES: tuple[float, ...] = tuple(round(0.1 * k, 1) for k in range(1, 11))
#: Tabulated ellipse shapes as a/b, ascending: 0.1 ... 1.0, then 1/0.9 ... 10.
A_OVER_B_NODES: tuple[float, ...] = G_NODES + tuple(1.0 / g for g in G_NODES[-2::-1])
#: Tabulated Poisson ratios.
POISSON_NODES: tuple[float, ...] = (0.0, 0.25, 0.5)

# rows: a/b = 0.1 ... 1.0, then b/a = 0.9 ... 0.1 (ascending a/b); columns: nu = 0, 0.25, 0.5
#: c11 [-] per row of :data:`A_OVER_B_NODES` and column of :data:`POISSON_NODES`.
C11_TABLE = np.array([
    [2.51, 3.31, 4.85], [2.59, 3.37, 4.81], [2.68, 3.44, 4.80], [2.78, 3.53, 4.82],
    [2.88, 3.62, 4.83], [2.98, 3.72, 4.91], [3.09, 3.81, 4.97], [3.19, 3.91, 5.05],
    [3.29, 4.01, 5.12], [3.40, 4.12, 5.20],
    [3.51, 4.22, 5.30], [3.65, 4.36, 5.42], [3.82, 4.54, 5.58], [4.06, 4.78, 5.80],
    [4.37, 5.10, 6.11], [4.84, 5.57, 6.57], [5.57, 6.34, 7.34], [6.96, 7.78, 8.82],
    [10.7, 11.7, 12.9],
])
#: c22 [-], same layout.
C22_TABLE = np.array([
    [2.51, 2.52, 2.53], [2.59, 2.63, 2.66], [2.68, 2.75, 2.81], [2.78, 2.88, 2.98],
    [2.88, 3.01, 3.14], [2.98, 3.14, 3.31], [3.09, 3.28, 3.48], [3.19, 3.41, 3.65],
    [3.29, 3.54, 3.82], [3.40, 3.67, 3.98],
    [3.51, 3.81, 4.16], [3.65, 3.99, 4.39], [3.82, 4.21, 4.67], [4.06, 4.50, 5.04],
    [4.37, 4.90, 5.56], [4.84, 5.48, 6.31], [5.57, 6.40, 7.51], [6.96, 8.14, 9.79],
    [10.7, 12.8, 16.0],
])
#: c23 [-], same layout.
C23_TABLE = np.array([
    [0.334, 0.473, 0.731], [0.483, 0.603, 0.809], [0.607, 0.715, 0.889],
    [0.720, 0.823, 0.977], [0.827, 0.929, 1.07], [0.930, 1.03, 1.18], [1.03, 1.14, 1.29],
    [1.13, 1.25, 1.40], [1.23, 1.36, 1.51], [1.33, 1.47, 1.63],
    [1.44, 1.59, 1.77], [1.58, 1.75, 1.94], [1.76, 1.95, 2.18], [2.01, 2.23, 2.50],
    [2.35, 2.62, 2.96], [2.88, 3.24, 3.70], [3.79, 4.32, 5.01], [5.72, 6.63, 7.89],
    [12.2, 14.6, 18.0],
])


@dataclass(frozen=True)
class KalkerCoefficients:
    """Kalker's creepage coefficients (Kalker 1990, Table E.3).

    Attributes
    ----------
    c11 : float
        Longitudinal [-].
    c22 : float
        Lateral [-].
    c23 : float
        Spin [-].
    """

    c11: float
    c22: float
    c23: float


def _along_g(table: np.ndarray, a_over_b: np.ndarray) -> np.ndarray:
    """(..., 3): the table's three nu columns at each a/b, linear in g within each half."""
    g = np.where(a_over_b <= 1.0, a_over_b, 1.0 / a_over_b)
    low_half, high_half = table[:10], table[9:][::-1]  # both as functions of ascending g
    cols = []
    for j in range(3):
        lo = np.interp(g, G_NODES, low_half[:, j])
        hi = np.interp(g, G_NODES, high_half[:, j])
        cols.append(np.where(a_over_b <= 1.0, lo, hi))
    return np.stack(cols, axis=-1)


def _along_nu(cols: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Quadratic Lagrange interpolation through the columns at nu = 0, 0.25, 0.5."""
    n0, n1, n2 = POISSON_NODES
    w0 = (nu - n1) * (nu - n2) / ((n0 - n1) * (n0 - n2))
    w1 = (nu - n0) * (nu - n2) / ((n1 - n0) * (n1 - n2))
    w2 = (nu - n0) * (nu - n1) / ((n2 - n0) * (n2 - n1))
    return w0 * cols[..., 0] + w1 * cols[..., 1] + w2 * cols[..., 2]


def kalker_coefficients(a_over_b, poisson_ratio=0.25):
    """Kalker's creepage coefficients c11, c22, c23 of the linear theory of rolling contact.

    Table E.3 of [1]_, interpolated linearly in g = a/b or b/a within the table's halves
    and quadratically through the three nu columns (module docstring).

    Parameters
    ----------
    a_over_b : float or array_like
        Contact-ellipse shape a/b [-] (a rolling, b lateral semi-axis), in [0.1, 10].
    poisson_ratio : float or array_like, default 0.25
        Poisson's ratio nu [-], in [0, 0.5].

    Returns
    -------
    KalkerCoefficients
        c11, c22, c23 [-]: floats for scalar input, arrays otherwise.

    Raises
    ------
    InputError
        ``a_over_b`` or ``poisson_ratio`` outside the table (no extrapolation).

    References
    ----------
    .. [1] J.J. Kalker, "Three-dimensional elastic bodies in rolling contact", Kluwer,
       Dordrecht 1990, Table E.3.

    Examples
    --------
    >>> kalker_coefficients(1.0, 0.25).c11
    4.12
    """
    g = np.asarray(a_over_b, dtype=float)
    nu = np.asarray(poisson_ratio, dtype=float)
    lo, hi = A_OVER_B_NODES[0], A_OVER_B_NODES[-1]
    if np.any(~np.isfinite(g)) or np.any(g < lo * (1 - 1e-12)) or np.any(g > hi * (1 + 1e-12)):
        raise InputError(f"a/b = {a_over_b} is outside Kalker's table [{lo}, {hi:g}]",
                         hint="the contact ellipse is too elongated for the tabulated values")
    if np.any(~np.isfinite(nu)) or np.any(nu < 0.0) or np.any(nu > 0.5):
        raise InputError(f"Poisson ratio {poisson_ratio} is outside [0, 0.5]")
    g = np.clip(g, lo, hi)
    g, nu = np.broadcast_arrays(g, nu)
    vals = [_along_nu(_along_g(t, g), nu) for t in (C11_TABLE, C22_TABLE, C23_TABLE)]
    if np.ndim(g) == 0:
        return KalkerCoefficients(*(float(v) for v in vals))
    return KalkerCoefficients(*vals)
