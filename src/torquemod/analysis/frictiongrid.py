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

__all__ = ["CHI2_95", "K0_GRID", "NEW_MEMBER_MARGIN", "new_pairs", "reference_chi2",
           "row_minima"]

#: chi-square quantile of one degree of freedom at 95 %
CHI2_95 = 3.841458820694124
#: chi2 margin [-] by which the members no rail law needs (:func:`new_pairs`) must beat the
#: others' best fit before they set the level and the estimate; below it they only widen
#: the interval (:func:`reference_chi2`)
NEW_MEMBER_MARGIN = 10.0
#: k0 values [-] profiled when the swing is given without C
K0_GRID = np.geomspace(3.0, 3000.0, 19)


def new_pairs(tabs, pairs) -> np.ndarray:
    """Which pairs hold a member that no rail law needs
    (:attr:`~torquemod.analysis.creeplaws.Member.beyond_rail_laws`: the knee members and the
    saturation tail at p = 1 with q > 1.5; Dugoff's and the hyperbolic law).

    Parameters
    ----------
    tabs : FamilyTables
        The family's tables (:func:`torquemod.analysis.creeplaws.family_tables`).
    pairs : ndarray of int, shape (K, 2)
        Member indices of the pairs.

    Returns
    -------
    ndarray of bool, shape (K,)
        True where a pair holds such a member.
    """
    new = np.array([m.beyond_rail_laws for m in tabs.members])
    return new[pairs[:, 0]] | new[pairs[:, 1]]


def reference_chi2(chi_all: float, chi_rail: float,
                   margin: float | None = None) -> tuple[float, bool]:
    """The reference chi2 [-] of the 95 % level, and whether the rail members alone give it
    (and the estimate).

    The "widen-only" rule: the new members (:func:`new_pairs`) fit the noise of some records
    better than the rail members (rig Polach and train magic formula at 86 %: chi2 lower by
    4.2-9.5 where they alone were kept, "determined" 21-66 % high), while on the records of
    their own laws they win by 0-11 (hyperbolic) and 4.8-115 (Dugoff), on Polach,
    exponential and Burckhardt records by exactly 0 (docs/friction.md). Unless they beat the
    rail members by more than ``margin`` (:data:`NEW_MEMBER_MARGIN`, 10: above the wrong
    records' differences), the rail members' best ``chi_rail`` is the reference, so they
    can widen the interval but not narrow it or take the estimate.

    Parameters
    ----------
    chi_all : float
        The whole family's smallest chi2 [-].
    chi_rail : float
        The smallest chi2 of the pairs without a new member [-] (inf when none).
    margin : float, optional
        The margin [-]; default :data:`NEW_MEMBER_MARGIN` (read at call time).

    Returns
    -------
    chi_ref : float
        The reference chi2 [-].
    rail_only : bool
        True when ``chi_ref`` is ``chi_rail`` (estimate from the rail members).
    """
    margin = NEW_MEMBER_MARGIN if margin is None else margin
    if math.isfinite(chi_rail) and not chi_all < chi_rail - margin:
        return float(chi_rail), True
    return float(chi_all), False


def row_minima(chi_t: np.ndarray, pairs_in: np.ndarray) -> np.ndarray:
    """Each trial P's smallest chi2 over the pairs marked in ``pairs_in``.

    Parameters
    ----------
    chi_t : ndarray, shape (M, K)
        chi2 [-] per trial P (rows) and pair (columns).
    pairs_in : ndarray of bool, shape (K,)
        The pairs taken.

    Returns
    -------
    ndarray, shape (M,)
        The minima [-]; inf where no pair is taken.
    """
    if not pairs_in.any():
        return np.full(chi_t.shape[0], np.inf)
    return chi_t[:, pairs_in].min(axis=1)


