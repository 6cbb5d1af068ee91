"""Steps 3-5 of the V-Track chain on two records in one compiled call: each record less its
line, extended at both ends by the model of its stationary tones
(:func:`torquemod.dsp.tonemodel.model_padded_rows`), the first record through its own
zero-phase filters (the wheel speed's notches), then both through the common ones (the
high- and band-pass) (:func:`torquemod.dsp.filters.zero_phase_cascade`).
"""

from __future__ import annotations

import cmath
import functools
import math

import numba
import numpy as np

from torquemod.dsp import filters, numpyblas, tonemodel
from torquemod.dsp.filters import (
    _filtfilt_rows,
    _settling_kernel,
    _steady_state,
    _steady_state_solve,
)
from torquemod.dsp.lstsq import _DPOTRF, _DPOTRS, LstsqFactor, _factor_of, _solve
from torquemod.dsp.tonemodel import (
    _fill_cos_sin,
    _line_and_tones_design,
    line_and_tones_design_compiled,
)

#: :func:`~torquemod.dsp.filters.settling_samples`' defaults: the share of the impulse
#: response's peak [-] and the longest response searched [samples].
_SETTLING_TOL = 1e-6
_SETTLING_MAX = 1_000_000


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
        levels[r] = _pad_record(np.ascontiguousarray(rows[r]), dn, factor, scale, trig, line,
                                pad, potrs, padded[r])
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


@numba.njit(cache=True, nogil=True)
def _pad_record(x: np.ndarray, dn: np.ndarray, factor: np.ndarray, scale: np.ndarray,
                trig: np.ndarray, line: np.ndarray, pad: int, potrs: int, out: np.ndarray
                ) -> float:
    """Record ``x`` less its fitted line, padded by ``pad`` samples at each end with its
    fitted tones, into ``out`` (``n + 2 pad``): the line and tones by the compiled solve
    (:func:`~torquemod.dsp.lstsq._solve`), the tones over the padded times from ``trig``;
    returns the line's level (its mean) [x's unit]."""
    coef = _solve(dn, factor, scale, x, potrs)
    if trig.shape[1]:
        out[:] = np.dot(trig, np.ascontiguousarray(coef[2:]))
    for i in range(x.size):
        out[pad + i] = x[i] - coef[0] - coef[1] * line[i]
    return coef[0]


