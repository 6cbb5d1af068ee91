"""A tone (with its harmonics) fitted beside a fixed basis at many trial frequencies: the
variable-projection search of the modulation frequency (Golub and Pereyra 1973) needs, at
each trial frequency f, the power a record's residual on the basis B keeps along the tone's
columns M(f) once those are made orthogonal to B (Frisch-Waugh-Lovell).

With Q an orthonormal basis of B's span (:func:`torquemod.dsp.projection.orthonormal_basis_t`,
:func:`torquemod.dsp.blockbasis.removal_basis_at`) and ``C = Q'M``, the residual
``r_M = M - Q C`` gives ``r_M'r_M = M'M - C'C`` and ``r_M'r_y = M'r_y - C'Q'r_y``: one
matrix product per batch of trial frequencies instead of a least-squares solve per
frequency, and small systems of 2 x (harmonics + 1) unknowns, all in one compiled call
(:func:`explained_power`, :func:`refine_peaks`).
"""

from __future__ import annotations

import math

import numba
import numpy as np


def tone_columns(n: int, fs_hz: float, frequencies_hz, orders=(1,)) -> np.ndarray:
    """Cosine and sine columns of tones and their harmonics, time from the record's middle.

    Parameters
    ----------
    n : int
        Samples.
    fs_hz : float
        Sample rate [Hz]; sample i is at ``t = (i - (n-1)/2)/fs_hz`` [s].
    frequencies_hz : sequence of float
        Fundamental frequencies f [Hz].
    orders : sequence of int
        Orders k (1 for the fundamental, 2, 3, ... for its harmonics).

    Returns
    -------
    ndarray
        ``n x 2*len(frequencies_hz)*len(orders)``: for each f, for each k, ``cos(2*pi*k*f*t)``
        then ``sin(2*pi*k*f*t)``; the columns of
        :func:`torquemod.processing.speedmodel.modulation_columns` side by side to ~1e-14
        (exact every 32 samples, rotated by one sample's angle between, the harmonics as
        powers of the fundamental's phasor).
    """
    out = np.empty((2 * len(frequencies_hz) * len(orders), n))
    _fill_tones_t(out, float(fs_hz), 2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64),
                  np.asarray(orders, dtype=np.int64))
    return out.T


@numba.njit(cache=True, nogil=True)
def _fill_tones_t(out: np.ndarray, fs_hz: float, omegas: np.ndarray, orders: np.ndarray
                  ) -> None:
    """Rows of ``out`` (``2*len(omegas)*len(orders) x n``): for each angular frequency w
    [rad/s] and order k, ``cos(k*w*t)`` then ``sin(k*w*t)`` over ``t = (i - (n-1)/2)/fs``.

    The fundamental's phasor is exact (libm) at every 32nd sample and rotated by one
    sample's angle between; the blocks of 32 samples are rotated side by side (independent
    recurrences, so the loop over the blocks runs on SIMD lanes), each sample by the same
    operations as one block at a time. The harmonics are powers of the fundamental's phasor,
    ``(c, s) <- (c c1 - s s1, s c1 + c s1)`` from ``(c1, s1)``, for all samples at once.
    """
    n = out.shape[1]
    nk = orders.size
    k_max = 1
    for k in orders:
        k_max = max(k_max, k)
    half = (n - 1) / 2.0
    nb = (n + 31) // 32
    cb = np.empty((32, nb))  # cb[j, b]: sample 32*b + j
    sb = np.empty((32, nb))
    c1, s1 = np.empty(n), np.empty(n)
    ck, sk = np.empty(n), np.empty(n)
    for f in range(omegas.size):
        w = omegas[f]
        cd, sd = math.cos(w / fs_hz), math.sin(w / fs_hz)
        for b in range(nb):  # exact, then rotated by one sample
            a = w * ((32 * b - half) / fs_hz)
            cb[0, b] = math.cos(a)
            sb[0, b] = math.sin(a)
        for j in range(1, 32):
            cp, sp, cn, sn = cb[j - 1], sb[j - 1], cb[j], sb[j]
            for b in range(nb):
                cn[b] = cp[b] * cd - sp[b] * sd
                sn[b] = sp[b] * cd + cp[b] * sd
        for b in range(nb):
            for j in range(min(32, n - 32 * b)):
                c1[32 * b + j] = cb[j, b]
                s1[32 * b + j] = sb[j, b]
        ck[:] = c1  # the first power, (1*c1 - 0*s1, 0*c1 + 1*s1) but for a zero's sign
        sk[:] = s1
        for k in range(1, k_max + 1):
            if k > 1:
                for i in range(n):
                    c, s = ck[i], sk[i]
                    ck[i] = c * c1[i] - s * s1[i]
                    sk[i] = s * c1[i] + c * s1[i]
            for j in range(nk):
                if orders[j] == k:
                    row = 2 * (f * nk + j)
                    out[row] = ck
                    out[row + 1] = sk


