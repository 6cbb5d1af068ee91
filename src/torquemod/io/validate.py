"""Checks applied to every recording at the edge, whatever format it came in."""

from __future__ import annotations

import math

import numpy as np

from torquemod.errors import InputError
from torquemod.io.experiment import CHANNELS, REQUIRED_CHANNELS, Recording

#: Largest deviation of a time stamp from the fitted uniform grid, in sample periods, that is
#: still taken as rounding or clock jitter rather than a gap or a jump.
IRREGULAR_TIME_TOLERANCE = 0.25


#: Samples per block of the time-grid fit: its temporaries stay in cache, whatever the length.
TIME_FIT_BLOCK = 1 << 16


def fit_time_grid(time_s: np.ndarray, *, path: object, channel: str = "time_s"
                  ) -> tuple[float, float, float]:
    """The uniform grid of a column of time stamps.

    Sample ``k`` lies at ``anchor_s + rel_s + k/fs_hz``. ``anchor_s`` is the first stamp as
    stored and ``rel_s`` the fitted start relative to it, so two grids' start difference
    ``(a1 - a2) + (r1 - r2)`` stays exact for absolute (epoch, ~1.7e9 s) stamps, whose
    float64 spacing is 2.4e-7 s.

    Parameters
    ----------
    time_s : ndarray
        The time stamps [s].
    path : object
        The file, named in messages.
    channel : str
        The time channel, named in messages. Default "time_s".

    Returns
    -------
    fs_hz : float
        Sample rate [Hz].
    anchor_s : float
        The first stamp [s].
    rel_s : float
        The fitted start relative to ``anchor_s`` [s].

    Raises
    ------
    InputError
        Fewer than two samples, stamps not finite, not strictly increasing, or not uniform
        (gaps, jumps, jitter above :data:`IRREGULAR_TIME_TOLERANCE` of a period), naming
        ``channel`` and the row.

    Notes
    -----
    The rate is the least-squares slope of time against sample index (fitted on the stamps
    less the first), insensitive to rounding and jitter of the stamps. Computed in blocks of
    :data:`TIME_FIT_BLOCK` samples (:func:`fit_time_grid_blocks`).

    Examples
    --------
    >>> import numpy as np
    >>> fs, anchor, rel = fit_time_grid(np.arange(100) / 50.0 + 3.0, path="x.csv")
    >>> round(fs, 9), anchor, abs(rel) < 1e-12
    (50.0, 3.0, True)
    """
    t = np.asarray(time_s, dtype=np.float64).reshape(-1)
    step = TIME_FIT_BLOCK
    return fit_time_grid_blocks(lambda: (t[a:a + step] for a in range(0, t.size, step)),
                                path=path, channel=channel)


def fit_time_grid_blocks(blocks, *, path: object, channel: str = "time_s"
                         ) -> tuple[float, float, float]:
    """:func:`fit_time_grid` of a column given as consecutive blocks.

    Parameters
    ----------
    blocks : callable
        ``blocks()`` returns a new iterator of 1-D float64 arrays [s] each time it is called
        (it is called twice).
    path : object
        The file, named in messages.
    channel : str
        The time channel, named in messages. Default "time_s".

    Returns
    -------
    fs_hz : float
        Sample rate [Hz].
    anchor_s : float
        The first stamp [s].
    rel_s : float
        The fitted start relative to ``anchor_s`` [s].

    Raises
    ------
    InputError
        As :func:`fit_time_grid`.

    Notes
    -----
    Pass 1 checks finiteness and order and sums ``r_k = t_k - t_0`` and ``k*r_k`` per block
    (numpy's pairwise sums, blocks added by ``math.fsum``); the least-squares slope is
    ``sum((k - kbar)*r_k)/sum((k - kbar)^2)`` with the denominator in closed form
    ``n*(n^2 - 1)/12``. Pass 2 takes the largest residual from the fitted line.
    """
    n = 0
    anchor = math.nan
    prev = math.nan
    s_r: list[float] = []
    s_kr: list[float] = []
    for block in blocks():
        b = np.asarray(block, dtype=np.float64).reshape(-1)
        if b.size == 0:
            continue
        finite = np.isfinite(b)
        if not finite.all():
            bad = n + int(np.flatnonzero(~finite)[0])
            raise InputError(f"non-finite time stamp at row {bad + 1}", path=path,
                             channel=channel, hint="repair or cut the recording")
        if n == 0:
            anchor = float(b[0])
        ext = b if n == 0 else np.concatenate(([prev], b))
        dt = np.diff(ext)
        if np.any(dt <= 0):
            i = int(np.flatnonzero(dt <= 0)[0])
            row = n + i - (0 if n == 0 else 1)  # index of the earlier stamp
            raise InputError(f"time is not strictly increasing at row {row + 2} "
                             f"({float(ext[i])!r} then {float(ext[i + 1])!r})", path=path,
                             channel=channel,
                             hint="sort the recording or cut it at the jump")
        rel = b - anchor  # exact for stamps within a factor 2 of each other (Sterbenz)
        k = np.arange(n, n + b.size, dtype=np.float64)
        s_r.append(float(rel.sum()))
        s_kr.append(float(np.dot(k, rel)))
        prev = float(b[-1])
        n += b.size
    if n < 2:
        raise InputError("fewer than two samples", path=path, channel=channel)
    n_mean = (n - 1) / 2.0
    sum_r = math.fsum(s_r)
    r_mean = sum_r / n
    slope = (math.fsum(s_kr) - n_mean * sum_r) / (n * (n * n - 1.0) / 12.0)
    rel0 = r_mean - slope * n_mean
    if not math.isfinite(slope) or slope <= 0:
        raise InputError("time stamps give no positive sample period", path=path,
                         channel=channel, hint="check the time channel")
    worst, jump, jump_row, k0, last = 0.0, -1.0, 0, 0, math.nan
    for block in blocks():
        b = np.asarray(block, dtype=np.float64).reshape(-1)
        if b.size == 0:
            continue
        res = b - anchor
        res -= rel0 + slope * np.arange(k0, k0 + b.size, dtype=np.float64)
        worst = max(worst, float(np.max(np.abs(res))))
        d = np.abs(np.diff(res if k0 == 0 else np.concatenate(([last], res))))
        if d.size and float(d.max()) > jump:
            jump = float(d.max())
            jump_row = int(np.argmax(d)) + (1 if k0 == 0 else 0) + k0
        last = float(res[-1])
        k0 += b.size
    worst /= slope
    if worst > IRREGULAR_TIME_TOLERANCE:
        raise InputError(f"time is not uniformly sampled (a gap or jump of {worst:.2f} sample "
                         f"periods near row {jump_row + 1})", path=path, channel=channel,
                         hint="resample the recording to a uniform rate before processing")
    return 1.0 / slope, anchor, rel0


