"""Compiled Newton solve of the large-signal theory's collocation equations (numba, nogil).

:func:`torquemod.twins.vtrack.theory.large_signal_phase_deg` finds the periodic steady state of the
wheel-contact-platform model by trigonometric collocation (Urabe 1965; the alternating
frequency/time form of Cameron & Griffin 1989): unknowns are the wheel-speed deviation ``u``
and the platform-speed deviation ``w`` [rad/s] at ``n`` instants of one period, equations::

    r1 = L u - (T_dc + A*s(t)) + R_w*F_x(u, w) = 0          (wheel; L = J_w d/dt [+ G2])
    r2 = w - P F_x(u, w) = 0                                (platform loop, P = R_p H_p)

with ``L`` and ``P`` circulant matrices built by theory.py and ``F_x`` the Polach (2005)
longitudinal creep force (P05 Eqs. 1-9, the same operations in the same order as the
vectorised :func:`torquemod.analysis.contact.polach.creep_force`) at the creepage
``xi = (V0*xi0 + u*R_w - w*R_p)/V``, ``V = (W_ref + w)*R_p``. :func:`newton_periodic` is
Newton-Raphson on them (dense Jacobian by central differences of the force, backtracking
on the residual norm) as theory.py ran it in Python before an earlier version; here it
runs without the GIL, so that the twin's steps solve their theory side by side, and each
step solves the Jacobian's ``n x n`` Schur complement (:func:`_newton_step`, by
:func:`_dense_solve`) instead of the whole ``2n x 2n`` system. Results agree with the
whole-Jacobian Python loop to ~1e-12 (rounding of the solve and of the matrix products;
tested in tests/twins/test_theory_kernels.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _pivot(lu: np.ndarray, x: np.ndarray, col: int) -> int:
    """Partial pivoting at column ``col``: the first row at or below ``col`` with the
    largest |lu[i, col]| is swapped with row ``col`` (in ``lu`` and ``x``); returns its
    index (``col`` when no swap), -1 when the column is zero there."""
    m = lu.shape[0]
    piv = col
    big = abs(lu[col, col])
    for i in range(col + 1, m):
        if abs(lu[i, col]) > big:
            big = abs(lu[i, col])
            piv = i
    if big == 0.0:
        return -1
    if piv != col:
        for j in range(m):
            lu[col, j], lu[piv, j] = lu[piv, j], lu[col, j]
        x[col], x[piv] = x[piv], x[col]
    return piv


@numba.njit(cache=True, nogil=True)
def _dense_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` by Gaussian elimination with partial pivoting, single-threaded.

    The Newton systems here are small (64-512 unknowns); a threaded BLAS ``gesv`` on a busy
    machine spent 10-100x longer waiting for its threads than computing. ``a`` is copied.
    Two pivots per pass over the rows below them: the second pivot's column is brought up
    to date first (its pivot search and row swap as one pivot at a time would do), then
    every row takes both eliminations in one sweep, ``(l_ij - f1*l_kj) - f2*l_(k+1)j`` --
    the same operations in the same order as eliminating one pivot at a time (a factor
    that is zero skips its row as there), so the same bits (tested), with half the passes
    over the matrix (1.5x faster at 128 and 256 unknowns)."""
    m = a.shape[0]
    lu = a.copy()
    x = b.copy()
    fk = np.empty(m)  # the first pivot's factor of each row below it
    k = 0
    while k < m:
        if _pivot(lu, x, k) < 0:
            x[:] = np.nan
            return x
        if k + 1 == m:
            break
        inv = 1.0 / lu[k, k]
        k1 = k + 1
        for i in range(k1, m):  # pivot k's elimination of column k + 1 only
            fac = lu[i, k] * inv
            fk[i] = fac
            if fac != 0.0:
                lu[i, k1] -= fac * lu[k, k1]
        piv = _pivot(lu, x, k1)
        if piv < 0:
            x[:] = np.nan
            return x
        fk[k1], fk[piv] = fk[piv], fk[k1]  # the row's first factor moves with it
        f = fk[k1]
        if f != 0.0:  # the second pivot's row takes the first elimination
            for j in range(k1 + 1, m):
                lu[k1, j] -= f * lu[k, j]
            x[k1] -= f * x[k]
        inv2 = 1.0 / lu[k1, k1]
        for i in range(k1 + 1, m):
            f1 = fk[i]
            f2 = lu[i, k1] * inv2
            if f1 != 0.0 and f2 != 0.0:
                for j in range(k1 + 1, m):
                    lu[i, j] = (lu[i, j] - f1 * lu[k, j]) - f2 * lu[k1, j]
                x[i] = (x[i] - f1 * x[k]) - f2 * x[k1]
            elif f1 != 0.0:
                for j in range(k1 + 1, m):
                    lu[i, j] -= f1 * lu[k, j]
                x[i] -= f1 * x[k]
            elif f2 != 0.0:
                for j in range(k1 + 1, m):
                    lu[i, j] -= f2 * lu[k1, j]
                x[i] -= f2 * x[k1]
        k += 2
    for i in range(m - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, m):
            acc -= lu[i, j] * x[j]
        x[i] = acc / lu[i, i]
    return x


