"""Step 2 of the V-Track chain: rational resampling of a record to the processing rate, one
channel or many at once, and the samples its edges leave unreliable.
"""

from __future__ import annotations

import functools
from fractions import Fraction

import numpy as np
from scipy import signal

from torquemod.dsp.decimate import (
    _resampling_fir,
    _two_stage_rows,
    decimate_two_stage,
    two_stage_plan,
)


def resample_ratio(fs_in_hz: float, fs_target_hz: float, *, max_denominator: int = 1000
                   ) -> tuple[int, int]:
    """Integers (up, down) with ``fs_in*up/down`` closest to ``fs_target``.

    Cached: the same rates for every cycle of a run, and ``Fraction.limit_denominator``
    costs ~50 us.

    Parameters
    ----------
    fs_in_hz : float
        Input rate [Hz].
    fs_target_hz : float
        Wanted rate [Hz].
    max_denominator : int
        Largest ``down`` [-]. Default 1000.

    Returns
    -------
    tuple of int
        (up, down).

    Examples
    --------
    >>> resample_ratio(16670.0, 53.344)
    (2, 625)
    """
    return _resample_ratio(float(fs_in_hz), float(fs_target_hz), int(max_denominator))


@functools.lru_cache(maxsize=64)
def _resample_ratio(fs_in_hz: float, fs_target_hz: float, max_denominator: int
                    ) -> tuple[int, int]:
    frac = Fraction(fs_target_hz / fs_in_hz).limit_denominator(max_denominator)
    if frac.numerator == 0:
        raise ValueError(f"cannot resample {fs_in_hz} Hz to {fs_target_hz} Hz")
    return frac.numerator, frac.denominator


RESAMPLE_METHODS = ("polyphase", "two_stage")


def resample(x: np.ndarray, up: int, down: int, *, kaiser_beta: float = 5.0,
             method: str = "polyphase", padtype: str = "line") -> np.ndarray:
    """Polyphase resampling by ``up/down`` along the last axis.

    MATLAB ``resample`` equivalent, Kaiser beta 5; the FIR is designed once per ratio and
    cached. Each row's mean is removed before and restored after, and with
    ``padtype="line"`` the ends are padded along a line, so a DC offset or slow trend does
    not ring at the edges [1]_. ``padtype="constant"`` changes only the
    :func:`resampler_edge_samples` outputs at each end, which the chain cuts off, and saves
    the padding's cost. ``method="two_stage"`` gives the same output samples at the same
    times through a cheaper route (:func:`decimate_two_stage`: an integer decimation by a
    long Kaiser FIR first, then ``resample_poly``'s arithmetic for the rest of the ratio); it
    falls back to ``"polyphase"`` when ``down`` has no suitable integer factor.

    Parameters
    ----------
    x : ndarray
        Signal(s), any unit, resampled along the last axis.
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].
    kaiser_beta : float
        Kaiser window beta of the FIR [-]. Default 5 (MATLAB's ``resample``).
    method : {"polyphase", "two_stage"}
        The route; both give the same output samples. Default "polyphase".
    padtype : {"line", "constant"}
        Pad the ends along a line, or with zeros after the mean removal. Default "line".

    Returns
    -------
    ndarray
        The resampled signal(s), same unit.

    Raises
    ------
    ValueError
        An unknown ``method`` or ``padtype``.

    References
    ----------
    .. [1] F. Gustafsson, "Determining the initial states in forward-backward filtering",
       IEEE Trans. Signal Process. 44(4) (1996) 988-992.
    """
    if method not in RESAMPLE_METHODS:
        raise ValueError(f"unknown resampling method {method!r}; use one of {RESAMPLE_METHODS}")
    if padtype not in ("line", "constant"):
        raise ValueError(f"padtype must be 'line' or 'constant', got {padtype!r}")
    x = np.asarray(x, dtype=np.float64)
    m = x.mean(axis=-1, keepdims=True)
    if method == "two_stage" and padtype == "constant" and two_stage_plan(up, down):
        rows = x.reshape(-1, x.shape[-1])
        y = _two_stage_rows(list(rows), m.reshape(-1), up, down, kaiser_beta)
        return y.reshape(*x.shape[:-1], y.shape[-1])
    return _resample_centred(x - m, m, up, down, kaiser_beta, method, padtype)