def chain_filtered(first: np.ndarray, second: np.ndarray, fs_hz: float, f_mod_hz: float,
                   notches_hz: list[float], notch_q: float,
                   highpass: tuple[float, int], bandpass: tuple[float, int],
                   offsets: tuple[float, float], *, first_less: tuple = (),
                   second_less: tuple = ()
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Steps 3-5 of the V-Track chain [1]_ on two records, designs and padding included.

    The notches at ``notches_hz`` (:func:`~torquemod.dsp.filters.design_notch`) and the
    band-pass around ``f_mod_hz`` (:func:`~torquemod.dsp.filters.design_bandpass`), the
    padding as the longest settling of any filter
    (:func:`~torquemod.dsp.filters.settling_samples`), then :func:`padded_and_filtered` with
    the tones ``[f_mod_hz, *notches_hz]``, the notches on the first record and the
    high- and band-pass on both; the records cut back to their own samples, the notched
    ones with their line's level and ``offsets`` added back. One compiled call
    (:func:`_chain_filtered_kernel`) with the same arithmetic as those steps one after the
    other (:func:`chain_filtered_reference`, tests/dsp/test_padfilter.py); that route where
    the compiled one cannot follow it (a least-squares design :meth:`LstsqFactor.of
    <torquemod.dsp.lstsq.LstsqFactor.of>` leaves to the SVD, numpy's BLAS not found).

    Parameters
    ----------
    first, second : ndarray
        Records of equal length (the wheel speed and the torque), any unit each.
    fs_hz : float
        Sample rate [Hz].
    f_mod_hz : float
        Modulation frequency [Hz], a tone of the padding model.
    notches_hz : list of float
        Frequencies of the first record's notches [Hz], each also a tone of the padding.
    notch_q : float
        The notches' quality factor [-].
    highpass : tuple of (float, int)
        The high-pass's cut-off [Hz] and order [-]
        (:func:`~torquemod.dsp.filters.design_highpass`).
    bandpass : tuple of (float, int)
        The band-pass's width [Hz] and prototype order [-], centred on ``f_mod_hz``.
    offsets : tuple of float
        Added to each notched record [its unit].
    first_less, second_less : tuple of ndarray
        Records subtracted from each first, in order (the speed model's slow part, orders
        and harmonics): ``first - p1 - p2 - ...``, numpy's numbers. Default none.

    Returns
    -------
    first_notched, second_notched : ndarray
        The records after their own filters, plus their line's level and offset.
    filtered : ndarray
        ``(2, n)``: both through the high- and band-pass.
    pad : int
        The padding used at each end [samples].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """
    first, first_less = _with_parts(first, first_less)
    second, second_less = _with_parts(second, second_less)
    hp = _highpass_parts(float(highpass[0]), int(highpass[1]), float(fs_hz))
    order = int(bandpass[1])
    lo, hi = filters.bandpass_edges(f_mod_hz, bandpass[0], fs_hz)  # (its ValueError)
    blas = numpyblas.addresses()
    if hp is not None and blas is not None and first.size == second.size >= 2 and order >= 1:
        status, pad, notched, filtered = _chain_filtered_kernel(
            first, first_less, second, second_less, float(fs_hz), float(f_mod_hz),
            np.array(notches_hz, dtype=np.float64), float(notch_q), *hp, order, lo, hi,
            bandpass_gain(order, lo, hi), float(offsets[0]), float(offsets[1]),
            blas[0], _DPOTRF, _DPOTRS)
        if status == 0:
            return notched[0], notched[1], filtered, int(pad)
    return chain_filtered_reference(first, second, fs_hz, f_mod_hz, notches_hz, notch_q,
                                    highpass, bandpass, offsets, first_less=first_less,
                                    second_less=second_less)


def chain_filtered_reference(first: np.ndarray, second: np.ndarray, fs_hz: float,
                             f_mod_hz: float, notches_hz: list[float], notch_q: float,
                             highpass: tuple[float, int], bandpass: tuple[float, int],
                             offsets: tuple[float, float], *, first_less: tuple = (),
                             second_less: tuple = ()
                             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """:func:`chain_filtered` by the designs, :func:`~torquemod.dsp.filters.settling_samples`
    and :func:`padded_and_filtered_reference`, one after the other.

    Parameters
    ----------
    first, second : ndarray
        Records of equal length, any unit each.
    fs_hz : float
        Sample rate [Hz].
    f_mod_hz : float
        Modulation frequency [Hz].
    notches_hz : list of float
        The first record's notches [Hz].
    notch_q : float
        Their quality factor [-].
    highpass : tuple of (float, int)
        Cut-off [Hz] and order [-] of the high-pass.
    bandpass : tuple of (float, int)
        Width [Hz] and prototype order [-] of the band-pass around ``f_mod_hz``.
    offsets : tuple of float
        Added to each notched record [its unit].
    first_less, second_less : tuple of ndarray
        Records subtracted from each first, in order. Default none.

    Returns
    -------
    first_notched, second_notched, filtered, pad
        As :func:`chain_filtered`.
    """
    for p in first_less:
        first = first - p
    for p in second_less:
        second = second - p
    hp = filters.design_highpass(highpass[0], highpass[1], fs_hz)
    bp = filters.design_bandpass(f_mod_hz, bandpass[0], bandpass[1], fs_hz)
    notches = [filters.design_notch(f0, notch_q, fs_hz) for f0 in notches_hz]
    pad = max(filters.settling_samples(ba) for ba in [hp, bp, *notches])
    n = len(first)
    p1, level1, p2, level2, both = padded_and_filtered_reference(
        first, second, fs_hz, [f_mod_hz, *notches_hz], pad, notches, [hp, bp])
    return (p1[pad:pad + n] + level1 + offsets[0], p2[pad:pad + n] + level2 + offsets[1],
            np.ascontiguousarray(both[:, pad:pad + n]), pad)


def _with_parts(record: np.ndarray, less: tuple) -> tuple[np.ndarray, tuple]:
    """A record and the parts subtracted from it as the compiled call takes them: float64
    and contiguous, the parts a tuple of arrays of one kind (all read-only or all not) and
    the record's length; otherwise the record less its parts by numpy, and one part of
    zeros (subtracting 0.0 changes no number)."""
    record = np.ascontiguousarray(record, dtype=np.float64)
    parts = tuple([np.ascontiguousarray(p, dtype=np.float64) for p in less])
    if parts and all(p.shape == record.shape for p in parts) \
            and len({p.flags.writeable for p in parts}) == 1:
        return record, parts
    for p in parts:
        record = record - p
    return record, (np.zeros(record.shape),)


@numba.njit(cache=True, nogil=True)
def _less(record: np.ndarray, parts: tuple) -> np.ndarray:
    """``record - parts[0] - parts[1] - ...`` element by element in that order (numpy's
    numbers for the same subtractions one array after another)."""
    out = np.empty(record.size)
    for i in range(record.size):
        v = record[i]
        for p in parts:
            v = v - p[i]
        out[i] = v
    return out


@functools.lru_cache(maxsize=16)
def _highpass_parts(cutoff_hz: float, order: int, fs_hz: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
    """The high-pass's ``b``, ``a``, steady state (``lfilter_zi``'s numbers) and settling
    [samples], cached (configuration, not measurements); None where the design is not of
    the compiled kind (``a[0] = 1``, ``b`` and ``a`` of one length)."""
    b, a = filters.design_highpass(cutoff_hz, order, fs_hz)
    if not (b.ndim == 1 and b.size == a.size >= 2 and a[0] == 1.0):
        return None
    b, a = np.array(b, dtype=np.float64), np.array(a, dtype=np.float64)
    zi = _steady_state(b, a)
    settle = int(_settling_kernel(b, a, _SETTLING_TOL, _SETTLING_MAX))
    for arr in (b, a, zi):  # shared by every later call (and thread): read only
        arr.setflags(write=False)
    return b, a, zi, settle


def bandpass_gain(order: int, lo: float, hi: float) -> float:
    """The gain ``bw**order`` of :func:`~torquemod.dsp.filters.design_bandpass`'s route
    by its arithmetic, for :func:`_butter_bandpass_compiled`: Python's power, which
    compiled code forms otherwise for a whole exponent (another last bit).

    Parameters
    ----------
    order : int
        The prototype's order [-].
    lo, hi : float
        Band edges [cycles per sample] (:func:`~torquemod.dsp.filters.bandpass_edges`).

    Returns
    -------
    float
        ``bw**order``, ``bw = 4*tan(pi*hi) - 4*tan(pi*lo)`` the band width pre-warped for
        the bilinear transform at fs = 2 [-].
    """
    return (4.0 * math.tan(math.pi * hi) - 4.0 * math.tan(math.pi * lo)) ** order


@numba.njit(cache=True, nogil=True)
def _butter_bandpass_compiled(order: int, lo: float, hi: float, gain: float
                              ) -> tuple[np.ndarray, np.ndarray]:
    """``filters._butter_bandpass`` (Butterworth prototype poles, low-pass to band-pass,
    bilinear transform with pre-warped edges, polynomial expansion) in compiled code with
    the same complex arithmetic: numba's complex products, quotients, ``exp`` and ``sqrt``
    follow CPython's, the same bits over 1e5 random designs of orders 1-4
    (tests/dsp/test_padfilter.py); ``gain`` from :func:`bandpass_gain`."""
    w1, w2 = 4.0 * math.tan(math.pi * lo), 4.0 * math.tan(math.pi * hi)
    bw, wo2 = w2 - w1, w1 * w2
    poles = np.empty(2 * order, dtype=np.complex128)
    i = 0
    for m in range(-order + 1, order, 2):
        p = -cmath.exp(1j * math.pi * m / (2 * order)) * bw / 2
        root = cmath.sqrt(p * p - wo2)
        poles[i] = p + root
        poles[i + 1] = p - root
        i += 2
    den = 1.0 + 0j
    a = np.zeros(2 * order + 1, dtype=np.complex128)
    a[0] = 1.0
    for length in range(1, 2 * order + 1):  # a[:length] holds the product so far
        p = poles[length - 1]
        den *= 4.0 - p
        z = (4.0 + p) / (4.0 - p)
        for j in range(length, 0, -1):  # a <- [*a, 0] - z*[0, *a], from the top down
            a[j] = (a[j] if j < length else 0j) - z * a[j - 1]
        a[0] = a[0] - z * 0j
    k = gain * (4.0 ** order / den).real
    b = np.zeros(2 * order + 1)
    comb = 1
    for j in range(order + 1):
        b[2 * j] = k * comb * (-1) ** j
        comb = comb * (order - j) // (j + 1)
    return b, a.real.copy()


@numba.njit(cache=True, nogil=True)
def _notch_design(f0_hz: float, q: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """:func:`~torquemod.dsp.filters.design_notch`'s arithmetic (Orfanidis's second-order
    notch) in compiled code: ``(b, a, ok)``, ``ok`` False outside ``0 <= w0 <= 1``."""
    w0 = 2 * f0_hz / fs_hz
    if w0 > 1.0 or w0 < 0.0 or not fs_hz > 0:
        return np.zeros(3), np.zeros(3), False
    bw = w0 / q * math.pi
    w0 = w0 * math.pi
    gain = 1.0 / (1.0 + math.tan(bw / 2.0))
    b = np.array([gain * 1.0, gain * (-2.0 * math.cos(w0)), gain * 1.0])
    a = np.array([1.0, -2.0 * gain * math.cos(w0), 2.0 * gain - 1.0])
    return b, a, True


@numba.njit(cache=True, nogil=True)
def _fill_cos_sin_together(out: np.ndarray, col0: int, omegas: np.ndarray, start: int) -> None:
    """:func:`~torquemod.dsp.tonemodel._fill_cos_sin` with up to four tones advancing
    together (:func:`~torquemod.dsp.tonemodel.fill_tones_together`, the same bits): the
    cos and sin of ``omegas[m]*(start + i)`` [rad per sample]."""
    tonemodel.fill_tones_together(out, col0, omegas, float(start), 1.0)


@numba.njit(cache=True, nogil=True)
def _chain_filtered_kernel(first_record: np.ndarray, first_less: tuple,
                           second_record: np.ndarray, second_less: tuple, fs_hz: float,
                           f_mod_hz: float, notches_hz: np.ndarray, q: float,
                           hp_b: np.ndarray, hp_a: np.ndarray, hp_zi: np.ndarray,
                           hp_settle: int, bp_order: int, bp_lo: float, bp_hi: float,
                           bp_gain: float, offset_first: float, offset_second: float,
                           syrk: int, potrf: int, potrs: int
                           ) -> tuple[int, int, np.ndarray, np.ndarray]:
    """:func:`chain_filtered` in one call: ``(status, pad, notched, filtered)``, status 0,
    or not 0 where the reference route must run. The notches by :func:`_notch_design`, the
    band-pass by :func:`_butter_bandpass_compiled`, the settling of
    each filter by :func:`~torquemod.dsp.filters._settling_kernel`, the line-and-tones
    design of :func:`~torquemod.dsp.tonemodel.line_and_tones_design_compiled` and its
    factor as
    :meth:`LstsqFactor.of <torquemod.dsp.lstsq.LstsqFactor.of>`
    (:func:`~torquemod.dsp.lstsq._factor_of`), then :func:`_pad_and_filter`'s steps; each
    record less its parts first (:func:`_less`)."""
    first = _less(first_record, first_less)
    second = _less(second_record, second_less)
    n = first.size
    k_notch = notches_hz.size
    nb = np.empty((k_notch, 3))
    na = np.empty((k_notch, 3))
    pad = hp_settle
    for j in range(k_notch):
        b, a, ok = _notch_design(notches_hz[j], q, fs_hz)
        if not ok:
            return 1, 0, np.empty((0, 0)), np.empty((0, 0))
        nb[j] = b
        na[j] = a
        pad = max(pad, _settling_kernel(b, a, 1e-6, 1_000_000))
    bp_b, bp_a = _butter_bandpass_compiled(bp_order, bp_lo, bp_hi, bp_gain)
    pad = max(pad, _settling_kernel(bp_b, bp_a, 1e-6, 1_000_000))
    tones = np.empty(1 + k_notch)
    tones[0] = f_mod_hz
    tones[1:] = notches_hz
    design, _, omegas = line_and_tones_design_compiled(n, fs_hz, tones)
    k = omegas.size
    dn, scale, _, factor, status = _factor_of(design, syrk, potrf)
    if status != 0:
        return 2, 0, np.empty((0, 0)), np.empty((0, 0))
    total = n + 2 * pad
    trig = np.empty((total, 2 * k))
    _fill_cos_sin_together(trig, 0, omegas, -pad)
    padded = np.zeros((2, total))
    levels = np.empty(2)
    line = np.ascontiguousarray(design[:, 1])
    for r in range(2):
        levels[r] = _pad_record(first if r == 0 else second, dn, factor, scale, trig, line,
                                pad, potrs, padded[r])
    notched = np.empty((2, n))
    filtered = np.empty((2, n))
    for j in range(k_notch):  # the first record through its notches
        b = nb[j].copy()
        a = na[j].copy()
        _filtfilt_rows(b, a, _steady_state_solve(b, a), padded[:1])
    offsets = (offset_first, offset_second)
    for r in range(2):
        for i in range(n):
            notched[r, i] = padded[r, pad + i] + levels[r] + offsets[r]
    _filtfilt_rows(hp_b, hp_a, hp_zi, padded)  # then both through the high- and band-pass
    _filtfilt_rows(bp_b, bp_a, _steady_state_solve(bp_b, bp_a), padded)
    filtered[:, :] = padded[:, pad:pad + n]
    return 0, pad, notched, filtered