@njit(cache=True, nogil=True, error_model="numpy")
def _chi_kernel(s_t, ds_t, sw_t, swing_a, f_peak, pairs, coa, y, var0, y_rel, coa_se,
                amp, p_grid, k_scale, k0_fixed, n_iter, beta_h, bmax_v):
    """For every pair (a, b) of neighbouring members and trial P: the weighted least squares
    ``y ~ alpha*s_a + beta*s_b`` with alpha, beta >= 0 (a mixture of the pair; a single
    member when one is 0). Returns chi2, ``alpha + beta`` (the amplitude: k0 in the units
    of y) and ``beta/(alpha + beta)``, each (K, M) (transposed views of trial-P-major
    arrays: a trial P's column is contiguous). ``amp``: the creepage swing per point
    (zeros: none); k0 = ``k_scale*(alpha + beta)`` when k_scale > 0, else ``k0_fixed``.
    With ``bmax_v`` > 0 (B_max*V [-]) a pair whose falling-friction member needs
    ``B = beta_h*k0/(mu0*V)`` above B_max (``beta_h`` = beta/h0 per member) is left out.

    The tables are utilisation-major (:class:`~torquemod.analysis.creeplaws.FamilyTables`
    ``s_t``, ``ds_t``, ``swing_t``; a swing table with no member means no swing): each
    trial P interpolates every member at each point's utilisation, reading one contiguous
    block per point (the swing rows, on the rising grid ``swing_a``, only up to the largest
    swing a refit can reach there: a bound from the largest k0 and peak). The first pass's
    weights do not depend on the pair, so each member's own sums in it are formed once per
    trial P. Each pair's two members are then copied into contiguous rows, once per trial P, and
    the pairs advance together, point by point, in loops over the pairs that the compiler
    turns into vector instructions (the table lookups that depend on a pair's fit are
    gathered in loops of their own); every pair's arithmetic is the same, in the same
    order, as a pair fitted alone (a pair whose fit stops early is carried along and left
    out at the end)."""
    n_u, n_s = s_t.shape
    n_q = pairs.shape[0]
    n_m = p_grid.size
    n = coa.size
    # trial-P-major: a trial P's cells are written together and returned as one column
    chi = np.full((n_m, n_q), np.inf)
    amps = np.full((n_m, n_q), np.nan)
    fracs = np.full((n_m, n_q), np.nan)
    G = np.empty((n, n_s))
    DG = np.empty((n, n_s))
    valid = np.empty(n_s, np.bool_)
    s_gg = np.empty(n_s)
    s_gy = np.empty(n_s)
    v0 = np.empty(n)
    w0 = np.empty(n)
    for i in range(n):
        v0[i] = var0[i] + (y_rel * y[i]) ** 2
        w0[i] = 1.0 / v0[i]
    has_swing = sw_t.shape[1] > 0
    n_a = swing_a.size
    n_us = sw_t.shape[0]
    a_top = swing_a[n_a - 1]
    # the widths of the swing grid's cells (the same subtraction as in a lookup); the
    # largest peak F_pk of the members (for the bound on the swing)
    d_a = np.empty(n_a)
    for j in range(n_a - 1):
        d_a[j] = swing_a[j + 1] - swing_a[j]
    n_sw = np.zeros(n, np.int64)
    s_lo = swing_a[0]
    d_lo = d_a[0]
    f_top = 0.0
    for s in range(n_s):
        if f_peak[s] > f_top:
            f_top = f_peak[s]
    ks = np.empty(n, np.int64)
    fs = np.empty(n)
    ku = np.empty(n, np.int64)
    fu = np.empty(n)
    # per trial P: each point's cell of both utilisation grids, every member interpolated
    # there (G, DG: point-major), and every valid member's swing rows (SW[i, s*n_a + j]); a
    # pair's swing lookup is then linear in the swing alone (the arithmetic of one bilinear
    # lookup)
    SW = np.empty((n, sw_t.shape[1] * n_a))
    # per pair (compacted to the pairs of valid members of a trial P): the pair, its fit so
    # far and its sums; G0A, G0B, D0A, D0B its members' s and ds/du at each point (copied
    # once per trial P); GA, GB, W the last pass's curves and weights at each point; the
    # rest scratch rows, one value per pair
    qi = np.empty(n_q, np.int64)
    A = np.empty(n_q, np.int64)
    B = np.empty(n_q, np.int64)
    AL = np.empty(n_q)
    BE = np.empty(n_q)
    K0 = np.empty(n_q)
    FA = np.empty(n_q)
    FB = np.empty(n_q)
    LIVE = np.empty(n_q, np.bool_)
    SAA = np.empty(n_q)
    SAB = np.empty(n_q)
    SBB = np.empty(n_q)
    SAY = np.empty(n_q)
    SBY = np.empty(n_q)
    # per pair, contiguous: the members' values at each point (gathered once per trial P)
    G0A = np.empty((n, n_q))
    G0B = np.empty((n, n_q))
    D0A = np.empty((n, n_q))
    D0B = np.empty((n, n_q))
    GA = np.empty((n, n_q))
    GB = np.empty((n, n_q))
    W = np.empty((n, n_q))
    RA = np.empty(n_q)
    RB = np.empty(n_q)
    JA = np.empty(n_q, np.int64)
    JB = np.empty(n_q, np.int64)
    C = np.empty(n_q)
    S0A = np.empty(n_q)
    S1A = np.empty(n_q)
    S0B = np.empty(n_q)
    S1B = np.empty(n_q)
    W0A = np.empty(n_q)
    W1A = np.empty(n_q)
    W0B = np.empty(n_q)
    W1B = np.empty(n_q)
    c_max = coa.max()
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
            valid[s] = True
        for i in range(n):
            k = ku[i]
            f = fu[i]
            for s in range(n_s):
                g = s_t[k, s] * (1.0 - f) + s_t[k + 1, s] * f
                G[i, s] = g
                DG[i, s] = ds_t[k, s] * (1.0 - f) + ds_t[k + 1, s] * f
                if not (g > 0.0):
                    valid[s] = False
        for s in range(n_s):
            if valid[s]:
                sgg = 0.0
                sgy = 0.0
                for i in range(n):
                    sgg += w0[i] * G[i, s] * G[i, s]
                    sgy += w0[i] * G[i, s] * y[i]
                s_gg[s] = sgg
                s_gy[s] = sgy
        # no swing row interpolated yet at this trial P (n_sw: how many of each point's)
        for i in range(n):
            n_sw[i] = 0
        # the pairs of valid members, in order
        nv = 0
        for q in range(n_q):
            a = pairs[q, 0]
            b = pairs[q, 1]
            if valid[a] and valid[b]:
                qi[nv] = q
                A[nv] = a
                B[nv] = b
                FA[nv] = f_peak[a]
                FB[nv] = f_peak[b]
                LIVE[nv] = True
                nv += 1
        for i in range(n):
            for v in range(nv):
                G0A[i, v] = G[i, A[v]]
                G0B[i, v] = G[i, B[v]]
            if n_iter > 1:
                for v in range(nv):
                    D0A[i, v] = DG[i, A[v]]
                    D0B[i, v] = DG[i, B[v]]
        for it in range(n_iter):
            last = it == n_iter - 1
            if it == 0:
                # fixed weights 1/v0 and no swing: the members' own sums, and the cross sum
                for v in range(nv):
                    SAA[v] = s_gg[A[v]]
                    SBB[v] = s_gg[B[v]]
                    SAY[v] = s_gy[A[v]]
                    SBY[v] = s_gy[B[v]]
                    SAB[v] = 0.0
                for i in range(n):
                    wi = w0[i]
                    for v in range(nv):
                        SAB[v] += wi * G0A[i, v] * G0B[i, v]
                if last:
                    for i in range(n):
                        wi = w0[i]
                        for v in range(nv):
                            GA[i, v] = G0A[i, v]
                            GB[i, v] = G0B[i, v]
                            W[i, v] = wi
            else:
                for v in range(nv):
                    K0[v] = k_scale * (AL[v] + BE[v]) if k_scale > 0.0 else k0_fixed
                    SAA[v] = 0.0
                    SAB[v] = 0.0
                    SBB[v] = 0.0
                    SAY[v] = 0.0
                    SBY[v] = 0.0
                # the largest k0 (NaN left out: its swing's cell is the first)
                k0_top = 0.0
                for v in range(nv):
                    if K0[v] > k0_top:
                        k0_top = K0[v]
                for i in range(n):
                    gai = GA[i]
                    gbi = GB[i]
                    if has_swing and amp[i] > 0.0:
                        ai = amp[i]
                        for v in range(nv):
                            RA[v] = min(ai * K0[v] * FA[v] / p, a_top)
                            RB[v] = min(ai * K0[v] * FB[v] / p, a_top)
                            JA[v] = 0
                            JB[v] = 0
                            S0A[v] = s_lo
                            S1A[v] = d_lo
                            S0B[v] = s_lo
                            S1B[v] = d_lo
                        # no pair's swing exceeds this bound (the same products and
                        # quotient of values at least as large, each rounded
                        # monotonically), so no swing lies above a grid value it does not
                        # exceed: cells beyond t_top are neither searched nor interpolated
                        r_top = min(ai * k0_top * f_top / p, a_top)
                        t_top = 0
                        for t in range(1, n_a - 1):
                            if r_top > swing_a[t]:
                                t_top = t
                        j_end = t_top + 2
                        # this point's swing rows up to the cell above t_top, interpolated
                        # as the refits reach them
                        if n_sw[i] < j_end:
                            k = ks[i]
                            f = fs[i]
                            for s in range(n_s):
                                if valid[s]:
                                    for j in range(n_sw[i], j_end):
                                        SW[i, s * n_a + j] = (sw_t[k, s, j] * (1 - f)
                                                              + sw_t[k + 1, s, j] * f)
                            n_sw[i] = j_end
                        # the swing's cell: the last inner grid value below it (the grid
                        # rises, so this is how many lie below: the first cell whose upper
                        # end reaches it; 0 for NaN), with its lower end and width
                        for t in range(1, t_top + 1):
                            st = swing_a[t]
                            dt = d_a[t]
                            for v in range(nv):
                                if RA[v] > st:
                                    JA[v] = t
                                    S0A[v] = st
                                    S1A[v] = dt
                                if RB[v] > st:
                                    JB[v] = t
                                    S0B[v] = st
                                    S1B[v] = dt
                        swi = SW[i]
                        for v in range(nv):
                            ja = JA[v]
                            jb = JB[v]
                            ba = A[v] * n_a + ja
                            bb = B[v] * n_a + jb
                            W0A[v] = swi[ba]
                            W1A[v] = swi[ba + 1]
                            W0B[v] = swi[bb]
                            W1B[v] = swi[bb + 1]
                        g0a = G0A[i]
                        g0b = G0B[i]
                        for v in range(nv):
                            xa = (RA[v] - S0A[v]) / S1A[v]
                            xb = (RB[v] - S0B[v]) / S1B[v]
                            gai[v] = g0a[v] + (W0A[v] * (1 - xa) + W1A[v] * xa)
                            gbi[v] = g0b[v] + (W0B[v] * (1 - xb) + W1B[v] * xb)
                    else:
                        g0a = G0A[i]
                        g0b = G0B[i]
                        for v in range(nv):
                            gai[v] = g0a[v]
                            gbi[v] = g0b[v]
                    # the weights with the CoA term of the last fit, and the sums
                    v0i = v0[i]
                    ci = coa_se[i]
                    yi = y[i]
                    d0a = D0A[i]
                    d0b = D0B[i]
                    wi_ = W[i]
                    for v in range(nv):
                        ga = gai[v]
                        gb = gbi[v]
                        wv = 1.0 / (v0i + ((AL[v] * d0a[v] + BE[v] * d0b[v]) / p * ci) ** 2)
                        wi_[v] = wv
                        SAA[v] += wv * ga * ga
                        SAB[v] += wv * ga * gb
                        SBB[v] += wv * gb * gb
                        SAY[v] += wv * ga * yi
                        SBY[v] += wv * gb * yi
            # the nonnegative fit of each pair from its sums (closed form)
            for v in range(nv):
                saa = SAA[v]
                sab = SAB[v]
                sbb = SBB[v]
                say = SAY[v]
                sby = SBY[v]
                det = saa * sbb - sab * sab
                al = -1.0
                be = -1.0
                if A[v] != B[v] and det > 1e-12 * saa * sbb:
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
                if LIVE[v] and not (al + be > 0.0):  # no fit: the pair stops here
                    LIVE[v] = False
                AL[v] = al
                BE[v] = be
        # the last iteration's fit, of the pairs still live
        for v in range(nv):
            C[v] = 0.0
        for i in range(n):
            yi = y[i]
            gai = GA[i]
            gbi = GB[i]
            wi_ = W[i]
            for v in range(nv):
                r = yi - AL[v] * gai[v] - BE[v] * gbi[v]
                C[v] += wi_[v] * r * r
        for v in range(nv):
            if not LIVE[v]:
                continue
            al = AL[v]
            be = BE[v]
            if bmax_v > 0.0:
                k0 = k_scale * (al + be) if k_scale > 0.0 else k0_fixed
                if (beta_h[A[v]] * k0 * FA[v] > bmax_v * p
                        or beta_h[B[v]] * k0 * FB[v] > bmax_v * p):
                    continue
            c = C[v]
            if math.isfinite(c):
                q = qi[v]
                chi[m, q] = c
                amps[m, q] = al + be
                fracs[m, q] = be / (al + be)
    return chi.T, amps.T, fracs.T


