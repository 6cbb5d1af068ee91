"""The settling time of several IIR filters at once, for the padding of steps 3-5 (the
longest settling of the chain's filters).

Each filter's settling is :func:`torquemod.dsp.filters.settling_samples`' doubling search on
its impulse response (the direct form II transposed with ``lfilter``'s order of operations,
J. O. Smith, "Introduction to Digital Filters", W3K Publishing 2007, "Transposed Direct-Forms"),
with the same steps and the same numbers as
:func:`~torquemod.dsp.filters._settling_kernel`. The impulse response is a recurrence whose
every sample waits on the previous one; the responses of different filters are independent,
so up to three of them advance in one loop and the processor overlaps their operations.
"""

from __future__ import annotations

import numba
import numpy as np

from torquemod.dsp.filters import _response_samples, _settling_kernel


@numba.njit(cache=True, nogil=True)
def longest_settling(bs: np.ndarray, as_: np.ndarray, lengths: np.ndarray, tol: float,
                     max_samples: int) -> int:
    """The largest settling [samples] of the filters ``bs[f, :lengths[f]]`` over
    ``as_[f, :lengths[f]]`` (``a[0] = 1``).

    Parameters
    ----------
    bs, as_ : ndarray
        ``(filters, 5)`` or wider: each filter's ``b`` and ``a`` from column 0.
    lengths : ndarray
        int64 number of coefficients of each filter (at least 2) [-].
    tol : float
        Share of the impulse response's peak [-] (``settling_samples``' ``tol``).
    max_samples : int
        Longest response searched [samples].

    Returns
    -------
    int
        ``max`` over the filters of ``settling_samples((b, a), tol=tol,
        max_samples=max_samples)``, 0 without filters. Filters of order 2 and 4 are searched
        three at a time (:func:`_settling_of_three`), others one at a time
        (:func:`~torquemod.dsp.filters._settling_kernel`).
    """
    nf = lengths.size
    result = 0
    group = np.empty(3, dtype=np.int64)
    g = 0
    for f in range(nf):
        m = lengths[f]
        if m == 3 or m == 5:
            group[g] = f
            g += 1
            if g == 3:
                result = max(result, _settling_of_three(bs, as_, lengths, group, g, tol,
                                                        max_samples))
                g = 0
        else:
            result = max(result, _settling_kernel(bs[f, :m].copy(), as_[f, :m].copy(), tol,
                                                  max_samples))
    if g:
        result = max(result, _settling_of_three(bs, as_, lengths, group, g, tol, max_samples))
    return result


@numba.njit(cache=True, nogil=True)
def _settling_of_three(bs: np.ndarray, as_: np.ndarray, lengths: np.ndarray,
                       group: np.ndarray, count: int, tol: float, max_samples: int) -> int:
    """The largest settling of the filters ``group[:count]`` (1 to 3, each of order 2 or
    4): :func:`~torquemod.dsp.filters._settling_kernel`'s search on each, their impulse
    responses advancing together (:func:`_three_responses`; a missing third filter is the
    first again, its answer unused), the last one still searched alone
    (:func:`~torquemod.dsp.filters._response_samples`)."""
    b = np.zeros((3, 5))
    a = np.zeros((3, 5))
    fourth = np.zeros(3, dtype=np.bool_)
    for s in range(3):
        f = group[s if s < count else 0]
        m = lengths[f]
        b[s, :m] = bs[f, :m]
        a[s, :m] = as_[f, :m]
        fourth[s] = m == 5
    z = np.zeros((3, 4))
    h = np.empty((3, min(max_samples, 4096)))  # grown when the search goes further
    peak = np.zeros(3)
    settled = np.full(3, -1, dtype=np.int64)
    for s in range(count, 3):
        settled[s] = 0
    done = 0
    n = 256
    while n <= max_samples:
        if n > h.shape[1]:
            grown = np.empty((3, min(max_samples, 4 * n)))
            grown[:, :done] = h[:, :done]
            h = grown
        n_open = 0
        alone = 0  # the filter still searched, when only one is
        for s in range(count):
            if settled[s] < 0:
                n_open += 1
                alone = s
        if n_open == 1:  # one left: its recurrence alone, as the single search runs it
            m = 5 if fourth[alone] else 3
            _response_samples(b[alone, :m].copy(), a[alone, :m].copy(), z[alone, :m - 1],
                              h[alone], done, n)
        else:  # the responses' first n samples, together
            _three_responses(b, a, fourth, z, h, done, n)
        open_ = 0
        for s in range(count):
            if settled[s] >= 0:
                continue
            hs = h[s]
            p = peak[s]
            for k in range(done, n):  # the peak of the first n: the earlier ones' and the new
                p = max(p, abs(hs[k]))
            peak[s] = p
            last = n - 1  # the last sample above the share of the peak, from the end
            while last >= 0 and not abs(hs[last]) > tol * p:
                last -= 1
            if last < n - n // 4:
                settled[s] = last + 1
            else:
                open_ += 1
        done = n
        if open_ == 0:
            break
        n *= 2
    result = 0
    for s in range(count):
        result = max(result, settled[s] if settled[s] >= 0 else max_samples)
    return result