#: layout of the constants vector ``c`` of :func:`newton_periodic`
C_RW, C_RP, C_N0, C_WREF, C_V0, C_XI0, C_XIY = range(7)
C_A, C_B, C_C11, C_C22, C_G, C_MU0, C_ARATIO, C_BS, C_KA, C_KS = range(7, 17)
N_CONST = 17


def pack_constants(rw: float, rp: float, n0: float, wref: float, v0: float, xi0: float,
                   xiy: float, polach: dict) -> np.ndarray:
    """The constants of :func:`newton_periodic`.

    Parameters
    ----------
    rw : float
        Wheel radius [m].
    rp : float
        Platform radius [m].
    n0 : float
        Normal load [N].
    wref : float
        The platform's set speed [rad/s].
    v0 : float
        Rolling speed [m/s].
    xi0 : float
        Steady creepage [-].
    xiy : float
        Lateral creepage [-].
    polach : dict
        The Polach parameters (``ContactParams.polach_kwargs()``).

    Returns
    -------
    ndarray
        The packed constants.
    """
    c = np.empty(N_CONST)
    c[:7] = rw, rp, n0, wref, v0, xi0, xiy
    c[7:] = (polach["a_m"], polach["b_m"], polach["c11"], polach["c22"],
             polach["shear_modulus_pa"], polach["mu0"], polach["a_ratio"], polach["b_s_m"],
             polach["k_a"], polach["k_s"])
    return c


@numba.njit(cache=True, nogil=True)
def _fx(xi_x, v, c):
    """Longitudinal Polach force [N] at creepage ``xi_x`` (lateral ``c[C_XIY]``) and rolling
    speed ``v`` [m/s]: :func:`torquemod.analysis.contact.polach.creep_force`'s ``F_x``, operation
    for
    operation (0 at zero or undefined total creepage, as its ``where``)."""
    xi_y = c[C_XIY]
    xi = math.hypot(xi_x, xi_y)
    if not xi > 0.0:
        return 0.0
    mu = c[C_MU0] * ((1.0 - c[C_ARATIO]) * math.exp(-c[C_BS] * abs(xi * v)) + c[C_ARATIO])
    cjj = math.hypot(c[C_C11] * xi_x / xi, c[C_C22] * xi_y / xi)
    eps = (np.pi * c[C_G] * c[C_A] * c[C_B] * cjj * abs(xi)
           / (4.0 * c[C_N0] * mu))
    ke = c[C_KA] * eps
    f = c[C_N0] * mu * ((2.0 / np.pi) * (ke / (1.0 + ke * ke) + math.atan(c[C_KS] * eps)))
    return f * xi_x / xi


@numba.njit(cache=True, nogil=True)
def _force(u, w, du, dw, c, out):
    """``out[i] = F_x`` at wheel deviation ``u[i] + du`` and platform deviation
    ``w[i] + dw`` [rad/s] (theory.py's ``force``)."""
    rw, rp, wref = c[C_RW], c[C_RP], c[C_WREF]
    base = c[C_V0] * c[C_XI0]
    for i in range(out.size):
        ui, wi = u[i] + du, w[i] + dw
        v = (wref + wi) * rp
        # w*R_w - V = V0*xi0 + u*R_w - w*R_p: keeps the digits of small creepages
        out[i] = _fx((base + ui * rw - wi * rp) / v, v, c)


@numba.njit(cache=True, nogil=True)
def orbit_forces(x, platform, n, c, hu):
    """The converged orbit's creepage and the force on either side of it: ``xi`` [-] at
    ``x`` and ``F_x`` [N] at wheel deviations ``u +- hu`` [rad/s] (``x`` as in
    :func:`newton_periodic`). Returns ``(xi, f_plus, f_minus)``."""
    u = x[:n]
    w = x[n:] if platform else np.zeros(n)
    rw, rp, wref = c[C_RW], c[C_RP], c[C_WREF]
    base = c[C_V0] * c[C_XI0]
    xi = np.empty(n)
    for i in range(n):
        xi[i] = (base + u[i] * rw - w[i] * rp) / ((wref + w[i]) * rp)
    f_plus, f_minus = np.empty(n), np.empty(n)
    _force(u, w, hu, 0.0, c, f_plus)
    _force(u, w, -hu, 0.0, c, f_minus)
    return xi, f_plus, f_minus


@numba.njit(cache=True, nogil=True)
def _residual(x, amp, dc, sine, lin_w, p_op, platform, n, c, fx, r):
    """The collocation residual ``r`` (``r1``, then ``r2`` with the platform) at ``x``."""
    u = x[:n]
    w = x[n:] if platform else np.zeros(n)
    _force(u, w, 0.0, 0.0, c, fx)
    rw = c[C_RW]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += lin_w[i, j] * u[j]
        r[i] = acc - (dc + amp * sine[i]) + rw * fx[i]
    if platform:
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += p_op[i, j] * fx[j]
            r[n + i] = w[i] - acc