def _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid, constant, model_rel, bmax_v=0.0):
    """chi2, amplitudes and mixing fractions (K, M) (:func:`_chi_kernel`), profiling k0 over
    :data:`K0_GRID` when a swing is given without C."""
    sw = tabs.swing_t if tabs.swing_t is not None else np.zeros((N_U_SWING, 0, SWING_A.size))
    var0 = se * se
    n_iter = 3 if sw.shape[1] else (2 if np.any(c_se > 0) else 1)
    if sw.shape[1] == 0 or (constant is not None and constant > 0):
        k_scale = float(constant) if constant is not None and constant > 0 else 1.0
        return _chi_kernel(tabs.s_t, tabs.ds_t, sw, SWING_A, tabs.f_peak, pairs, coa, y, var0,
                           model_rel, c_se, amp, p_grid, k_scale, 0.0, n_iter, tabs.beta_h,
                           bmax_v if constant is not None and constant > 0 else 0.0)
    best = None
    for k0 in K0_GRID:
        out = _chi_kernel(tabs.s_t, tabs.ds_t, sw, SWING_A, tabs.f_peak, pairs, coa, y, var0,
                          model_rel, c_se, amp, p_grid, -1.0, float(k0), n_iter, tabs.beta_h,
                          bmax_v)
        if best is None:
            best = out
        else:
            better = out[0] < best[0]
            best = tuple(np.where(better, o, b) for o, b in zip(out, best, strict=True))
    return best


