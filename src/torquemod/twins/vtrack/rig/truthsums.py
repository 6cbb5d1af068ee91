"""Compiled sums of the twin's ground truth (numba, without the GIL).

The truth of a step (:mod:`torquemod.twins.vtrack.rig.truth`) needs, over the recorded
samples and over each platform revolution, the means of six columns and the standard
deviations of two (two passes, as ``numpy.std``), and the normal equations of the
least-squares fit of the modulation's sine with the speed loop's wobble fitted out
(``X^T X`` and ``X^T [torque, speed]`` for the basis ``X`` of :func:`_fit_basis`). Every sum
here adds its terms one after the other in sample order, so the results do not depend on
how the loops are blocked or fused (tested bit for bit against plain loops):
:func:`step_sums` takes the means' first pass, the fit's basis and the fit's sums in one
sweep over blocks of the samples while they are in cache.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.twins.vtrack.rig.kernels import SMALL, cos_small, sin_small


@numba.njit(cache=True, nogil=True)
def _span_moments(raw, a, b, cols, mean, std_cols, std):
    """Means over rows ``a:b`` of ``raw`` of the columns ``cols`` into ``mean``, and the
    standard deviations (two passes, as ``numpy.std``) of the columns ``std_cols`` (indices
    into ``cols``) into ``std``: one pass over the rows instead of a copy per column."""
    mean[:] = 0.0
    for k in range(a, b):
        for j in range(cols.size):
            mean[j] += raw[k, cols[j]]
    mean /= b - a
    std[:] = 0.0
    for k in range(a, b):
        for j in range(std_cols.size):
            d = raw[k, cols[std_cols[j]]] - mean[std_cols[j]]
            std[j] += d * d
    for j in range(std_cols.size):
        std[j] = math.sqrt(std[j] / (b - a))


@numba.njit(cache=True, nogil=True)
def _partition_moments(raw, edges, cols, mean, std_cols, std):
    """:func:`_span_moments` of the whole ``edges[0]:edges[-1]`` (row 0 of ``mean`` and
    ``std``) and of each part ``edges[j]:edges[j+1]`` (row ``j + 1``) in two passes over the
    rows instead of two per span: the parts' sums give the whole's mean, and the second pass
    gathers the squared deviations from both means. The truth's layout (6 means, 2 standard
    deviations) sums in local variables (:func:`_partition_sums_6_2`: a third of the time
    of sums kept in the output arrays, the same additions in the same order)."""
    m = edges.size - 1
    nc, ns = cols.size, std_cols.size
    mean[:] = 0.0
    std[:] = 0.0
    if nc == 6 and ns == 2:
        _partition_sums_6_2(raw, edges, cols, mean, std_cols, std)
    else:
        for j in range(m):
            for k in range(edges[j], edges[j + 1]):
                for c in range(nc):
                    mean[j + 1, c] += raw[k, cols[c]]
        _means_from_sums(edges, mean)
        for j in range(m):
            for k in range(edges[j], edges[j + 1]):
                for c in range(ns):
                    x = raw[k, cols[std_cols[c]]]
                    d = x - mean[j + 1, std_cols[c]]
                    e = x - mean[0, std_cols[c]]
                    std[j + 1, c] += d * d
                    std[0, c] += e * e
    _finish_std(edges, std)


@numba.njit(cache=True, nogil=True)
def _finish_std(edges, std):
    """Sums of squared deviations (rows as :func:`_partition_moments`') to standard
    deviations."""
    m = edges.size - 1
    for j in range(m):
        for c in range(std.shape[1]):
            std[j + 1, c] = math.sqrt(std[j + 1, c] / (edges[j + 1] - edges[j]))
    for c in range(std.shape[1]):
        std[0, c] = math.sqrt(std[0, c] / (edges[m] - edges[0]))


@numba.njit(cache=True, nogil=True)
def _means_from_sums(edges, mean):
    """Rows ``1..m`` of ``mean`` hold the parts' sums: make them means and row 0 the
    whole's (the sum of the parts' sums over all rows)."""
    m = edges.size - 1
    for j in range(m):
        for c in range(mean.shape[1]):
            mean[0, c] += mean[j + 1, c]
            mean[j + 1, c] /= edges[j + 1] - edges[j]
    for c in range(mean.shape[1]):
        mean[0, c] /= edges[m] - edges[0]


@numba.njit(cache=True, nogil=True)
def _partition_sums_6_2(raw, edges, cols, mean, std_cols, std):
    """:func:`_partition_moments`' two passes for 6 mean and 2 deviation columns with the
    running sums in local variables (registers) instead of the output arrays; leaves the
    means and the sums of squared deviations (rows as there) in ``mean`` and ``std``."""
    m = edges.size - 1
    c0, c1, c2, c3, c4, c5 = cols[0], cols[1], cols[2], cols[3], cols[4], cols[5]
    for j in range(m):
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        for k in range(edges[j], edges[j + 1]):
            s0 += raw[k, c0]
            s1 += raw[k, c1]
            s2 += raw[k, c2]
            s3 += raw[k, c3]
            s4 += raw[k, c4]
            s5 += raw[k, c5]
        mean[j + 1, 0], mean[j + 1, 1], mean[j + 1, 2] = s0, s1, s2
        mean[j + 1, 3], mean[j + 1, 4], mean[j + 1, 5] = s3, s4, s5
    _means_from_sums(edges, mean)
    _deviations_2(raw, edges, cols, mean, std_cols, std)


@numba.njit(cache=True, nogil=True)
def _deviations_2(raw, edges, cols, mean, std_cols, std):
    """The second pass of :func:`_partition_sums_6_2`: the sums of squared deviations of
    the two columns ``cols[std_cols]`` from each part's mean and from the whole's (``mean``
    rows ``j + 1`` and 0) into ``std`` (rows as there)."""
    m = edges.size - 1
    a0, a1 = std_cols[0], std_cols[1]
    k0, k1 = cols[a0], cols[a1]
    w0 = w1 = 0.0  # the whole's
    for j in range(m):
        p0 = p1 = 0.0  # the part's
        mj0, mj1, mw0, mw1 = mean[j + 1, a0], mean[j + 1, a1], mean[0, a0], mean[0, a1]
        for k in range(edges[j], edges[j + 1]):
            x = raw[k, k0]
            d = x - mj0
            e = x - mw0
            p0 += d * d
            w0 += e * e
            x = raw[k, k1]
            d = x - mj1
            e = x - mw1
            p1 += d * d
            w1 += e * e
        std[j + 1, 0], std[j + 1, 1] = p0, p1
    std[0, 0], std[0, 1] = w0, w1


#: fit samples between exact evaluations of the basis's sines (rotated in between)
_BASIS_EXACT = 256


@numba.njit(cache=True, nogil=True)
def _fit_basis(t, w, wob, theta, x):
    """:func:`_basis_rows` with the step ``dt = t[1] - t[0]`` [s] of these times."""
    _basis_rows(t, t[1] - t[0] if t.size > 1 else 0.0, w, wob, theta, x)


@numba.njit(cache=True, nogil=True)
def _basis_rows(t, dt, w, wob, theta, x):
    """The truth fit's basis at times ``t`` [s] (equally spaced) and platform angles
    ``theta`` [rad] into ``x``: ``cos(w*t)``, ``sin(w*t)``, 1, then per wobble row
    (:func:`~torquemod.twins.vtrack.rig.dynamics.wobble_table`) cos and sin of ``rate*t`` (band
    rows) or
    ``order*theta`` (revolution rows) -- :func:`~torquemod.twins.vtrack.rig.dynamics.wobble_basis`
    and the
    modulation's columns, each sine rotated from sample to sample (through ``rate*dt``, whose
    small-angle sin and cos are computed once per column, or the angle's small increment,
    :mod:`torquemod.twins.vtrack.rig.kernels`) and exact every ``_BASIS_EXACT`` samples
    (from the first). ``dt`` [s]: the times' step (the time columns' rotation)."""
    n = t.size
    nw = wob.shape[0]
    m1 = nw + 1
    rates = np.empty(m1)
    rev = np.zeros(m1, dtype=np.bool_)
    rates[0] = w
    for j in range(nw):
        rates[j + 1] = wob[j, 1]
        rev[j + 1] = wob[j, 3] > 0.5
    # time columns turn by the same rates[j]*dt every sample
    c_dt, s_dt = np.empty(m1), np.empty(m1)
    small = np.zeros(m1, dtype=np.bool_)
    for j in range(m1):
        d = rates[j] * dt
        small[j] = abs(d) <= SMALL
        c_dt[j], s_dt[j] = cos_small(d), sin_small(d)
    c, s = np.empty(m1), np.empty(m1)
    for k in range(n):
        exact = k % _BASIS_EXACT == 0
        for j in range(m1):
            if rev[j]:
                d = rates[j] * (theta[k] - theta[k - 1]) if k > 0 else 0.0
                if exact or not abs(d) <= SMALL:
                    arg = rates[j] * theta[k]
                    c[j], s[j] = math.cos(arg), math.sin(arg)
                else:
                    cd, sd = cos_small(d), sin_small(d)
                    c[j], s[j] = c[j] * cd - s[j] * sd, s[j] * cd + c[j] * sd
            elif exact or not small[j]:
                arg = rates[j] * t[k]
                c[j], s[j] = math.cos(arg), math.sin(arg)
            else:
                cd, sd = c_dt[j], s_dt[j]
                c[j], s[j] = c[j] * cd - s[j] * sd, s[j] * cd + c[j] * sd
        x[k, 0], x[k, 1], x[k, 2] = c[0], s[0], 1.0
        for j in range(nw):
            x[k, 3 + 2 * j], x[k, 4 + 2 * j] = c[j + 1], s[j + 1]


#: rows of the fit taken per load and store of each sum (:func:`_add_rows8`)
_ROWS = 8


@numba.njit(cache=True, nogil=True)
def _add_rows8(x, i, sg):
    """Add rows ``i..i+7`` of ``x`` (the fit's basis, then torque and speed, padded with
    zeros) to ``sg[p, q] = sum x[:, p]*x[:, q]`` for every basis column ``p``: each sum is
    loaded and stored once for the eight rows and takes their products one row after the
    other, as eight single-row updates would (the same additions in the same order). The
    loop over ``q`` runs over whole rows of ``sg`` (the lower triangle is computed too and
    never read), so that it compiles to vector instructions across the sums."""
    r0, r1, r2, r3 = x[i], x[i + 1], x[i + 2], x[i + 3]
    r4, r5, r6, r7 = x[i + 4], x[i + 5], x[i + 6], x[i + 7]
    w = x.shape[1]
    for p in range(sg.shape[0]):
        b0, b1, b2, b3 = r0[p], r1[p], r2[p], r3[p]
        b4, b5, b6, b7 = r4[p], r5[p], r6[p], r7[p]
        row = sg[p]
        for q in range(w):
            row[q] = (((((((row[q] + b0 * r0[q]) + b1 * r1[q]) + b2 * r2[q]) + b3 * r3[q])
                        + b4 * r4[q]) + b5 * r5[q]) + b6 * r6[q]) + b7 * r7[q]


@numba.njit(cache=True, nogil=True)
def _fit_sums(raw, t0_s, fs, stride, w, wob, coef, cols, win_lo, win_hi, gram, rhs, ref):
    """The truth fit's normal equations over windows of one step, without the GIL.

    The fit's samples are the rows ``i*stride`` of ``raw`` (sample ``k`` at
    ``t0_s + k/fs`` [s]); their basis is :func:`_fit_basis` (modulation cos, sin, DC, then the
    wobble rows of ``wob``; ``cols = (platform angle, torque, wheel speed)`` columns of
    ``raw``). For each window ``j`` (fit samples ``win_lo[j] <= i < win_hi[j]``):
    ``gram[j] = X^T X`` and ``rhs[j] = X^T [torque, speed]``. ``ref[i]``: the speed
    reference's wobble at fit sample ``i``, ``X[i, 3:] @ coef``. The windows overlap (the
    whole step and its revolutions), so the sums are taken over the pieces between
    consecutive window edges (each sample once, row after row) and added up per window.
    Torque and speed ride as two more columns of the basis (``X^T [torque, speed]`` are
    then columns of the same sums: ``x_p*u`` is the product ``u*x_p`` bit for bit), the
    rows padded to a multiple of 8 columns for :func:`_add_rows8`."""
    n = (raw.shape[0] + stride - 1) // stride
    m = 3 + 2 * wob.shape[0]
    width = (m + 2 + 7) // 8 * 8
    t, theta = np.empty(n), np.empty(n)
    for i in range(n):
        t[i] = t0_s + (i * stride) / fs
        theta[i] = raw[i * stride, cols[0]]
    x = np.zeros((n, width))
    _fit_basis(t, w, wob, theta, x)
    for i in range(n):
        x[i, m] = raw[i * stride, cols[1]]
        x[i, m + 1] = raw[i * stride, cols[2]]
        r = 0.0
        for q in range(m - 3):
            r += x[i, 3 + q] * coef[q]
        ref[i] = r
    edges = np.unique(np.concatenate((win_lo, win_hi)))
    nseg = edges.size - 1
    sg = np.zeros((max(nseg, 1), m, width))
    for g in range(nseg):
        i, hi = edges[g], edges[g + 1]
        sgg = sg[g]
        while i + _ROWS <= hi:  # eight rows per load and store of each sum, row by row
            _add_rows8(x, i, sgg)
            i += _ROWS
        while i < hi:
            for p in range(m):
                bp = x[i, p]
                for q in range(width):
                    sgg[p, q] += bp * x[i, q]
            i += 1
    _windows(edges, sg, win_lo, win_hi, m, gram, rhs)


#: fit rows per block of :func:`step_sums`: a multiple of ``_BASIS_EXACT``, so that each
#: block's basis starts exact as the whole's does there
_BLOCK = _BASIS_EXACT


@numba.njit(cache=True, nogil=True)
def step_sums(raw, t0_s, fs, stride, w, wob, coef, fcols, win_lo, win_hi, gram, rhs, ref,
              edges, mcols, std_cols, mean, std):
    """:func:`_fit_sums` and :func:`_partition_moments` (the truth's layout: 6 mean
    columns ``mcols``, 2 deviation columns ``std_cols``) of one step in one sweep: block by
    block of ``_BLOCK`` fit rows, the means' first pass over the block's samples, the
    fit's basis, speed reference and sums for its rows, while the block is in cache; then
    the deviations' pass. Every sum takes its terms in the same order as there, so the
    results are theirs bit for bit (tested); the arguments are theirs."""
    n = (raw.shape[0] + stride - 1) // stride
    m = 3 + 2 * wob.shape[0]
    width = (m + 2 + 7) // 8 * 8
    dt = (t0_s + (1 * stride) / fs) - (t0_s + (0 * stride) / fs) if n > 1 else 0.0
    fedges = np.unique(np.concatenate((win_lo, win_hi)))
    nseg = fedges.size - 1
    sg = np.zeros((max(nseg, 1), m, width))
    x = np.zeros((_BLOCK, width))
    t, theta = np.empty(_BLOCK), np.empty(_BLOCK)
    nparts = edges.size - 1
    c0, c1, c2, c3, c4, c5 = mcols[0], mcols[1], mcols[2], mcols[3], mcols[4], mcols[5]
    mean[:] = 0.0
    std[:] = 0.0
    part = 0
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    k = edges[0]
    for i0 in range(0, n, _BLOCK):
        i1 = min(i0 + _BLOCK, n)
        k_end = min(i1 * stride, edges[nparts])
        while k < k_end:  # the means' first pass, part by part (_partition_sums_6_2)
            stop = min(k_end, edges[part + 1])
            for kk in range(k, stop):
                s0 += raw[kk, c0]
                s1 += raw[kk, c1]
                s2 += raw[kk, c2]
                s3 += raw[kk, c3]
                s4 += raw[kk, c4]
                s5 += raw[kk, c5]
            k = stop
            if k == edges[part + 1]:
                mean[part + 1, 0], mean[part + 1, 1], mean[part + 1, 2] = s0, s1, s2
                mean[part + 1, 3], mean[part + 1, 4], mean[part + 1, 5] = s3, s4, s5
                s0 = s1 = s2 = s3 = s4 = s5 = 0.0
                part += 1
        nb = i1 - i0
        for r in range(nb):
            k_r = (i0 + r) * stride
            t[r] = t0_s + k_r / fs
            theta[r] = raw[k_r, fcols[0]]
            x[r, m] = raw[k_r, fcols[1]]
            x[r, m + 1] = raw[k_r, fcols[2]]
            ref[i0 + r] = 0.0
        _basis_rows(t[:nb], dt, w, wob, theta[:nb], x)
        for q in range(m - 3):  # each row's terms in order; the rows side by side
            cq = coef[q]
            for r in range(nb):
                ref[i0 + r] += x[r, 3 + q] * cq
        for g in range(nseg):
            a, b = max(fedges[g], i0), min(fedges[g + 1], i1)
            sgg = sg[g]
            i = a
            while i + _ROWS <= b:
                _add_rows8(x, i - i0, sgg)
                i += _ROWS
            while i < b:
                for p in range(m):
                    bp = x[i - i0, p]
                    for q in range(width):
                        sgg[p, q] += bp * x[i - i0, q]
                i += 1
    _means_from_sums(edges, mean)
    _deviations_2(raw, edges, mcols, mean, std_cols, std)
    _finish_std(edges, std)
    _windows(fedges, sg, win_lo, win_hi, m, gram, rhs)


@numba.njit(cache=True, nogil=True)
def _windows(fedges, sg, win_lo, win_hi, m, gram, rhs):
    """The windows' normal equations (``gram``, ``rhs``) from the sums ``sg`` over the
    pieces between consecutive window edges ``fedges``, added piece after piece; the lower
    triangle of each ``gram`` mirrored from the upper."""
    gram[:] = 0.0
    rhs[:] = 0.0
    for g in range(fedges.size - 1):
        for j in range(win_lo.size):
            if win_lo[j] <= fedges[g] and fedges[g + 1] <= win_hi[j]:
                for p in range(m):
                    for q in range(m):
                        gram[j, p, q] += sg[g, p, q]
                    rhs[j, p, 0] += sg[g, p, m]
                    rhs[j, p, 1] += sg[g, p, m + 1]
    for j in range(win_lo.size):
        for p in range(m):
            for q in range(p):
                gram[j, p, q] = gram[j, q, p]