def sample_rate_from_time(time_s: np.ndarray, *, path: object, channel: str = "time_s"
                          ) -> tuple[float, float]:
    """Sample rate and start time of a uniformly sampled time column.

    Parameters
    ----------
    time_s : ndarray
        The time stamps [s].
    path : object
        The file, named in messages.
    channel : str
        The time channel, named in messages. Default "time_s".

    Returns
    -------
    fs_hz : float
        Sample rate [Hz].
    t0_s : float
        Start ``anchor_s + rel_s`` [s] (:func:`fit_time_grid`), good to the float64 spacing of
        the stamps (2.4e-7 s at epoch times of 1.7e9 s).

    Raises
    ------
    InputError
        As :func:`fit_time_grid`.
    """
    fs, anchor, rel = fit_time_grid(time_s, path=path, channel=channel)
    return fs, anchor + rel


def check_finite(rec: Recording, *, path: object) -> None:
    """Refuse NaN or inf in any channel.

    Parameters
    ----------
    rec : Recording
        The recording.
    path : object
        The file, named in the message.

    Raises
    ------
    InputError
        On the first channel holding NaN or inf: how many, and the first sample.
    """
    for name, x in rec.channels.items():
        finite = np.isfinite(x)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise InputError(f"{int((~finite).sum())} NaN/inf values (first at sample {bad + 1})",
                             path=path, channel=name,
                             hint="repair the file, or choose --nan-policy interpolate|drop-cycle")


def check_channels(rec: Recording, *, path: object) -> None:
    """Check the channels: the required ones present, each 1-D, numeric and of one length.

    Optional channels may be absent.

    Parameters
    ----------
    rec : Recording
        The recording.
    path : object
        The file, named in the message.

    Raises
    ------
    InputError
        A required channel missing, a channel not 1-D, or of another length.
    """
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


def _longest_run(mask: np.ndarray) -> int:
    """Length of the longest run of True in a boolean array."""
    if not mask.any():
        return 0
    edges = np.diff(np.concatenate([[0], mask.view(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int((stops - starts).max())


def clipping_notes(rec: Recording, *, path: object, min_run_s: float = 0.005,
                   min_fraction: float = 1e-3) -> list[str]:
    """Warnings for channels that look clipped.

    A run of at least ``min_run_s`` of consecutive samples, and at least ``min_fraction`` of
    all samples, sitting exactly at the channel's maximum or minimum (a saturated sensor or a
    logger range set too small). A live, noisy signal reaches its extreme once, not for a run
    of samples; the phase and the means of a clipped channel are biased, so the user must
    know.

    Parameters
    ----------
    rec : Recording
        The recording.
    path : object
        The file, named in the warnings.
    min_run_s : float
        Shortest run at an extreme [s]. Default 0.005.
    min_fraction : float
        Smallest share of all samples at the extremes [-]. Default 1e-3.

    Returns
    -------
    list of str
        One warning per clipped channel.
    """
    out = []
    n = rec.n_samples
    need = max(int(np.ceil(min_run_s * rec.fs_hz)), int(np.ceil(min_fraction * n)), 3)
    for name, x in rec.channels.items():
        finite = x[np.isfinite(x)]
        if finite.size < need or finite.min() == finite.max():
            continue
        for which, value in (("maximum", finite.max()), ("minimum", finite.min())):
            at = x == value
            if at.sum() >= need and (run := _longest_run(at)) >= need:
                out.append(f"{path}: channel '{name}' sits at its {which} {value:.6g} for "
                           f"{run} consecutive samples ({run / rec.fs_hz:.3g} s; "
                           f"{100 * at.mean():.2g} % of the record): a clipped sensor or a "
                           "logger range set too small? Check the channel; its phase and "
                           "means are biased where it is clipped")
    return out
