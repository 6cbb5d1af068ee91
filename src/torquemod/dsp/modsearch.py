"""The search of a modulation frequency beside a fixed basis in one compiled call: the spectral
peaks of two records less their fit on the basis with the tone at a start frequency
(:func:`torquemod.dsp.spectrum.peak_frequencies`), the peaks again with the tone at the
mean of the first peaks (the records' removal by
:func:`torquemod.dsp.projection.removal_at_tone`) and each peak refined to the frequency at
which the tone explains most of its record (variable projection, G. H. Golub and V. Pereyra,
"The differentiation of pseudo-inverses and nonlinear least squares problems whose variables
separate", SIAM J. Numer. Anal. 10(2), 1973; :func:`torquemod.dsp.tonesearch.refine_peaks`).

The kernel calls the kernels of those functions in their order with their arguments, so the
numbers are theirs; what it spares is the passage through Python between them (five calls'
arguments checked and converted, the intermediate records boxed as numpy arrays).
"""

from __future__ import annotations

import numba
import numpy as np

from torquemod.dsp import numpyblas
from torquemod.dsp.peakkernels import _peaks_of_records
from torquemod.dsp.projection import _removal_at_tone
from torquemod.dsp.spectrum import _batch_plan
from torquemod.dsp.tonesearch import _refine

#: :func:`~torquemod.dsp.spectrum.peak_frequencies`' defaults of the refinement's tolerance
#: [Hz], the peak-to-floor power ratio [-] and Brent's evaluations, which the search takes
_XTOL_HZ, _MIN_RATIO, _MAXFUN = 1e-6, 20.0, 500


@numba.njit(cache=True, nogil=True)
def _search_kernel(first, start_hz, qt, r_y, qy, fs_hz, duration_s, orders, refine, tol_hz,
                   syrk, gemm, gesv, xtol_hz, min_ratio, maxfun, dn, factor, scale, design,
                   window, trig, freqs, bins, lobe, fs_plan):
    """:func:`search_modulation` in one call: ``(status, peaks)``, ``peaks`` (3, 2) the
    first peaks, the second and the refined ones (one array: one boxed for Python), status
    0 when every step went the compiled way; otherwise the step that did not (1: the first
    peaks, 2: the first peaks' mean is the start frequency, 3: the removal, 4: the second
    peaks)."""
    out = np.full((3, 2), np.nan)
    p1, ok = _peaks_of_records(first, xtol_hz, min_ratio, maxfun, dn, factor, scale, design,
                               window, trig, freqs, bins, lobe, fs_plan)
    if not ok:
        return 1, out
    out[0, 0], out[0, 1] = p1[0], p1[1]
    f_mod = 0.5 * (p1[0] + p1[1])
    if f_mod == start_hz:
        return 2, out
    cleaned, ok = _removal_at_tone(fs_hz, 2 * np.pi * f_mod, orders, qt, r_y, qy, syrk, gemm,
                                   gesv)
    if not ok:
        return 3, out
    p2, ok = _peaks_of_records(cleaned, xtol_hz, min_ratio, maxfun, dn, factor, scale,
                               design, window, trig, freqs, bins, lobe, fs_plan)
    if not ok:
        return 4, out
    out[1, 0], out[1, 1] = p2[0], p2[1]
    if refine:
        refined = _refine(qt, r_y, qy, fs_hz, duration_s, np.array([0, 1]), out[1].copy(),
                          orders, tol_hz)
        out[2, 0], out[2, 1] = refined[0], refined[1]
    else:
        out[2, 0], out[2, 1] = p2[0], p2[1]
    return 0, out


def search_modulation(first: np.ndarray, start_hz: float, qt: np.ndarray, r_y: np.ndarray,
                      qy: np.ndarray, fs_hz: float, orders: np.ndarray, *,
                      band_hz: tuple[float, float], window: str, detrend: str, zero_pad: int,
                      refine: bool, tol_hz: float
                      ) -> tuple[list[float], list[float], list[float]] | None:
    """Two passes of spectral peaks and their refinement for two records, in one call.

    The first pass reads ``first``, the records less their fit on the basis with the tone at
    ``start_hz``; the second the records less their fit with the tone at the mean of the
    first pass's peaks; then each record's second peak is refined (when ``refine``).

    Parameters
    ----------
    first : ndarray
        ``(n, 2)`` records less their fit at ``start_hz`` (C order, float64), any unit.
    start_hz : float
        The frequency of ``first``'s tone [Hz].
    qt, r_y, qy : ndarray
        ``Q'`` of an orthonormal basis (``p x n``), the records less their projection on it
        (``n x 2``) and ``Q'r_y``, as :func:`~torquemod.dsp.projection.removal_at_tone`
        takes them.
    fs_hz : float
        Sample rate [Hz].
    orders : ndarray
        int64 orders of the tone (1 and its harmonics) [-].
    band_hz, window, detrend, zero_pad
        As :func:`~torquemod.dsp.spectrum.peak_frequencies` (band [Hz]).
    refine : bool
        Whether to refine the second peaks.
    tol_hz : float
        Step below which a refinement stops [Hz]
        (:func:`~torquemod.dsp.tonesearch.refine_peaks`).

    Returns
    -------
    tuple of list of float or None
        The first pass's peaks, the second's and the refined ones (the second's without
        ``refine``) [Hz], each as those functions one after the other give them; None
        where one of them would go another way than its compiled one (a column without
        its line, another window, another layout, the first peaks' mean at ``start_hz``):
        the caller then takes them one by one.
    """
    n = first.shape[0] if first.ndim == 2 else 0
    blas, gesv = numpyblas.addresses(), numpyblas.gesv_address()
    if (blas is None or gesv is None or n < 2 or first.shape[1] != 2
            or not isinstance(window, str) or type(zero_pad) is not int):
        return None
    for a in (first, qt, r_y, qy):
        if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 2 or a.dtype != np.float64 \
                or not a.flags.c_contiguous:
            return None
    plan = _batch_plan(n, fs_hz, *band_hz, window, detrend == "linear", zero_pad)
    if plan is None or r_y.shape != (n, 2):
        return None
    status, peaks = _search_kernel(
        first, float(start_hz), qt, r_y, qy, float(fs_hz), n / fs_hz,
        np.asarray(orders, dtype=np.int64), bool(refine), float(tol_hz), blas[0], blas[1],
        gesv, _XTOL_HZ, _MIN_RATIO, _MAXFUN, *plan)
    if status != 0:
        return None
    p1, p2, refined = peaks.tolist()  # (Python floats, the same numbers)
    return p1, p2, refined