def explained_power(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
                    frequencies_hz, columns, orders=(1,)) -> np.ndarray:
    """Power of a record's residual that a tone explains beyond a basis, at many trial
    frequencies in one compiled call.

    For each i, ``r_y' r_M (r_M'r_M)^-1 r_M' r_y`` with ``r_y`` record ``columns[i]`` less its
    least-squares fit on the basis and ``r_M`` the tone's columns at ``frequencies_hz[i]``
    (:func:`tone_columns`) less their projection on it (Frisch-Waugh-Lovell):
    ``r_M'r_M = M'M - C'C`` and ``r_M'r_y = M'r_y - C'Q'r_y`` with ``C = Q'M``.

    Parameters
    ----------
    qt : ndarray
        ``Q'`` (``p x n``) of an orthonormal basis Q of the basis's span
        (:func:`orthonormal_basis_t`).
    r_y : ndarray
        Records less their fit on the basis (``n x records``).
    qy : ndarray
        ``Q' r_y`` (``p x records``; zero to rounding).
    fs_hz : float
        Sample rate [Hz]; time runs from the record's middle.
    frequencies_hz, columns : sequence
        Trial frequency [Hz] and record index of each evaluation.
    orders : sequence of int
        The tone's orders (1 and its harmonics).

    Returns
    -------
    ndarray
        The explained power of each evaluation [record unit^2]; NaN where the tone's
        columns are (numerically) in the basis's span.
    """
    return _explained(qt, np.ascontiguousarray(r_y), np.ascontiguousarray(qy), float(fs_hz),
                      2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64),
                      np.asarray(columns, dtype=np.int64), np.asarray(orders, dtype=np.int64))


def refine_peaks(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
                 duration_s: float, columns, peaks_hz, orders=(1,), *,
                 tol_hz: float = 1e-6) -> list[float]:
    """The frequencies near ``peaks_hz`` at which a tone explains most of each record beyond
    a basis (variable projection, Golub and Pereyra 1973): parabolic steps through three
    values of :func:`explained_power`, ``0.05/T``, ``0.005/T`` and ``0.0005/T`` apart (T the
    record's duration), each from the previous vertex, until a step is below ``tol_hz``; a
    record whose explained power is not concave there keeps its peak. All the records
    advance in step, in one compiled call.

    Parameters
    ----------
    qt, r_y, qy : ndarray
        As :func:`explained_power`.
    fs_hz : float
        Sample rate [Hz].
    duration_s : float
        The records' duration T [s] (samples over the rate).
    columns, peaks_hz : sequence
        Record index and starting frequency [Hz] of each search.
    orders : sequence of int
        The tone's orders (1 and its harmonics).
    tol_hz : float
        Step below which a search stops [Hz]. Default 1e-6.

    Returns
    -------
    list of float
        The refined frequencies [Hz].
    """
    out = _refine(qt, np.ascontiguousarray(r_y), np.ascontiguousarray(qy), float(fs_hz),
                  float(duration_s), np.asarray(columns, dtype=np.int64),
                  np.asarray(peaks_hz, dtype=np.float64), np.asarray(orders, dtype=np.int64),
                  float(tol_hz))
    return out.tolist()  # (Python floats, the same numbers)


