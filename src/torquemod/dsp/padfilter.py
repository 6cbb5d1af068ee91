"""Steps 3-5 of the V-Track chain on two records in one compiled call: each record less its
line, extended at both ends by the model of its stationary tones
(:func:`torquemod.dsp.tonemodel.model_padded_rows`), the first record through its own
zero-phase filters (the wheel speed's notches), then both through the common ones (the
high- and band-pass) (:func:`torquemod.dsp.filters.zero_phase_cascade`).
"""

from __future__ import annotations

import numba
import numpy as np

from torquemod.dsp import filters, tonemodel
from torquemod.dsp.filters import _filtfilt_rows, _steady_state_solve
from torquemod.dsp.lstsq import _DPOTRS, LstsqFactor, _solve
from torquemod.dsp.tonemodel import _fill_cos_sin, _line_and_tones_design


def padded_and_filtered(first: np.ndarray, second: np.ndarray, fs_hz: float,
                        tones_hz: list[float], pad: int, first_filters: list, common_filters: list
                        ) -> tuple[np.ndarray, float, np.ndarray, float, np.ndarray]:
    """Two records padded by their tone model, the first through its own zero-phase
    filters, then both through the common ones.

    The same steps and the same arithmetic as :func:`~torquemod.dsp.tonemodel.
    model_padded_rows` followed by :func:`~torquemod.dsp.filters.zero_phase_cascade` on the
    first record with ``first_filters`` and on both with ``common_filters``
    (:func:`padded_and_filtered_reference`), in one compiled call; the tone model's
    padding comes from a compiled matrix-vector product instead of numpy's, so the padding
    may differ from that route's in the last bits (tests/dsp/test_padfilter.py).

    Parameters
    ----------
    first, second : ndarray
        Records of equal length, any unit each.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        The stationary tones [Hz].
    pad : int
        Samples added at each end [-].
    first_filters, common_filters : list of tuple of ndarray
        (b, a) of each filter, in order.

    Returns
    -------
    first_padded : ndarray
        The first record, padded, less its line, through its own filters.
    first_level : float
        Its line's mean [its unit].
    second_padded : ndarray
        The second record, padded, less its line.
    second_level : float
        Its line's mean.
    both_filtered : ndarray
        ``(2, n + 2*pad)``: the two padded records through the common filters.
    """
    rows = np.vstack([first, second]).astype(np.float64, copy=False)
    n = rows.shape[1]
    design, kept = _line_and_tones_design(n, fs_hz, tones_hz)
    fac = LstsqFactor.of(design)
    packed = _packed([*first_filters, *common_filters])
    if fac is None or not fac.dn.flags.c_contiguous or packed is None or pad < 0:
        return padded_and_filtered_reference(first, second, fs_hz, tones_hz, pad,
                                             first_filters, common_filters)
    padded, levels, both = _pad_and_filter(
        rows, fac.dn, np.asfortranarray(fac.factor), fac.scale, np.ascontiguousarray(
            design[:, 1]), 2 * np.pi * np.array(kept, dtype=np.float64) / fs_hz, int(pad),
        *packed, len(first_filters), _DPOTRS)
    return padded[0], float(levels[0]), padded[1], float(levels[1]), both


def padded_and_filtered_reference(first: np.ndarray, second: np.ndarray, fs_hz: float,
                                  tones_hz: list[float], pad: int, first_filters: list,
                                  common_filters: list
                                  ) -> tuple[np.ndarray, float, np.ndarray, float, np.ndarray]:
    """:func:`padded_and_filtered` by :func:`~torquemod.dsp.tonemodel.model_padded_rows` and
    :func:`~torquemod.dsp.filters.zero_phase_cascade`, one after the other.

    Parameters
    ----------
    first, second : ndarray
        Records of equal length, any unit each.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        The stationary tones [Hz].
    pad : int
        Samples added at each end [-].
    first_filters, common_filters : list of tuple of ndarray
        (b, a) of each filter, in order.

    Returns
    -------
    first_padded, first_level, second_padded, second_level, both_filtered
        As :func:`padded_and_filtered` (the records' units; ``both_filtered`` is
        ``(2, n + 2*pad)``).
    """
    (p1, level1, _), (p2, level2, _) = tonemodel.model_padded_rows([first, second], fs_hz,
                                                                   tones_hz, pad)
    p1 = filters.zero_phase_cascade(first_filters, p1)
    both = filters.zero_phase_cascade(common_filters, np.vstack([p1, p2]))
    return p1, level1, p2, level2, both


def _packed(filters_ba: list) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The filters' ``b`` and ``a`` as rows of two arrays (zero-padded) and each filter's
    length; None where a filter is not of the compiled kind (``a[0] = 1``, ``b`` and ``a``
    of one length, at least 2)."""
    size = 2
    for b, a in filters_ba:
        if np.ndim(b) != 1 or np.ndim(a) != 1 or len(b) != len(a) or len(b) < 2 \
                or a[0] != 1.0:
            return None
        size = max(size, len(b))
    bs = np.zeros((len(filters_ba), size))
    as_ = np.zeros((len(filters_ba), size))
    lengths = np.empty(len(filters_ba), dtype=np.int64)
    for i, (b, a) in enumerate(filters_ba):
        bs[i, :len(b)] = b
        as_[i, :len(a)] = a
        lengths[i] = len(b)
    return bs, as_, lengths


@numba.njit(cache=True, nogil=True)
def _pad_and_filter(rows: np.ndarray, dn: np.ndarray, factor: np.ndarray, scale: np.ndarray,
                    line: np.ndarray, omegas: np.ndarray, pad: int, bs: np.ndarray,
                    as_: np.ndarray, lengths: np.ndarray, n_first: int, potrs: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`padded_and_filtered` on the rows of ``rows``: the line and tones fitted by
    the compiled solve (:func:`~torquemod.dsp.lstsq._solve`, the route of
    ``LstsqFactor.solve`` for a contiguous record), the tones over the padded times by
    :func:`~torquemod.dsp.tonemodel._fill_cos_sin`, each filter by
    :func:`~torquemod.dsp.filters._filtfilt_rows` from the steady state of
    :func:`~torquemod.dsp.filters._steady_state_solve` (``lfilter_zi``'s numbers; the
    second- and fourth-order ones with their state in registers, two rows at a time):
    ``(padded, levels, both_filtered)``."""
    n_rows, n = rows.shape
    total = n + 2 * pad
    k = omegas.size
    trig = np.empty((total, 2 * k))
    _fill_cos_sin(trig, 0, omegas, -pad)
    padded = np.zeros((n_rows, total))
    levels = np.empty(n_rows)
    for r in range(n_rows):
        x = np.ascontiguousarray(rows[r])
        coef = _solve(dn, factor, scale, x, potrs)
        if k:
            padded[r] = np.dot(trig, np.ascontiguousarray(coef[2:]))
        for i in range(n):
            padded[r, pad + i] = x[i] - coef[0] - coef[1] * line[i]
        levels[r] = coef[0]
    both = padded  # (the first row's own filters act on it before the copy below)
    for f in range(lengths.size):
        m = lengths[f]
        b = bs[f, :m].copy()
        a = as_[f, :m].copy()
        if f == n_first:  # then both rows through the common ones
            both = padded.copy()
        _filtfilt_rows(b, a, _steady_state_solve(b, a), padded[:1] if f < n_first else both)
    if n_first == lengths.size:
        both = padded.copy()
    return padded, levels, both
