"""Checks applied to every recording at the edge, whatever format it came in."""

from __future__ import annotations

import numpy as np

from ..data import CHANNELS, REQUIRED_CHANNELS, Recording
from ..errors import InputError

#: Largest deviation of a time stamp from the fitted uniform grid, in sample periods, that is
#: still taken as rounding or clock jitter rather than a gap or a jump.
IRREGULAR_TIME_TOLERANCE = 0.25


def sample_rate_from_time(time_s: np.ndarray, *, path: object) -> tuple[float, float]:
    """Sample rate [Hz] and start time [s] of a uniformly sampled time column.

    The rate is the least-squares slope of time against sample index, which is insensitive to
    the rounding of time stamps written as text. Raises :class:`InputError` when the time is
    not strictly increasing or not uniform (gaps, jumps, jitter above
    :data:`IRREGULAR_TIME_TOLERANCE` of a sample period).
    """
    t = np.asarray(time_s, dtype=np.float64)
    if t.size < 2:
        raise InputError("fewer than two samples", path=path, channel="time_s")
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"non-finite time stamp at row {bad + 1}", path=path, channel="time_s",
                         hint="repair or cut the recording")
    dt = np.diff(t)
    if np.any(dt <= 0):
        bad = int(np.flatnonzero(dt <= 0)[0])
        raise InputError(f"time is not strictly increasing at row {bad + 2} "
                         f"({float(t[bad])!r} then {float(t[bad + 1])!r})", path=path,
                         channel="time_s",
                         hint="sort the recording or cut it at the jump")
    n = np.arange(t.size, dtype=np.float64)
    n_c = n - n.mean()
    slope = float(np.dot(n_c, t - t.mean()) / np.dot(n_c, n_c))
    t0 = float(t.mean() - slope * n.mean())
    resid = t - (t0 + slope * n)
    worst = float(np.max(np.abs(resid))) / slope
    if worst > IRREGULAR_TIME_TOLERANCE:
        bad = int(np.argmax(np.abs(np.diff(resid)))) + 1
        raise InputError(f"time is not uniformly sampled (a gap or jump of {worst:.2f} sample "
                         f"periods near row {bad + 1})", path=path, channel="time_s",
                         hint="resample the recording to a uniform rate before processing")
    return 1.0 / slope, t0


def check_finite(rec: Recording, *, path: object) -> None:
    """Raise :class:`InputError` on the first NaN or inf in any channel."""
    for name, x in rec.channels.items():
        finite = np.isfinite(x)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise InputError(f"{int((~finite).sum())} NaN/inf values (first at sample {bad + 1})",
                             path=path, channel=name,
                             hint="repair the file, or choose --nan-policy interpolate|drop-cycle")


def check_channels(rec: Recording, *, path: object) -> None:
    """The required channels present (optional ones may be absent), each 1-D, numeric and of
    one common length."""
    n = None
    for name in CHANNELS:
        if name not in rec.channels:
            if name not in REQUIRED_CHANNELS:
                continue
            raise InputError("missing channel", path=path, channel=name,
                             hint="add the column or map it in the manifest's [channels]")
        x = rec.channels[name]
        if x.ndim != 1:
            raise InputError(f"expected a 1-D signal, got shape {x.shape}", path=path,
                             channel=name)
        if n is None:
            n = x.size
        elif x.size != n:
            raise InputError(f"has {x.size} samples, other channels have {n}", path=path,
                             channel=name, hint="all channels must be sampled together; "
                             "export them again or cut them to one length")