@numba.njit(cache=True, nogil=True)
def _refine(qt, r_y, qy, fs_hz, duration, columns, peaks, orders, tol_hz):
    """:func:`refine_peaks` in one call: each step's explained powers of every active
    search from one :func:`_explained` evaluation, the steps' arithmetic as Python's on
    floats."""
    f = peaks.copy()
    active = np.ones(peaks.size, dtype=np.bool_)
    two_pi = 2 * np.pi
    for h in (0.05 / duration, 0.005 / duration, 0.0005 / duration):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        omegas = np.empty(3 * idx.size)
        cols = np.empty(3 * idx.size, dtype=np.int64)
        for j in range(idx.size):
            i = idx[j]
            omegas[3 * j] = two_pi * (f[i] + -1.0 * h)
            omegas[3 * j + 1] = two_pi * (f[i] + 0.0 * h)
            omegas[3 * j + 2] = two_pi * (f[i] + 1.0 * h)
            cols[3 * j] = cols[3 * j + 1] = cols[3 * j + 2] = columns[i]
        e = _explained(qt, r_y, qy, fs_hz, omegas, cols, orders)
        for j in range(idx.size):
            i = idx[j]
            e_lo, e_0, e_hi = e[3 * j], e[3 * j + 1], e[3 * j + 2]
            curvature = e_lo - 2.0 * e_0 + e_hi
            active[i] = False
            if not curvature < 0:  # not near a maximum: the spectral peak's value
                f[i] = peaks[i]
                continue
            step = 0.5 * h * (e_lo - e_hi) / curvature
            lo, hi = -2.0 * h, 2.0 * h
            step = lo if lo > step else step  # Python's max(step, lo), min(., hi)
            step = hi if hi < step else step
            f[i] += step
            if not abs(step) < tol_hz:
                active[i] = True
    return f


