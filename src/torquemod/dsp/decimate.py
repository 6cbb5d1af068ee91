"""Step 2's decimation kernels: ``resample_poly``'s FIR design and the two-stage decimator:
both stages in numba, one row at a time (:func:`torquemod.dsp.filters.resample`
and :func:`~torquemod.dsp.filters.resample_rows` are the entry points).
"""

from __future__ import annotations

import functools

import numba
import numpy as np
from scipy import signal


@functools.lru_cache(maxsize=16)
def _resampling_fir(up: int, down: int, kaiser_beta: float) -> np.ndarray:
    """The FIR ``resample_poly`` designs (10 zero crossings either side, Kaiser window)."""
    max_rate = max(up, down)
    half_len = 10 * max_rate
    h = signal.firwin(2 * half_len + 1, 1.0 / max_rate, window=("kaiser", kaiser_beta))
    return h  # resample_poly scales a given FIR by up itself


# Two-stage decimation. Stage 1 keeps 0..f_pass flat to STAGE1_RIPPLE (so the
# amplitude at the modulation frequency moves by less than the phase target of 1e-4 deg,
# 1.7e-6 rad, would allow) and stops everything that would alias into 0..f_pass + stage 2's
# transition; stage 2 is resample_poly's own design for the remaining ratio.
STAGE1_RIPPLE_DB = 120.0
STAGE1_MIN_OVERSAMPLING = 8.0  # stage-1 output rate >= 8x the final rate