@numba.njit(cache=True, nogil=True)
def _three_responses(b: np.ndarray, a: np.ndarray, fourth: np.ndarray, z: np.ndarray,
                     h: np.ndarray, start: int, stop: int) -> None:
    """Samples ``start:stop`` of the impulse responses of the three filters ``b[s]/a[s]``
    (order 4 where ``fourth[s]``, else 2) into ``h[s]``, from and to the states ``z[s]``,
    in one loop: each sample of each filter by the operations of
    :func:`~torquemod.dsp.filters._response_samples` (the same numbers)."""
    u0, u1, u2, u3 = z[0, 0], z[0, 1], z[0, 2], z[0, 3]
    v0, v1, v2, v3 = z[1, 0], z[1, 1], z[1, 2], z[1, 3]
    w0, w1, w2, w3 = z[2, 0], z[2, 1], z[2, 2], z[2, 3]
    f0, f1, f2 = fourth[0], fourth[1], fourth[2]
    pb0, pb1, pb2 = b[0], b[1], b[2]
    pa0, pa1, pa2 = a[0], a[1], a[2]
    h0, h1, h2 = h[0], h[1], h[2]
    for k in range(start, stop):
        xn = 1.0 if k == 0 else 0.0
        y0 = u0 + pb0[0] * xn
        y1 = v0 + pb1[0] * xn
        y2 = w0 + pb2[0] * xn
        if f0:
            u0 = u1 + xn * pb0[1] - y0 * pa0[1]
            u1 = u2 + xn * pb0[2] - y0 * pa0[2]
            u2 = u3 + xn * pb0[3] - y0 * pa0[3]
            u3 = xn * pb0[4] - y0 * pa0[4]
        else:
            u0 = u1 + xn * pb0[1] - y0 * pa0[1]
            u1 = xn * pb0[2] - y0 * pa0[2]
        if f1:
            v0 = v1 + xn * pb1[1] - y1 * pa1[1]
            v1 = v2 + xn * pb1[2] - y1 * pa1[2]
            v2 = v3 + xn * pb1[3] - y1 * pa1[3]
            v3 = xn * pb1[4] - y1 * pa1[4]
        else:
            v0 = v1 + xn * pb1[1] - y1 * pa1[1]
            v1 = xn * pb1[2] - y1 * pa1[2]
        if f2:
            w0 = w1 + xn * pb2[1] - y2 * pa2[1]
            w1 = w2 + xn * pb2[2] - y2 * pa2[2]
            w2 = w3 + xn * pb2[3] - y2 * pa2[3]
            w3 = xn * pb2[4] - y2 * pa2[4]
        else:
            w0 = w1 + xn * pb2[1] - y2 * pa2[1]
            w1 = xn * pb2[2] - y2 * pa2[2]
        h0[k] = y0
        h1[k] = y1
        h2[k] = y2
    z[0, 0], z[0, 1], z[0, 2], z[0, 3] = u0, u1, u2, u3
    z[1, 0], z[1, 1], z[1, 2], z[1, 3] = v0, v1, v2, v3
    z[2, 0], z[2, 1], z[2, 2], z[2, 3] = w0, w1, w2, w3
