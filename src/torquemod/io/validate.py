"""Checks applied to every recording at the edge, whatever format it came in."""

from __future__ import annotations

import numpy as np

from ..data import CHANNELS, REQUIRED_CHANNELS, Recording
from ..errors import InputError

#: Largest deviation of a time stamp from the fitted uniform grid, in sample periods, that is
#: still taken as rounding or clock jitter rather than a gap or a jump.
IRREGULAR_TIME_TOLERANCE = 0.25


def fit_time_grid(time_s: np.ndarray, *, path: object, channel: str = "time_s"
                  ) -> tuple[float, float, float]:
    """The uniform grid of a column of time stamps [s]: ``(fs_hz, anchor_s, rel_s)``, sample
    ``k`` at ``anchor_s + rel_s + k / fs_hz``.

    ``anchor_s`` is the first stamp as stored and ``rel_s`` the fitted start relative to it,
    so two grids' start difference ``(a1 - a2) + (r1 - r2)`` stays exact for absolute
    (epoch, ~1.7e9 s) stamps, whose float64 spacing is 2.4e-7 s. The rate is the
    least-squares slope of time against sample index (fitted on the stamps less the first),
    which is insensitive to rounding and jitter of the stamps. Raises :class:`InputError`
    naming ``channel`` when the stamps are not finite, not strictly increasing or not
    uniform (gaps, jumps, jitter above :data:`IRREGULAR_TIME_TOLERANCE` of a period).
    """
    t = np.asarray(time_s, dtype=np.float64).reshape(-1)
    if t.size < 2:
        raise InputError("fewer than two samples", path=path, channel=channel)
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"non-finite time stamp at row {bad + 1}", path=path, channel=channel,
                         hint="repair or cut the recording")
    dt = np.diff(t)
    if np.any(dt <= 0):
        bad = int(np.flatnonzero(dt <= 0)[0])
        raise InputError(f"time is not strictly increasing at row {bad + 2} "
                         f"({float(t[bad])!r} then {float(t[bad + 1])!r})", path=path,
                         channel=channel,
                         hint="sort the recording or cut it at the jump")
    del dt
    anchor = float(t[0])
    rel = t - anchor  # exact for stamps within a factor 2 of each other (Sterbenz)
    n = np.arange(t.size, dtype=np.float64)
    n_mean = (t.size - 1) / 2.0
    n -= n_mean
    r_mean = float(rel.mean())
    slope = float(np.dot(n, rel - r_mean) / np.dot(n, n))
    rel0 = r_mean - slope * n_mean
    # residuals from the fitted line, in place: rel - (rel0 + slope * k)
    n *= slope
    rel -= r_mean
    rel -= n
    if not np.isfinite(slope) or slope <= 0:
        raise InputError("time stamps give no positive sample period", path=path,
                         channel=channel, hint="check the time channel")
    worst = float(np.max(np.abs(rel))) / slope
    if worst > IRREGULAR_TIME_TOLERANCE:
        bad = int(np.argmax(np.abs(np.diff(rel)))) + 1
        raise InputError(f"time is not uniformly sampled (a gap or jump of {worst:.2f} sample "
                         f"periods near row {bad + 1})", path=path, channel=channel,
                         hint="resample the recording to a uniform rate before processing")
    return 1.0 / slope, anchor, rel0


def sample_rate_from_time(time_s: np.ndarray, *, path: object, channel: str = "time_s"
                          ) -> tuple[float, float]:
    """Sample rate [Hz] and start time [s] of a uniformly sampled time column.

    See :func:`fit_time_grid` (same checks); the start is ``anchor_s + rel_s``, good to the
    float64 spacing of the stamps (2.4e-7 s at epoch times of 1.7e9 s).
    """
    fs, anchor, rel = fit_time_grid(time_s, path=path, channel=channel)
    return fs, anchor + rel


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
