"""Step 6 of the V-Track chain: align cycles by the unbiased cross-correlation."""

from __future__ import annotations

import numpy as np
from scipy import signal


def unbiased_xcorr(x: np.ndarray, y: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Unbiased cross-correlation, as MATLAB's ``xcorr(x, y, maxlag, 'unbiased')``.

    ``r[k] = sum_n x[n+k]*y[n] / M(k)`` for |k| <= max_lag, M(k) the number of overlapping
    samples at lag k (``N - |k|`` for equal lengths).

    Parameters
    ----------
    x, y : ndarray
        The signals.
    max_lag : int
        Largest |lag| [samples].

    Returns
    -------
    lags : ndarray of int
        The lags [samples].
    r : ndarray
        The correlation, unit of x times unit of y.

    Examples
    --------
    >>> import numpy as np
    >>> lags, r = unbiased_xcorr(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]), 1)
    >>> lags.tolist(), r.tolist()
    ([-1, 0, 1], [4.0, 4.666666666666667, 4.0])
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    full = signal.correlate(x, y, mode="full")
    lags = signal.correlation_lags(x.size, y.size, mode="full")
    overlap = signal.correlate(np.ones(x.size), np.ones(y.size), mode="full")
    keep = np.abs(lags) <= max_lag
    return lags[keep], full[keep] / np.round(overlap[keep])


def alignment_lag(reference: np.ndarray, other: np.ndarray, max_lag: int) -> int:
    """The lag that maximises the unbiased cross-correlation of two signals.

    ``other[n]`` best matches ``reference[n - k]``, i.e. ``other`` shifted left by k
    (``other[n + k]``) aligns with ``reference[n]``.

    Parameters
    ----------
    reference : ndarray
        The reference signal.
    other : ndarray
        The signal to align.
    max_lag : int
        Largest |lag| searched [samples].

    Returns
    -------
    int
        k [samples].

    Examples
    --------
    >>> import numpy as np
    >>> x = np.sin(np.arange(200) / 7.0)
    >>> alignment_lag(x[5:105], x[:100], 20)
    5
    """
    lags, r = unbiased_xcorr(other, reference, max_lag)
    return int(lags[np.argmax(r)])