@numba.njit(cache=True, nogil=True)
def _force_slopes(x, platform, n, c, fu, fw):
    """Central differences of the force at ``x`` into ``fu = dF_x/du`` and (with the
    platform) ``fw = dF_x/dw`` [N*s/rad], steps ``1e-7*(1 + max|u|)`` and
    ``1e-7*(1e-3 + max|w|)`` [rad/s]."""
    u = x[:n]
    w = x[n:] if platform else np.zeros(n)
    hu = 1e-7 * (1.0 + np.abs(u).max())
    fp, fm = np.empty(n), np.empty(n)
    _force(u, w, hu, 0.0, c, fp)
    _force(u, w, -hu, 0.0, c, fm)
    for i in range(n):
        fu[i] = (fp[i] - fm[i]) / (2.0 * hu)
    if not platform:
        return
    hw = 1e-7 * (1e-3 + np.abs(w).max())
    _force(u, w, 0.0, hw, c, fp)
    _force(u, w, 0.0, -hw, c, fm)
    for i in range(n):
        fw[i] = (fp[i] - fm[i]) / (2.0 * hw)


@numba.njit(cache=True, nogil=True)
def _newton_step(r, lin_w, p_op, pl, platform, n, c, fu, fw, s):
    """Newton step ``dx`` with ``J dx = -r`` for the Jacobian of :func:`_residual`::

        J = [[L + R_w Fu,  R_w Fw    ],     Fu = diag(dF_x/du), Fw = diag(dF_x/dw)
             [-P Fu,       I - P Fw  ]]

    Without the platform ``J = L + R_w Fu`` is solved as it stands. With it, the second
    block row plus ``P/R_w`` times the first is ``(P L/R_w) du + dw = -r2 - P r1/R_w``
    (the platform equation is linear in the force, so the force drops out of that
    combination), which gives ``dw`` from ``du`` and leaves the ``n x n`` Schur
    complement ``(L + R_w Fu - Fw P L) du = -r1 - R_w Fw (-r2 - P r1/R_w)``: the same
    step as the ``2n x 2n`` system up to rounding, at an eighth of the elimination's
    operations. ``pl`` is the circulant ``P L``; ``s`` an ``n x n`` work array."""
    rw = c[C_RW]
    if not platform:
        for i in range(n):
            for j in range(n):
                s[i, j] = lin_w[i, j]
            s[i, i] += rw * fu[i]
        return _dense_solve(s, -r)
    b2 = np.empty(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += p_op[i, j] * r[j]
        b2[i] = -r[n + i] - acc / rw
    rhs = np.empty(n)
    for i in range(n):
        for j in range(n):
            s[i, j] = lin_w[i, j] - fw[i] * pl[i, j]
        s[i, i] += rw * fu[i]
        rhs[i] = -r[i] - rw * fw[i] * b2[i]
    du = _dense_solve(s, rhs)
    dx = np.empty(2 * n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += pl[i, j] * du[j]
        dx[i] = du[i]
        dx[n + i] = b2[i] - acc / rw
    return dx


@numba.njit(cache=True, nogil=True)
def _norm(r):
    acc = 0.0
    for v in r:
        acc += v * v
    return math.sqrt(acc)


@numba.njit(cache=True, nogil=True)
def newton_periodic(x, amp, dc, sine, lin_w, p_op, pl, platform, n, c, rtol, max_iter):
    """Newton-Raphson on the collocation equations from ``x`` (length ``n``, or ``2n`` with
    the platform) at modulation amplitude ``amp`` [N*m] on ``dc`` [N*m]; ``sine`` the unit
    drive at the collocation instants, ``lin_w``, ``p_op`` and ``pl = p_op @ lin_w`` the
    circulant operators, ``c`` :func:`pack_constants`. Each step solves the Jacobian's
    ``n x n`` Schur complement (:func:`_newton_step`). Converged when the last step's
    largest wheel-speed change is at most ``rtol`` of the largest wheel-speed deviation;
    each step is halved (down to 1e-4) until the residual norm falls. Returns
    ``(x, iterations, converged)``."""
    m = x.size
    fx = np.empty(n)
    r = np.empty(m)
    rn = np.empty(m)
    fu, fw = np.empty(n), np.empty(n)
    s = np.empty((n, n))
    _residual(x, amp, dc, sine, lin_w, p_op, platform, n, c, fx, r)
    norm = _norm(r)
    for it in range(1, max_iter + 1):
        _force_slopes(x, platform, n, c, fu, fw)
        dx = _newton_step(r, lin_w, p_op, pl, platform, n, c, fu, fw, s)
        if not np.all(np.isfinite(dx)):
            return x, it, False
        small = np.abs(dx[:n]).max() <= rtol * max(np.abs(x[:n]).max(), 1e-9)
        lam = 1.0
        while True:  # backtracking on the residual norm
            xn = x + lam * dx
            _residual(xn, amp, dc, sine, lin_w, p_op, platform, n, c, fx, rn)
            nn = _norm(rn)
            if np.isfinite(nn) and (nn < norm or small):
                break
            lam *= 0.5
            if lam < 1e-4:
                return x, it, False
        x = xn
        r, rn = rn, r
        norm = nn
        if small:
            return x, it, True
    return x, max_iter, False