def _coarse_to_fine(tabs, pairs, coa, y, se, c_se, amp, p_grid, constant, model_rel,
                    bmax_v: float = 0.0, every: int = 3, rounds: int = 5, rail=None):
    """:func:`_chi_all` on every ``every``-th trial P, then on every grid point between two
    evaluated neighbours where the profile crosses the 95 % level, comes near it from
    outside, or that hold its minimum (or the rail pairs' minimum), until no such gap is left
    (the level follows the lowest chi2 found, referred by :func:`reference_chi2` to the
    pairs marked in ``rail`` when given). Returns the
    evaluated grid indices (sorted) and chi2, amplitude, mixing fraction there (K, m)."""
    m = p_grid.size
    done = np.unique(np.r_[np.arange(0, m, every), m - 1])
    # the evaluated trial P's columns, batch by batch (a cell is the same whichever call
    # computes it), and the profile there; ``have`` marks the evaluated ones
    batches: list = []
    prof_all = np.full(m, np.nan)
    prof_rail = np.full(m, np.inf)
    have = np.zeros(m, bool)
    use_rail = rail is not None and bool(rail.any())

    def put(cols, out):
        batches.append((cols, out))
        chi_t = out[0].T  # trial-P-major: each trial P's row contiguous
        prof_all[cols] = chi_t.min(axis=1)
        if use_rail:
            prof_rail[cols] = row_minima(chi_t, rail)
        have[cols] = True

    put(done, _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid[done], constant, model_rel,
                       bmax_v))
    dof = max(coa.size - 3, 1)
    for _ in range(rounds):
        prof = prof_all[done]
        if not np.isfinite(prof).any():
            break
        c_min, _ = reference_chi2(float(np.min(prof)), float(np.min(prof_rail[done])))
        level = c_min + CHI2_95 * max(1.0, c_min / dof)
        j = int(np.argmin(prof))
        jr = int(np.argmin(prof_rail[done])) if rail is not None else j
        ins = prof <= level
        near = prof <= level + 2.0 * CHI2_95 * max(1.0, c_min / dof)
        gaps = np.flatnonzero(np.diff(done) > 1)
        need = [g for g in gaps if (ins[g] != ins[g + 1]) or (near[g] and not ins[g])
                or (near[g + 1] and not ins[g + 1]) or g in (j - 1, j, jr - 1, jr)]
        if not need:
            break
        new = np.concatenate([np.arange(done[g] + 1, done[g + 1]) for g in need])
        put(new, _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid[new], constant,
                          model_rel, bmax_v))
        done = np.flatnonzero(have)
    cols = np.concatenate([c for c, _ in batches])
    order = np.argsort(cols, kind="stable")
    outs = [np.concatenate([o[k].T for _, o in batches])[order].T for k in range(3)]
    return done, outs