@numba.njit(cache=True, nogil=True)
def _explained(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
               omegas: np.ndarray, columns: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """:func:`explained_power` in one compiled call (the basis products by BLAS)."""
    n = r_y.shape[0]
    p = qt.shape[0]
    k2 = 2 * orders.size
    rows = np.empty((omegas.size * k2 + r_y.shape[1], n))  # M' and then r_y'
    mt = rows[:omegas.size * k2]
    _fill_tones_t(mt, fs_hz, omegas, orders)
    rows[omegas.size * k2:] = r_y.T
    ct = mt @ qt.T  # (M'Q): C' row by row
    out = np.empty(omegas.size)
    g = np.empty((k2, k2))
    b = np.empty(k2)
    # the products r_M'r_y (k2) and the lower triangle of M'M (k2*(k2+1)/2) of one
    # frequency: jobs (row of mt, other vector, target), 8 dot products per pass over the
    # samples (each summed in sample order as one at a time: the same numbers, without
    # waiting on one sum's additions)
    n_jobs = k2 + k2 * (k2 + 1) // 2
    job_a = np.empty(n_jobs, dtype=np.int64)
    job_d = np.empty(n_jobs, dtype=np.int64)
    sums = np.empty(n_jobs)
    n_tone_rows = omegas.size * k2
    for f in range(omegas.size):
        o = f * k2
        col = columns[f]
        if k2 == 2 or k2 == 4 or k2 == 6:  # the tone's rows read once for all products
            _tone_dots(rows, o, n_tone_rows + col, k2, sums)
        else:
            q = 0
            for a in range(k2):
                job_a[q] = o + a
                job_d[q] = n_tone_rows + col  # the record's residual, a row after the tones
                q += 1
                for d in range(a + 1):
                    job_a[q] = o + a
                    job_d[q] = o + d
                    q += 1
            for start in range(0, n_jobs, 8):
                if n_jobs - start > 4:
                    _dots8(rows, job_a, job_d, start, min(start + 8, n_jobs), sums)
                else:  # (the last few: four running sums, not eight)
                    _dots4(rows, job_a, job_d, start, n_jobs, sums)
        q = 0
        for a in range(k2):
            s = sums[q]
            q += 1
            for j in range(p):
                s -= ct[o + a, j] * qy[j, col]
            b[a] = s
            for d in range(a + 1):
                s = sums[q]
                q += 1
                for j in range(p):
                    s -= ct[o + a, j] * ct[o + d, j]
                g[a, d] = s
        # b' g^-1 b by the Cholesky factor of g (lower, in place): |L^-1 b|^2
        ok = True
        for a in range(k2):
            for d in range(a + 1):
                s = g[a, d]
                for j in range(d):
                    s -= g[a, j] * g[d, j]
                if a == d:
                    if not s > 0:
                        ok = False
                        break
                    g[a, a] = math.sqrt(s)
                else:
                    g[a, d] = s / g[d, d]
            if not ok:
                break
        if not ok:
            out[f] = np.nan
            continue
        e = 0.0
        for a in range(k2):
            s = b[a]
            for j in range(a):
                s -= g[a, j] * b[j]
            b[a] = s / g[a, a]
            e += b[a] * b[a]
        out[f] = e
    return out


@numba.njit(cache=True, nogil=True)
def _dots8(rows: np.ndarray, job_a: np.ndarray, job_d: np.ndarray, start: int, stop: int,
           sums: np.ndarray) -> None:
    """``sums[q] = rows[job_a[q]] . rows[job_d[q]]`` for q in ``start:stop`` (at most 8):
    eight running sums at once, each over the samples in order (the numbers of one sum at a
    time)."""
    last = stop - 1
    x0, y0 = rows[job_a[start]], rows[job_d[start]]
    x1, y1 = rows[job_a[min(start + 1, last)]], rows[job_d[min(start + 1, last)]]
    x2, y2 = rows[job_a[min(start + 2, last)]], rows[job_d[min(start + 2, last)]]
    x3, y3 = rows[job_a[min(start + 3, last)]], rows[job_d[min(start + 3, last)]]
    x4, y4 = rows[job_a[min(start + 4, last)]], rows[job_d[min(start + 4, last)]]
    x5, y5 = rows[job_a[min(start + 5, last)]], rows[job_d[min(start + 5, last)]]
    x6, y6 = rows[job_a[min(start + 6, last)]], rows[job_d[min(start + 6, last)]]
    x7, y7 = rows[job_a[min(start + 7, last)]], rows[job_d[min(start + 7, last)]]
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for i in range(rows.shape[1]):
        s0 += x0[i] * y0[i]
        s1 += x1[i] * y1[i]
        s2 += x2[i] * y2[i]
        s3 += x3[i] * y3[i]
        s4 += x4[i] * y4[i]
        s5 += x5[i] * y5[i]
        s6 += x6[i] * y6[i]
        s7 += x7[i] * y7[i]
    acc = (s0, s1, s2, s3, s4, s5, s6, s7)
    for q in range(stop - start):
        sums[start + q] = acc[q]


@numba.njit(cache=True, nogil=True)
def _dots4(rows: np.ndarray, job_a: np.ndarray, job_d: np.ndarray, start: int, stop: int,
           sums: np.ndarray) -> None:
    """:func:`_dots8` for at most 4 products."""
    last = stop - 1
    x0, y0 = rows[job_a[start]], rows[job_d[start]]
    x1, y1 = rows[job_a[min(start + 1, last)]], rows[job_d[min(start + 1, last)]]
    x2, y2 = rows[job_a[min(start + 2, last)]], rows[job_d[min(start + 2, last)]]
    x3, y3 = rows[job_a[min(start + 3, last)]], rows[job_d[min(start + 3, last)]]
    s0 = s1 = s2 = s3 = 0.0
    for i in range(rows.shape[1]):
        s0 += x0[i] * y0[i]
        s1 += x1[i] * y1[i]
        s2 += x2[i] * y2[i]
        s3 += x3[i] * y3[i]
    acc = (s0, s1, s2, s3)
    for q in range(stop - start):
        sums[start + q] = acc[q]


@numba.njit(cache=True, nogil=True)
def _tone_dots(rows: np.ndarray, o: int, yr: int, k2: int, sums: np.ndarray) -> None:
    """:func:`_explained`'s products of one frequency for a tone of 2, 4 or 6 rows
    (``rows[o:o + k2]``, the record's residual ``rows[yr]``): for each row a, its product
    with the residual, then with rows 0..a, into ``sums`` in that order. The same sums as
    :func:`_dots8` (each over the samples in order, a product and an addition a sample),
    but each row read once a sample for all the products that use it (:func:`_dots_a01`,
    :func:`_dots_a23`, :func:`_dots_a45`) instead of twice a product."""
    y = rows[yr]
    x0, x1 = rows[o], rows[o + 1]
    if k2 == 2:
        _dots_a01(x0, x1, y, sums)
        return
    x2, x3 = rows[o + 2], rows[o + 3]
    _dots_a01(x0, x1, y, sums)
    _dots_a23(x0, x1, x2, x3, y, sums)
    if k2 == 6:
        _dots_a45(x0, x1, x2, x3, rows[o + 4], rows[o + 5], y, sums)


@numba.njit(cache=True, nogil=True)
def _dots_a01(x0: np.ndarray, x1: np.ndarray, y: np.ndarray, sums: np.ndarray) -> None:
    """:func:`_tone_dots`' products of rows 0 and 1: ``sums[0:5]``."""
    s0 = s1 = s2 = s3 = s4 = 0.0
    for i in range(y.size):
        a0, a1, b = x0[i], x1[i], y[i]
        s0 += a0 * b
        s1 += a0 * a0
        s2 += a1 * b
        s3 += a1 * a0
        s4 += a1 * a1
    sums[0], sums[1], sums[2], sums[3], sums[4] = s0, s1, s2, s3, s4


@numba.njit(cache=True, nogil=True)
def _dots_a23(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, x3: np.ndarray, y: np.ndarray,
              sums: np.ndarray) -> None:
    """:func:`_tone_dots`' products of rows 2 and 3: ``sums[5:14]``."""
    s5 = s6 = s7 = s8 = s9 = s10 = s11 = s12 = s13 = 0.0
    for i in range(y.size):
        a0, a1, a2, a3, b = x0[i], x1[i], x2[i], x3[i], y[i]
        s5 += a2 * b
        s6 += a2 * a0
        s7 += a2 * a1
        s8 += a2 * a2
        s9 += a3 * b
        s10 += a3 * a0
        s11 += a3 * a1
        s12 += a3 * a2
        s13 += a3 * a3
    sums[5], sums[6], sums[7], sums[8], sums[9] = s5, s6, s7, s8, s9
    sums[10], sums[11], sums[12], sums[13] = s10, s11, s12, s13


@numba.njit(cache=True, nogil=True)
def _dots_a45(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, x3: np.ndarray, x4: np.ndarray,
              x5: np.ndarray, y: np.ndarray, sums: np.ndarray) -> None:
    """:func:`_tone_dots`' products of rows 4 and 5: ``sums[14:27]``."""
    s14 = s15 = s16 = s17 = s18 = s19 = s20 = s21 = s22 = s23 = s24 = s25 = s26 = 0.0
    for i in range(y.size):
        a0, a1, a2, a3, a4, a5, b = x0[i], x1[i], x2[i], x3[i], x4[i], x5[i], y[i]
        s14 += a4 * b
        s15 += a4 * a0
        s16 += a4 * a1
        s17 += a4 * a2
        s18 += a4 * a3
        s19 += a4 * a4
        s20 += a5 * b
        s21 += a5 * a0
        s22 += a5 * a1
        s23 += a5 * a2
        s24 += a5 * a3
        s25 += a5 * a4
        s26 += a5 * a5
    sums[14], sums[15], sums[16], sums[17], sums[18] = s14, s15, s16, s17, s18
    sums[19], sums[20], sums[21], sums[22], sums[23] = s19, s20, s21, s22, s23
    sums[24], sums[25], sums[26] = s24, s25, s26