def resample_rows(rows, up: int, down: int, *, kaiser_beta: float = 5.0,
                  method: str = "polyphase", padtype: str = "line", return_means: bool = False
                  ):
    """:func:`resample` of ``np.vstack(rows)`` without stacking them first.

    Each row's mean is removed while it is copied into the stacked array, which saves one
    pass over the data. The means are the same numbers ``resample`` removes (numpy sums each
    row the same way), so the output is bit-identical.

    Parameters
    ----------
    rows : sequence of ndarray
        Records of equal length, any unit.
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].
    kaiser_beta : float
        Kaiser window beta of the FIR [-]. Default 5 (MATLAB's ``resample``).
    method : {"polyphase", "two_stage"}
        The route; both give the same output samples. Default "polyphase".
    padtype : {"line", "constant"}
        Pad the ends along a line, or with zeros after the mean removal. Default "line".
    return_means : bool
        Also return the rows' means. Default False.

    Returns
    -------
    y : ndarray
        (n_rows, n_out) resampled rows.
    means : ndarray
        ``np.mean(row)`` of each row (float64), only with ``return_means``.

    Raises
    ------
    ValueError
        An unknown ``method`` or ``padtype``.
    """
    if method not in RESAMPLE_METHODS:
        raise ValueError(f"unknown resampling method {method!r}; use one of {RESAMPLE_METHODS}")
    if padtype not in ("line", "constant"):
        raise ValueError(f"padtype must be 'line' or 'constant', got {padtype!r}")
    rows = [np.asarray(r, dtype=np.float64) for r in rows]
    if method == "two_stage" and padtype == "constant" and two_stage_plan(up, down):
        # the means removed inside the numba kernel, row by row: no stacked copy at all
        m = np.array([r.mean() for r in rows])
        y = _two_stage_rows(rows, m, up, down, kaiser_beta)
        return (y, m) if return_means else y
    xc = np.empty((len(rows), rows[0].size))
    m = np.empty((len(rows), 1))
    for i, r in enumerate(rows):
        m[i, 0] = r.mean()
        np.subtract(r, m[i, 0], out=xc[i])
    y = _resample_centred(xc, m, up, down, kaiser_beta, method, padtype)
    return (y, m[:, 0]) if return_means else y


def _resample_centred(xc: np.ndarray, m: np.ndarray, up: int, down: int, kaiser_beta: float,
                      method: str, padtype: str) -> np.ndarray:
    """Resample mean-free rows ``xc`` and add their means ``m`` back (see :func:`resample`)."""
    if method == "two_stage":
        plan = two_stage_plan(up, down)
        if plan is not None:
            return decimate_two_stage(xc, up, down, kaiser_beta=kaiser_beta,
                                      line=padtype == "line") + m
    y = signal.resample_poly(xc, up, down, axis=-1,
                             window=_resampling_fir(up, down, float(kaiser_beta)),
                             padtype=padtype)
    return y + m


def resampler_edge_samples(up: int, down: int) -> int:
    """Output samples at each end touched by the zero padding of :func:`resample`'s FIR.

    ``resample_poly`` uses ``10*max(up, down)`` taps either side of the centre at the
    upsampled rate; one output sample is ``down`` upsampled samples, so the FIR reaches
    ``ceil(10*max(up, down)/down)`` output samples into the padding (plus one of margin).

    Parameters
    ----------
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].

    Returns
    -------
    int
        Samples at each end.

    Examples
    --------
    >>> resampler_edge_samples(2, 625)
    11
    """
    half_taps = 10 * max(int(up), int(down))
    return -(-half_taps // int(down)) + 1  # (the ceiling in integers)