@functools.lru_cache(maxsize=16)
def two_stage_plan(up: int, down: int) -> tuple[int, int] | None:
    """``(q1, down2)``: the largest divisor ``q1`` of ``down`` leaving the stage-1 rate at
    least ``STAGE1_MIN_OVERSAMPLING`` times the final rate (``down/q1 >= 8*up``), and the
    remaining ``down2 = down // q1``; None when no divisor above 1 qualifies (2/625 gives 25,
    25: 16 670 Hz -> 666.8 Hz -> 53.344 Hz)."""
    best = None
    for q in range(2, down + 1):
        if down % q == 0 and down // q >= STAGE1_MIN_OVERSAMPLING * up:
            best = q
    return None if best is None else (best, down // best)


@functools.lru_cache(maxsize=16)
def stage1_fir(q1: int, up: int, down: int) -> np.ndarray:
    """Stage-1 low-pass (odd length, symmetric: zero phase about its centre) for decimating
    by ``q1`` before a final ``up/down`` resampling, in units of the input rate: pass band to
    the final Nyquist ``f_p = up/(2*down)``, stop band from ``1/q1 - 1.5*f_p`` (what would alias
    into the final band and stage 2's transition), Kaiser window for ``STAGE1_RIPPLE_DB``
    (Kaiser 1974 via ``scipy.signal.kaiserord``). 2/625 with q1 = 25 gives 215 taps."""
    f_p = up / (2.0 * down)
    f_s = 1.0 / q1 - 1.5 * f_p
    numtaps, beta = signal.kaiserord(STAGE1_RIPPLE_DB, 2.0 * (f_s - f_p))
    numtaps += 1 - numtaps % 2
    h = signal.firwin(numtaps, f_p + f_s, window=("kaiser", beta))  # cutoff rel. Nyquist
    h.setflags(write=False)
    return h


#: numba's fast-math flags for the decimation kernels: sums may be reordered (vectorised,
#: several partial sums) and multiply-adds fused; no assumption about NaN or infinity. The
#: outputs then differ from a strictly ordered sum by rounding only (measured 1.5e-15 of the
#: output's size on the benchmark's cycle), and the FIR runs 3-4x faster.
_FAST = {"reassoc", "contract"}


@numba.njit(cache=True, nogil=True, fastmath=_FAST)
def _fir_decimate_row(x: np.ndarray, offset: float, h: np.ndarray, q: int, y: np.ndarray
                      ) -> None:
    """``y[k] = sum_j h[j] (x[q*k + j - half] - offset)`` with zeros outside the record (a
    centred FIR, zero phase when ``h`` is symmetric, evaluated only at the kept samples)."""
    n = x.size
    taps = h.size
    half = (taps - 1) // 2
    for k in range(y.size):
        start = q * k - half
        acc = 0.0
        if start >= 0 and start + taps <= n:  # (a loop from 0 over a known count: LLVM
            for j in range(taps):  # vectorises it; general bounds would stay scalar, 7x slower)
                acc += h[j] * (x[start + j] - offset)
        else:
            for j in range(max(0, -start), min(taps, n - start)):
                acc += h[j] * (x[start + j] - offset)
        y[k] = acc


@numba.njit(cache=True, nogil=True, fastmath=_FAST)
def _upfirdn_centred_row(x: np.ndarray, phases: np.ndarray, taps: int, up: int, down: int,
                         y: np.ndarray) -> None:
    """``y[m] = sum_i x[i] h[half + m*down - i*up]`` (zeros outside the record and the
    filter): ``resample_poly(x, up, down, window=h, padtype="constant")``'s output ``m``,
    computed directly. ``phases`` holds the reversed filter ``h[::-1]`` (``taps`` long,
    already scaled by ``up`` as ``resample_poly`` scales it) split into its ``up``
    polyphase components, zero-padded (:func:`_stage2_phases`), so every sum runs forward
    over contiguous memory."""
    n = x.size
    half = (taps - 1) // 2
    for m in range(y.size):
        p = half + m * down  # filter index of input sample 0
        i_lo = max(0, (p - taps + up) // up)  # first i with p - i*up < taps
        i_hi = min(n - 1, p // up)
        acc = 0.0
        if i_hi >= i_lo:
            base = taps - 1 - p + i_lo * up  # index into h[::-1] of input sample i_lo
            xs = x[i_lo:i_hi + 1]
            hs = phases[base % up, base // up:base // up + xs.size]
            for t in range(xs.size):
                acc += hs[t] * xs[t]
        y[m] = acc


@numba.njit(cache=True, nogil=True)
def _fir_decimate(x: np.ndarray, h: np.ndarray, q: int) -> np.ndarray:
    """``y[c, k] = sum_j h[j] x[c, q*k + j - half]`` with zeros outside the record: a
    centred (zero-phase) symmetric FIR evaluated only at the kept samples."""
    n_ch, n = x.shape
    y = np.zeros((n_ch, (n - 1) // q + 1))
    for c in range(n_ch):
        _fir_decimate_row(x[c], 0.0, h, q, y[c])
    return y


@numba.njit(cache=True, nogil=True)
def _two_stage_row(x: np.ndarray, offset: float, h1: np.ndarray, q1: int,
                   phases2: np.ndarray, taps2: int, up: int, down2: int, y: np.ndarray) -> None:
    """Both stages of :func:`decimate_two_stage` on one row less ``offset``, into ``y``
    (as many outputs as ``y`` holds), plus ``offset`` restored."""
    y1 = np.empty((x.size - 1) // q1 + 1)
    _fir_decimate_row(x, offset, h1, q1, y1)
    _upfirdn_centred_row(y1, phases2, taps2, up, down2, y)
    for m in range(y.size):
        y[m] += offset


@functools.lru_cache(maxsize=16)
def _stage2_phases(up: int, down2: int, kaiser_beta: float) -> tuple[np.ndarray, int]:
    """Stage 2's FIR (``resample_poly``'s own design for ``up/down2``, times ``up`` as
    ``resample_poly`` scales it), reversed and split into its ``up`` polyphase components
    ``phases[r, t] = h[::-1][r + t*up]`` (zero-padded), and its length; read-only."""
    h = (_resampling_fir(up, down2, kaiser_beta) * up)[::-1]
    per = -(-h.size // up)
    phases = np.zeros((up, per))
    for r in range(up):
        part = h[r::up]
        phases[r, :part.size] = part
    phases.setflags(write=False)
    return phases, h.size


def _two_stage_rows(rows: list[np.ndarray], offsets: np.ndarray, up: int, down: int,
                    kaiser_beta: float) -> np.ndarray:
    """:func:`decimate_two_stage` (zero padding) of each row less its offset [its unit], the
    offset added back: ``(len(rows), ceil(n*up/down))``. The rows need not be stacked."""
    q1, down2 = two_stage_plan(up, down)
    n = rows[0].size
    out = np.empty((len(rows), -(-n * up // down)))
    h1 = stage1_fir(q1, up, down)
    phases2, taps2 = _stage2_phases(up, down2, float(kaiser_beta))
    for r, off, y in zip(rows, offsets, out, strict=True):
        if r.size != n:
            raise ValueError("rows of different lengths")
        _two_stage_row(np.ascontiguousarray(r, dtype=np.float64), float(off), h1, q1, phases2,
                       taps2, up, down2, y)
    return out


def decimate_two_stage(x: np.ndarray, up: int, down: int, *, kaiser_beta: float = 5.0,
                       line: bool = False) -> np.ndarray:
    """Resample rows by ``up/down`` in two stages, the same output samples as one stage.

    :func:`stage1_fir` decimating by the integer ``q1`` of :func:`two_stage_plan`, then
    ``resample_poly(up, down2)``'s arithmetic with its own Kaiser design, both with zero
    padding and both in numba, row by row (the sums are those of ``resample_poly``'s
    ``upfirdn``, in another order: rounding only). Output ``m`` sits at input sample
    ``m*down/up`` as with one-stage ``resample_poly``, and there are as many
    (``ceil(n*up/down)``).

    Parameters
    ----------
    x : ndarray
        Signal(s), any unit, along the last axis.
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].
    kaiser_beta : float
        Kaiser beta of the designs [-]. Default 5.
    line : bool
        Remove the line through the end samples before and restore it at the output times
        after (a symmetric FIR of unit DC gain passes a line unchanged), so a trend does not
        ring at the ends. Default False.

    Returns
    -------
    ndarray
        The resampled signal(s), same unit.

    Raises
    ------
    ValueError
        ``down`` has no integer first stage.
    """
    if two_stage_plan(up, down) is None:
        raise ValueError(f"no integer first stage for {up}/{down}")
    x = np.asarray(x, dtype=np.float64)
    shape = x.shape
    x2 = np.ascontiguousarray(x.reshape(-1, shape[-1]))
    n = x2.shape[1]
    n_out = -(-n * up // down)
    if line:
        t = np.arange(n) / max(n - 1, 1)
        slope = (x2[:, -1:] - x2[:, :1])
        x2 = x2 - x2[:, :1] - slope * t
    y = _two_stage_rows(list(x2), np.zeros(x2.shape[0]), up, down, kaiser_beta)
    if line:
        t_out = np.arange(n_out) * (down / up) / max(n - 1, 1)
        y = y + x[..., :1].reshape(-1, 1) + slope * t_out
    return y.reshape(*shape[:-1], n_out)
