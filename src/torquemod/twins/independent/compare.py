"""An estimate of available adhesion per stretch of track against the independent
generator's truth: which of the estimator's segments (``segments.csv``) stands for each true
friction segment (:func:`match_segments`), shared by the tests and the benchmark.

The estimator's positions come from its own speed integration; they are mapped to the
truth's positions through the rows' times (both record ``time_s``), so a drift of the
estimated position does not shift the match.
"""

from __future__ import annotations

import numpy as np

from torquemod.twins.independent.train import FrictionSegment, IndependentRunSpec

__all__ = ["match_segments"]


def match_segments(spec: IndependentRunSpec, track, segments, truth
                   ) -> list[tuple[FrictionSegment, object]]:
    """For each true friction segment of ``spec``, the estimated segment overlapping it most.

    Parameters
    ----------
    spec : IndependentRunSpec
        The run's truth: its segments and length [m].
    track : pandas.DataFrame
        The estimator's rows, with ``time_s`` [s] and ``position_m`` [m].
    segments : pandas.DataFrame
        The estimator's segments (``segments.csv``), with ``start_m`` and ``end_m`` [m] in
        the estimator's positions.
    truth : pandas.DataFrame
        The generator's truth table, with ``time_s`` [s] and ``position_m`` [m].

    Returns
    -------
    list of (FrictionSegment, pandas.Series or None)
        Per true segment, in order, the row of ``segments`` whose stretch (mapped to true
        positions) overlaps it over the longest distance; None when none overlaps it.
    """
    x_true = np.interp(track["time_s"], truth["time_s"], truth["position_m"])
    x_est = track["position_m"].to_numpy()
    mapped = [np.interp([a, b], x_est, x_true)
              for a, b in zip(segments["start_m"], segments["end_m"], strict=True)]
    ends = [s.start_m for s in spec.segments[1:]] + [spec.length_m]
    out = []
    for seg, end in zip(spec.segments, ends, strict=True):
        overlap = [min(end, b) - max(seg.start_m, a) for a, b in mapped]
        best = int(np.argmax(overlap)) if overlap else -1
        out.append((seg, segments.iloc[best] if best >= 0 and overlap[best] > 0 else None))
    return out
