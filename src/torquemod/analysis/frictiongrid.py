"""The chi-square grid behind :mod:`torquemod.analysis.friction`: for every pair of
neighbouring members of the creep-law family and every trial available adhesion P, the
weighted least-squares fit of a mixture of the pair to the observations, and the
coarse-to-fine pass that evaluates only the trial P where the profile's 95 % level is
decided (profile likelihood, Wilks 1938). Pure numerics, compiled with numba; the model,
the estimand and the interval rule are documented in :mod:`torquemod.analysis.friction`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from torquemod.analysis.creeplaws import N_U_SWING, SWING_A

__all__ = ["CHI2_95", "K0_GRID"]

#: chi-square quantile of one degree of freedom at 95 %
CHI2_95 = 3.841458820694124
#: k0 values [-] profiled when the swing is given without C
K0_GRID = np.geomspace(3.0, 3000.0, 19)


@njit(cache=True, nogil=True)
def _solve_pair(saa, sab, sbb, say, sby, distinct):
    """``alpha, beta >= 0`` minimising the weighted squares of ``y - alpha*g_a - beta*g_b``
    from the sums of the normal equations: Cramer's rule when the solution is feasible and
    the pair not (nearly) collinear, else the better single member."""
    det = saa * sbb - sab * sab
    al = -1.0
    be = -1.0
    if distinct and det > 1e-12 * saa * sbb:
        al = (sbb * say - sab * sby) / det
        be = (saa * sby - sab * say) / det
    if not (al >= 0.0 and be >= 0.0):
        # the best single member: chi2 = syy - say^2/saa (syy common)
        if say * say / saa >= sby * sby / sbb:
            al = say / saa
            be = 0.0
        else:
            al = 0.0
            be = sby / sbb
    return al, be


@njit(cache=True, nogil=True)
def _chi_kernel(sd_tab, sw_head, sw_tab, swing_a, f_peak, pairs, coa, y, var0, y_rel,
                coa_se, amp, p_grid, k_scale, k0_fixed, n_iter, beta_h, bmax_v):
    """For every pair (a, b) of neighbouring members and trial P: the weighted least squares
    ``y ~ alpha*s_a + beta*s_b`` with alpha, beta >= 0 (a mixture of the pair; a single
    member when one is 0). Returns chi2, ``alpha + beta`` (the amplitude: k0 in the units
    of y) and ``beta/(alpha + beta)``, each (K, M). ``amp``: the creepage swing per point
    (zeros: none); k0 = ``k_scale*(alpha + beta)`` when k_scale > 0, else ``k0_fixed``.
    With ``bmax_v`` > 0 (B_max*V [-]) a pair whose falling-friction member needs
    ``B = beta_h*k0/(mu0*V)`` above B_max (``beta_h`` = beta/h0 per member) is left out
    (before its fit when k0 is fixed). ``sd_tab``, ``sw_head``: the tables as laid out by
    :func:`_layout`; ``sw_tab`` the whole swing table."""
    n_s, n_u = sd_tab.shape[0], sd_tab.shape[1]
    n_h = sw_head.shape[2]
    n_q = pairs.shape[0]
    n_m = p_grid.size
    n = coa.size
    chi = np.full((n_q, n_m), np.inf)
    amps = np.full((n_q, n_m), np.nan)
    fracs = np.full((n_q, n_m), np.nan)
    used = np.zeros(n_s, np.bool_)
    for q in range(n_q):
        used[pairs[q, 0]] = True
        used[pairs[q, 1]] = True
    G = np.empty((n_s, n))
    DG = np.empty((n_s, n))
    valid = np.empty(n_s, np.bool_)
    s_gg = np.empty(n_s)
    s_gy = np.empty(n_s)
    k_top = np.empty(n_s)
    al_q = np.empty(n_q)
    be_q = np.empty(n_q)
    live = np.zeros(n_q, np.bool_)
    ga = np.empty(n)
    gb = np.empty(n)
    w = np.empty(n)
    # the variance without the CoA term (and its weight), the same for every pair and P
    v0 = np.empty(n)
    w0 = np.empty(n)
    for i in range(n):
        v0[i] = var0[i] + (y_rel * y[i]) ** 2
        w0[i] = 1.0 / v0[i]
    has_swing = sw_tab.shape[0] > 0
    n_a = swing_a.size
    n_us = sw_tab.shape[1]
    a_top = swing_a[n_a - 1]
    ks = np.empty(n, np.int64)
    fs = np.empty(n)
    ku = np.empty(n, np.int64)
    fu = np.empty(n)
    # every member's swing rows interpolated at the points' utilisations (SW[s, i, :]),
    # filled per trial P only up to the largest swing its pairs reach (``top``)
    SW = np.empty((sw_tab.shape[0], n, n_a))
    top = np.zeros((sw_tab.shape[0], n), np.int64)
    c_max = coa.max()
    check_b = bmax_v > 0.0
    for m in range(n_m):
        p = p_grid[m]
        if c_max >= p:
            continue
        for i in range(n):
            pos = coa[i] / p * (n_us - 1)
            k = min(int(pos), n_us - 2)
            ks[i] = k
            fs[i] = pos - k
            pos = coa[i] / p * (n_u - 1)
            k = min(int(pos), n_u - 2)
            ku[i] = k
            fu[i] = pos - k
        for s in range(n_s):
            valid[s] = used[s]
            if not used[s]:
                continue
            for i in range(n):
                k = ku[i]
                f = fu[i]
                G[s, i] = sd_tab[s, k, 0] * (1.0 - f) + sd_tab[s, k + 1, 0] * f
                DG[s, i] = sd_tab[s, k, 1] * (1.0 - f) + sd_tab[s, k + 1, 1] * f
                if not (G[s, i] > 0.0):
                    valid[s] = False
                    break
            if not valid[s]:
                continue
            gg = 0.0
            gy = 0.0
            for i in range(n):
                gg += w0[i] * G[s, i] * G[s, i]
                gy += w0[i] * G[s, i] * y[i]
            s_gg[s] = gg
            s_gy[s] = gy
            if has_swing:
                for i in range(n):
                    top[s, i] = 0
        for it in range(n_iter):
            last = it == n_iter - 1
            swing_now = has_swing and it > 0
            if swing_now:
                # the largest k0 among each member's pairs, and the swing rows up to it
                for s in range(n_s):
                    k_top[s] = 0.0
                for q in range(n_q):
                    if live[q]:
                        k0 = k_scale * (al_q[q] + be_q[q]) if k_scale > 0.0 else k0_fixed
                        k_top[pairs[q, 0]] = max(k_top[pairs[q, 0]], k0)
                        k_top[pairs[q, 1]] = max(k_top[pairs[q, 1]], k0)
                for s in range(n_s):
                    if not (valid[s] and k_top[s] > 0.0):
                        continue
                    for i in range(n):
                        if not amp[i] > 0.0:
                            continue
                        red = min(amp[i] * k_top[s] * f_peak[s] / p, a_top)
                        j = 0
                        while j < n_a - 2 and swing_a[j + 1] < red:
                            j += 1
                        k = ks[i]
                        f = fs[i]
                        for jj in range(top[s, i], j + 2):
                            if jj < n_h:
                                SW[s, i, jj] = (sw_head[s, k, jj] * (1 - f)
                                                + sw_head[s, k + 1, jj] * f)
                            else:
                                SW[s, i, jj] = (sw_tab[s, k, jj] * (1 - f)
                                                + sw_tab[s, k + 1, jj] * f)
                        top[s, i] = max(top[s, i], j + 2)
            for q in range(n_q):
                a = pairs[q, 0]
                b = pairs[q, 1]
                if it == 0:
                    live[q] = False
                    if not (valid[a] and valid[b]):
                        continue
                    if check_b and not k_scale > 0.0 and (
                            beta_h[a] * k0_fixed * f_peak[a] > bmax_v * p
                            or beta_h[b] * k0_fixed * f_peak[b] > bmax_v * p):
                        # k0 fixed: the test after the fit, the same whatever the fit
                        continue
                    # the first fit: no swing, the weights without the CoA term
                    sab = 0.0
                    for i in range(n):
                        sab += w0[i] * G[a, i] * G[b, i]
                    al, be = _solve_pair(s_gg[a], sab, s_gg[b], s_gy[a], s_gy[b], a != b)
                    if last:
                        for i in range(n):
                            ga[i] = G[a, i]
                            gb[i] = G[b, i]
                            w[i] = w0[i]
                else:
                    if not live[q]:
                        continue
                    al = al_q[q]
                    be = be_q[q]
                    k0 = k_scale * (al + be) if k_scale > 0.0 else k0_fixed
                    saa = 0.0
                    sab = 0.0
                    sbb = 0.0
                    say = 0.0
                    sby = 0.0
                    for i in range(n):
                        ga[i] = G[a, i]
                        gb[i] = G[b, i]
                        if swing_now and amp[i] > 0.0:
                            red = min(amp[i] * k0 * f_peak[a] / p, a_top)
                            j = 0
                            while j < n_a - 2 and swing_a[j + 1] < red:
                                j += 1
                            fa = (red - swing_a[j]) / (swing_a[j + 1] - swing_a[j])
                            ga[i] += SW[a, i, j] * (1 - fa) + SW[a, i, j + 1] * fa
                            red = min(amp[i] * k0 * f_peak[b] / p, a_top)
                            j = 0
                            while j < n_a - 2 and swing_a[j + 1] < red:
                                j += 1
                            fa = (red - swing_a[j]) / (swing_a[j + 1] - swing_a[j])
                            gb[i] += SW[b, i, j] * (1 - fa) + SW[b, i, j + 1] * fa
                        v = v0[i] + ((al * DG[a, i] + be * DG[b, i]) / p * coa_se[i]) ** 2
                        w[i] = 1.0 / v
                        saa += w[i] * ga[i] * ga[i]
                        sab += w[i] * ga[i] * gb[i]
                        sbb += w[i] * gb[i] * gb[i]
                        say += w[i] * ga[i] * y[i]
                        sby += w[i] * gb[i] * y[i]
                    al, be = _solve_pair(saa, sab, sbb, say, sby, a != b)
                live[q] = False
                if not (al + be > 0.0):
                    continue
                if not last:
                    al_q[q] = al
                    be_q[q] = be
                    live[q] = True
                    continue
                if check_b:
                    k0 = k_scale * (al + be) if k_scale > 0.0 else k0_fixed
                    if (beta_h[a] * k0 * f_peak[a] > bmax_v * p
                            or beta_h[b] * k0 * f_peak[b] > bmax_v * p):
                        continue
                c = 0.0
                for i in range(n):
                    r = y[i] - al * ga[i] - be * gb[i]
                    c += w[i] * r * r
                if math.isfinite(c):
                    chi[q, m] = c
                    amps[q, m] = al + be
                    fracs[q, m] = be / (al + be)
    return chi, amps, fracs


_LAYOUTS: dict = {}
#: the swing amplitudes kept apart for the lookups (:func:`_layout`)
SWING_HEAD = 6
#: the swing table of a family without one
_NO_SWING = np.zeros((0, N_U_SWING, SWING_A.size))


def _layout(s: np.ndarray, ds: np.ndarray, sw: np.ndarray) -> tuple:
    """The tables as the kernel reads them, built once per table (kept while it lives):
    ``s`` and ``ds`` interleaved (S, N_U, 2) so that a point's slope and its derivative share
    a cache line; the first :data:`SWING_HEAD` swing amplitudes apart (S, N_U_SWING, head),
    the ones nearly every lookup uses (a third of the table) [-]."""
    key = (id(s), id(ds), id(sw))
    hit = _LAYOUTS.get(key)
    if hit is None or hit[0] is not s or hit[1] is not ds or hit[2] is not sw:
        sd = np.ascontiguousarray(np.stack([s, ds], axis=-1))
        head = np.ascontiguousarray(sw[:, :, :SWING_HEAD])
        hit = (s, ds, sw, sd, head)
        while len(_LAYOUTS) >= 4:
            _LAYOUTS.pop(next(iter(_LAYOUTS)))
        _LAYOUTS[key] = hit
    return hit[3], hit[4]


def _chi_grid(s, ds, sw, swing_a, f_peak, pairs, coa, y, var0, y_rel, coa_se, amp, p_grid,
              k_scale, k0_fixed, n_iter, beta_h, bmax_v):
    """:func:`_chi_kernel` on the family's tables as :class:`~torquemod.analysis.creeplaws.
    FamilyTables` holds them (``s``, ``ds`` (S, N_U); ``sw`` (S, N_U_SWING, A), or (0, *, *)
    without swing)."""
    sd, head = _layout(s, ds, sw)
    return _chi_kernel(sd, head, sw, swing_a, f_peak, pairs, coa, y, var0, y_rel, coa_se,
                       amp, p_grid, k_scale, k0_fixed, n_iter, beta_h, bmax_v)


def _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid, constant, model_rel, bmax_v=0.0):
    """chi2, amplitudes and mixing fractions (K, M) (:func:`_chi_kernel`), profiling k0 over
    :data:`K0_GRID` when a swing is given without C."""
    sw = tabs.swing if tabs.swing is not None else _NO_SWING
    var0 = se * se
    n_iter = 3 if sw.shape[0] else (2 if np.any(c_se > 0) else 1)
    if sw.shape[0] == 0 or (constant is not None and constant > 0):
        k_scale = float(constant) if constant is not None and constant > 0 else 1.0
        return _chi_grid(tabs.s, tabs.ds, sw, SWING_A, tabs.f_peak, pairs,
                           coa, y, var0, model_rel, c_se, amp, p_grid, k_scale, 0.0, n_iter,
                           tabs.beta_h,
                           bmax_v if constant is not None and constant > 0 else 0.0)
    best = None
    for k0 in K0_GRID:
        out = _chi_grid(tabs.s, tabs.ds, sw, SWING_A, tabs.f_peak, pairs,
                          coa, y, var0, model_rel, c_se, amp, p_grid, -1.0, float(k0),
                          n_iter, tabs.beta_h, bmax_v)
        if best is None:
            best = out
        else:
            better = out[0] < best[0]
            best = tuple(np.where(better, o, b) for o, b in zip(out, best, strict=True))
    return best


def _coarse_to_fine(tabs, pairs, coa, y, se, c_se, amp, p_grid, constant, model_rel,
                    bmax_v: float = 0.0, every: int = 3, rounds: int = 5):
    """:func:`_chi_all` on every ``every``-th trial P, then on every grid point between two
    evaluated neighbours where the profile crosses the 95 % level, comes near it from
    outside, or that hold its minimum, until no such gap is left (the level follows the lowest
    chi2 found). Returns the
    evaluated grid indices (sorted) and chi2, amplitude, mixing fraction there (K, m)."""
    m = p_grid.size
    done = np.unique(np.r_[np.arange(0, m, every), m - 1])
    first = _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid[done], constant, model_rel,
                     bmax_v)
    # every trial P's columns, filled as they are evaluated (a cell is the same whichever
    # call computes it); ``have`` marks the evaluated ones
    full = [np.empty((o.shape[0], m), o.dtype) for o in first]
    for f_, o in zip(full, first, strict=True):
        f_[:, done] = o
    have = np.zeros(m, bool)
    have[done] = True
    outs = list(first)
    dof = max(coa.size - 3, 1)
    for _ in range(rounds):
        prof = outs[0].min(axis=0)
        if not np.isfinite(prof).any():
            break
        c_min = float(np.min(prof))
        level = c_min + CHI2_95 * max(1.0, c_min / dof)
        j = int(np.argmin(prof))
        ins = prof <= level
        near = prof <= level + 2.0 * CHI2_95 * max(1.0, c_min / dof)
        gaps = np.flatnonzero(np.diff(done) > 1)
        need = [g for g in gaps if (ins[g] != ins[g + 1]) or (near[g] and not ins[g])
                or (near[g + 1] and not ins[g + 1]) or g in (j - 1, j)]
        if not need:
            break
        new = np.concatenate([np.arange(done[g] + 1, done[g + 1]) for g in need])
        more = _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid[new], constant, model_rel,
                        bmax_v)
        for f_, o in zip(full, more, strict=True):
            f_[:, new] = o
        have[new] = True
        done = np.flatnonzero(have)
        outs = [f_[:, done] for f_ in full]
    return done, outs
