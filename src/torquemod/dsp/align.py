"""Step 6 of the V-Track chain: align cycles by the unbiased cross-correlation."""

from __future__ import annotations

import numpy as np
from scipy import signal


def unbiased_xcorr(x: np.ndarray, y: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Unbiased cross-correlation ``r[k] = sum_n x[n+k]*y[n] / M(k)`` for |k| <= max_lag,
    where M(k) is the number of overlapping samples at lag k (``N - |k|`` for equal lengths),
    as MATLAB's ``xcorr(x, y, maxlag, 'unbiased')``. Returns (lags, r)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    full = signal.correlate(x, y, mode="full")
    lags = signal.correlation_lags(x.size, y.size, mode="full")
    overlap = signal.correlate(np.ones(x.size), np.ones(y.size), mode="full")
    keep = np.abs(lags) <= max_lag
    return lags[keep], full[keep] / np.round(overlap[keep])


def alignment_lag(reference: np.ndarray, other: np.ndarray, max_lag: int) -> int:
    """Lag k [samples] maximising the unbiased cross-correlation: ``other[n]`` best matches
    ``reference[n - k]``, i.e. ``other`` shifted left by k (``other[n + k]``) aligns with
    ``reference[n]``."""
    lags, r = unbiased_xcorr(other, reference, max_lag)
    return int(lags[np.argmax(r)])
