"""Channels on their own time bases put on the torque channel's sample times
(logger realities), and the :class:`~torquemod.io.experiment.Recording` a reader's channels make.

A reader finds raw channels in its file (:class:`~torquemod.io.channels.RawChannel`: values,
unit, perhaps their own time stamps or rate); :func:`assemble_recording` converts units
(:mod:`torquemod.io.channels`), fits each channel's time base to a uniform grid
(:func:`torquemod.io.validate.fit_time_grid`), cuts every channel to the span they all cover,
low-passes a faster channel below the torque's Nyquist frequency and interpolates linearly at
the torque's sample times, with a note of the interpolation error that implies. The streaming
run reader (:mod:`torquemod.io.runstream`) uses the same plans chunk by chunk.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from torquemod.errors import InputError
from torquemod.io.channels import (
    TIME,
    TORQUE,
    ChannelMap,
    ChannelSpec,
    RawChannel,
    _available_text,
    _converted,
    _missing,
    as_vector,
    convert_units,
)
from torquemod.io.experiment import CHANNELS, OPTIONAL_CHANNELS, Recording
from torquemod.io.validate import fit_time_grid

#: A channel on its own time base must cover at least this share of the torque channel's
#: time span (all channels are cut to the span they share); otherwise it is refused.
MIN_COVERAGE = 0.9
#: Start offsets within this many sample periods of a whole number of samples, and rates so
#: close that they drift apart by less than this over the record, are taken as exact (the
#: fitted grids of jittered stamps differ by less, see tests/io/test_logger_timebase.py).
SAME_INSTANT_SAMPLES = 0.01
#: Highest frequency [Hz] of the method's signals, for the interpolation error stated in the
#: notes: linear interpolation of a sine of frequency f between samples dt apart errs by at
#: most (2*pi*f*dt)^2/8 of its amplitude.
SIGNAL_BAND_HZ = 30.0
#: A channel sampled faster than the torque is low-passed (zero-phase Butterworth, this
#: order, at this share of the torque's sample rate) before it is interpolated, so that its
#: noise above the torque's Nyquist frequency does not alias.
ANTI_ALIAS_ORDER = 8
ANTI_ALIAS_SHARE = 0.4


@dataclass(frozen=True)
class _Grid:
    """Uniform sample times: sample ``k`` at ``anchor_s + rel_s + k / fs_hz`` [s]. The split
    keeps start differences of absolute (epoch) time stamps exact."""

    fs_hz: float
    anchor_s: float
    rel_s: float = 0.0

    @property
    def t0_s(self) -> float:
        return self.anchor_s + self.rel_s

    def start_in(self, ref: _Grid) -> float:
        """This grid's first sample time in sample periods of ``ref`` after ref's first."""
        return ((self.anchor_s - ref.anchor_s) + (self.rel_s - ref.rel_s)) * ref.fs_hz

    def text(self) -> str:
        return f"{self.fs_hz:.6g} Hz from {self.t0_s:.9g} s"


def _stamps_grid(t: np.ndarray, path: object, channel: str) -> _Grid:
    fs, anchor, rel = fit_time_grid(t, path=path, channel=channel)
    return _Grid(fs, anchor, rel)


def _own_grid(raw: RawChannel, n: int, path: object, channel: str,
              fitted: list[tuple[np.ndarray, _Grid]] | None = None) -> _Grid | None:
    """A channel's own time base (stamps, or a rate and start), None if it has none.
    ``fitted`` holds stamps already fitted (an MDF group's master comes once per channel)."""
    if raw.time_s is not None:
        t = np.asarray(raw.time_s, dtype=np.float64).reshape(-1)
        if t.size != n:
            raise InputError(f"has {n} samples but {t.size} time stamps", path=path,
                             channel=channel, hint="is the file complete?")
        for seen, grid in fitted or []:
            if seen is t or np.array_equal(seen, t):
                return grid
        grid = _stamps_grid(t, path, channel)
        if fitted is not None:
            fitted.append((t, grid))
        return grid
    if raw.fs_hz is not None:
        fs, t0 = float(raw.fs_hz), float(raw.t0_s)
        if not math.isfinite(fs) or fs <= 0 or not math.isfinite(t0):
            raise InputError(f"its time base ({fs} Hz from {t0} s) is not usable", path=path,
                             channel=channel, hint="map a 'time' channel or set "
                             "sample_rate_hz in the manifest")
        return _Grid(fs, t0)
    return None


def _with_own_time(spec: ChannelSpec, raw: RawChannel,
                   lookup: Callable[[str], RawChannel | None], path: object,
                   available: Callable[[], list[str]] | None,
                   notes: list[str] | None = None) -> RawChannel:
    """``raw`` with the time vector the manifest maps for it (the entry's ``time`` key).

    A slow channel exported beside fast ones in one table (CSV, Parquet) is padded with
    empty cells below its last sample: rows where both its time and its value are empty
    at the end are cut off (a note says how many); empty cells anywhere else stay an
    error."""
    if not spec.time:
        return raw
    t_raw = lookup(spec.time)
    if t_raw is None:
        raise _missing(replace(spec, name=spec.time), path, available)
    t_values = as_vector(t_raw.values, path=path, channel=spec.channel)
    if t_values.dtype.kind in "mM":
        raise InputError(f"its time vector '{spec.time}' holds date-times", path=path,
                         channel=spec.channel, hint="map a numeric time vector (seconds)")
    unit = spec.time_unit or (str(t_raw.unit).strip() if t_raw.unit else None)
    t = convert_units(t_values, unit, "time", path=path, channel=spec.channel)
    values = as_vector(raw.values, path=path, channel=spec.channel)
    if t.size == values.size and t.size and not math.isfinite(float(t[-1])):
        finite = np.flatnonzero(np.isfinite(t))
        k = int(finite[-1]) + 1 if finite.size else 0
        tail = values[k:]
        if k >= 2 and tail.dtype.kind == "f" and not np.isfinite(tail).any():
            t, raw = t[:k], replace(raw, values=values[:k])
            if notes is not None:
                notes.append(f"channel '{spec.channel}': {values.size - k} empty rows below "
                             f"its last sample (time '{spec.time}') cut off")
    return replace(raw, time_s=t, fs_hz=None)


def _recording_grid(cmap: ChannelMap, lookup: Callable[[str], RawChannel | None],
                    torque_grid: _Grid | None, native_rate: tuple[float, float] | None,
                    n: int, path: object) -> _Grid:
    """The recording's time base by precedence: the time channel, the torque's own time
    base, the file's sample rate (the manifest's sample rate is handled by the caller)."""
    spec = cmap.time
    raw = lookup(spec.name)
    if raw is None and spec.explicit:
        raise _missing(spec, path, None)
    if raw is not None:
        t = _converted(spec, raw, path)
        if t.size != n:
            raise InputError(f"has {t.size} samples, the channels have {n}", path=path,
                             channel=TIME)
        return _stamps_grid(t, path, TIME)
    if torque_grid is not None:
        return torque_grid
    if native_rate is not None:
        fs, t0 = float(native_rate[0]), float(native_rate[1])
        if not math.isfinite(fs) or fs <= 0:
            raise InputError(f"sample rate {fs} Hz is not a positive number", path=path,
                             channel=TIME)
        if not math.isfinite(t0):
            raise InputError(f"start time {t0} s is not finite", path=path, channel=TIME)
        return _Grid(fs, t0)
    raise InputError(f"no time base: no time channel '{spec.name}' and no sample rate in the "
                     "file", path=path, channel=TIME,
                     hint="map 'time' or set sample_rate_hz in [channels] or in the "
                          "[[recording]] (docs/format.md)")


@dataclass
class _Plan:
    """How one channel on its own time base reaches the torque's samples: sample ``k`` of
    the torque is at ``(k - start) * ratio`` of the channel; ``shift`` is the whole-sample
    offset when no interpolation is needed."""

    grid: _Grid
    m: int
    start: float
    ratio: float
    shift: int | None

    @property
    def end(self) -> float:
        return self.start + (self.m - 1) / self.ratio


def _plan(channel: str, grid: _Grid, m: int, ref: _Grid, n: int, path: object) -> _Plan:
    start = grid.start_in(ref)
    ratio = grid.fs_hz / ref.fs_hz
    if not (math.isfinite(start) and math.isfinite(ratio) and 1e-6 < ratio < 1e6):
        raise InputError(f"its time base ({grid.text()}) cannot be matched to "
                         f"{TORQUE}'s ({ref.text()})", path=path, channel=channel,
                         hint="check the file's time properties, or map a common 'time' "
                              "channel in [channels]")
    if abs(ratio - 1.0) * max(n, m) <= SAME_INSTANT_SAMPLES:
        ratio = 1.0
        whole = round(start)
        if abs(start - whole) <= SAME_INSTANT_SAMPLES:
            return _Plan(grid, m, float(whole), 1.0, int(whole))
    return _Plan(grid, m, start, ratio, None)


def _coverage_error(channel: str, plan: _Plan, ref: _Grid, n: int, shared: float,
                    path: object) -> InputError:
    span = (n - 1) / ref.fs_hz
    first, last = plan.start / ref.fs_hz, plan.end / ref.fs_hz
    late = f"starts {first:.4f} s after" if first > 0 else ""
    early = f"ends {span - last:.4f} s before" if last < span else ""
    how = " and ".join(x for x in (late, early) if x) or "is offset from"
    return InputError(f"{how} {TORQUE} (it covers {first:+.4f} s to {last:+.4f} s of "
                      f"{TORQUE}'s 0 to {span:.4f} s); the channels share {100 * shared:.1f} % "
                      f"of that span, at least {100 * MIN_COVERAGE:.0f} % is needed",
                      path=path, channel=channel,
                      hint="export all channels over one time span, or cut the recording to "
                           "the span this channel covers")


def _lowpass(x: np.ndarray, fs_hz: float, cutoff_hz: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt
    sos = butter(ANTI_ALIAS_ORDER, cutoff_hz, fs=fs_hz, output="sos")
    return sosfiltfilt(sos, x, padlen=min(x.size - 1, 3 * (2 * len(sos) + 1)))


def _interpolated(x: np.ndarray, plan: _Plan, lo: int, hi: int) -> np.ndarray:
    """Linear interpolation of ``x`` at torque samples ``lo..hi`` (positions in the channel's
    samples are exact to ~1e-9 of a sample even for 1e7-sample records)."""
    u = np.arange(lo, hi + 1, dtype=np.float64)
    u -= plan.start
    u *= plan.ratio
    np.clip(u, 0.0, plan.m - 1.0, out=u)
    i = np.minimum(u.astype(np.intp), plan.m - 2)
    u -= i
    out = x[i + 1] - x[i]
    out *= u
    out += x[i]
    return out


def _align(channels: dict[str, np.ndarray], grids: dict[str, _Grid | None], ref: _Grid,
           path: object, notes: list[str]) -> tuple[dict[str, np.ndarray], int]:
    """Every channel on the torque's sample times ``ref`` (channels without their own time
    base are taken as sampled with the torque); all cut to the span they share. Returns the
    channels and the first torque sample kept."""
    n = channels[TORQUE].size
    plans: dict[str, _Plan] = {}
    for name, x in channels.items():
        if name == TORQUE:
            continue
        grid = grids.get(name)
        if grid is None:
            if x.size != n:
                raise InputError(f"has {x.size} samples, {TORQUE} has {n}", path=path,
                                 channel=name, hint="all channels must be sampled together "
                                 "(or each on its own declared time base)")
            continue
        if x.size < 2:
            raise InputError(f"fewer than two samples ({x.size})", path=path, channel=name)
        plans[name] = _plan(name, grid, x.size, ref, n, path)
    span = shared_span(plans, ref, n, path)
    if span is None:
        return channels, 0
    lo, hi = span
    out: dict[str, np.ndarray] = {}
    for name, x in channels.items():
        plan = plans.get(name)
        if plan is None:
            out[name] = x[lo:hi + 1]
        elif plan.shift is not None:
            prepared(name, x, plan, ref, notes)
            out[name] = x[lo - plan.shift:hi + 1 - plan.shift]
        else:
            out[name] = _interpolated(prepared(name, x, plan, ref, notes), plan, lo, hi)
    note_cut(lo, hi, n, notes)
    return out, lo


def shared_span(plans: dict[str, _Plan], ref: _Grid, n: int, path: object
                ) -> tuple[int, int] | None:
    """First and last of the torque's samples that every planned channel covers.

    Parameters
    ----------
    plans : dict of str to _Plan
        How each channel on its own time base is put on the torque's times.
    ref : _Grid
        The torque's time grid.
    n : int
        The torque's sample count.
    path : object
        The file, named in messages.

    Returns
    -------
    tuple of int or None
        ``(first, last)`` sample indices (within :data:`SAME_INSTANT_SAMPLES`); None when
        every channel lies on the torque's samples already.

    Raises
    ------
    InputError
        A channel covers less than :data:`MIN_COVERAGE` of the torque's span.
    """
    if all(p.shift == 0 and p.m == n for p in plans.values()):
        return None
    eps = SAME_INSTANT_SAMPLES
    lo = max([0, *(math.ceil(p.start - eps) for p in plans.values())])
    hi = min([n - 1, *(math.floor(p.end + eps) for p in plans.values())])
    shared = max(hi - lo, 0) / (n - 1)
    if shared < MIN_COVERAGE:
        def covered(p: _Plan) -> float:
            return min(p.end, n - 1.0) - max(p.start, 0.0)
        worst = min(plans, key=lambda k: covered(plans[k]))
        raise _coverage_error(worst, plans[worst], ref, n, shared, path)
    return lo, hi


def prepared(name: str, x: np.ndarray, plan: _Plan, ref: _Grid, notes: list[str]
             ) -> np.ndarray:
    """A channel ready to be put on the torque's times.

    Low-passed when it is sampled faster than the torque and holds no NaN/inf.

    Parameters
    ----------
    name : str
        The method channel.
    x : ndarray
        Its values (SI units).
    plan : _Plan
        How it is put on the torque's times.
    ref : _Grid
        The torque's time grid.
    notes : list of str
        The recording's notes; the note saying what is done is appended.

    Returns
    -------
    ndarray
        The channel, filtered when needed.
    """
    offset_ms = plan.start / ref.fs_hz * 1e3
    if plan.shift is not None:
        if plan.shift:
            notes.append(f"channel '{name}' starts {plan.shift:+d} samples "
                         f"({offset_ms:+.4f} ms) from {TORQUE}: shifted by whole samples "
                         "(no interpolation)")
        return x
    what = "interpolated linearly"
    if plan.ratio > 1.0:
        if np.isfinite(x).all():
            x = _lowpass(x, plan.grid.fs_hz, ANTI_ALIAS_SHARE * ref.fs_hz)
            what = (f"low-passed at {ANTI_ALIAS_SHARE * ref.fs_hz:.6g} Hz (zero-phase "
                    f"Butterworth, order {ANTI_ALIAS_ORDER}) and interpolated linearly")
        else:
            what = "interpolated linearly (not low-passed: it holds NaN/inf)"
    if plan.grid.fs_hz > 2 * SIGNAL_BAND_HZ:
        err = (2 * math.pi * SIGNAL_BAND_HZ / plan.grid.fs_hz) ** 2 / 8
        bound = (f"error < {err:.1e} of the amplitude of a {SIGNAL_BAND_HZ:.0f} Hz "
                 "component")
    else:  # a slow reference (radar, GNSS): it carries no component that fast
        bound = (f"a slow channel: components above {plan.grid.fs_hz / 2:.6g} Hz are "
                 "not in it")
    notes.append(f"channel '{name}' on its own time base (starts {offset_ms:+.4f} ms from "
                 f"{TORQUE}, {plan.grid.fs_hz:.6g} Hz vs {ref.fs_hz:.6g} Hz): {what} "
                 f"onto {TORQUE}'s sample times ({bound})")
    return x


def note_cut(lo: int, hi: int, n: int, notes: list[str]) -> None:
    """Add the note of a cut to the shared span (none when nothing was cut).

    Parameters
    ----------
    lo : int
        First sample kept.
    hi : int
        Last sample kept.
    n : int
        Samples before the cut.
    notes : list of str
        The notes, appended to.
    """
    if lo > 0 or hi < n - 1:
        notes.append(f"cut to the span all channels share: {lo} samples of {TORQUE} dropped "
                     f"at the start and {n - 1 - hi} at the end ({hi + 1 - lo} of {n} kept)")


def _check_one_time_base(grids: dict[str, _Grid | None], n: int, path: object) -> None:
    """With a sample rate from the manifest, refuse channels whose own time bases differ
    (the manifest's rate would put them on one grid, misaligned)."""
    timed = [(k, g) for k, g in grids.items() if g is not None]
    if len(timed) < 2:
        return
    name0, ref = timed[0]
    for name, grid in timed[1:]:
        start = grid.start_in(ref)
        ratio = grid.fs_hz / ref.fs_hz
        if not (math.isfinite(start) and math.isfinite(ratio)) or \
                abs(start) > SAME_INSTANT_SAMPLES or \
                abs(ratio - 1.0) * n > SAME_INSTANT_SAMPLES:
            raise InputError(f"its own time base ({grid.text()}) differs from {name0}'s "
                             f"({ref.text()}); a sample rate from the manifest would put "
                             "them on one grid, misaligned", path=path, channel=name,
                             hint="remove sample_rate_hz from the manifest so the file's "
                                  "time bases are used")


def assemble_recording(cmap: ChannelMap, lookup: Callable[[str], RawChannel | None], *,
                       path: object, source: str,
                       native_rate: tuple[float, float] | None = None,
                       available: Callable[[], list[str]] | None = None,
                       notes: list[str] | None = None) -> Recording:
    """Build a :class:`Recording` from a reader's channel lookup.

    Every method channel is looked up by its mapped name and converted to SI; the optional
    ones (:data:`~torquemod.io.experiment.OPTIONAL_CHANNELS`) may be absent unless the map
    names them explicitly; forces come as Fx with Fz (Fy optional). Channels on their own
    time base are put on the torque's sample times and all channels are cut to the span they
    share (:data:`MIN_COVERAGE`); what was done goes into ``Recording.notes`` after the
    reader's own ``notes``.

    Parameters
    ----------
    cmap : ChannelMap
        The checked ``[channels]`` map.
    lookup : callable
        ``lookup(name) -> RawChannel | None`` for a file channel name.
    path : object
        The file, named in messages.
    source : str
        ``Recording.source``.
    native_rate : tuple of float or None
        ``(fs_hz [Hz], t0_s [s])`` of the file's own time base, the last resort. Default
        None.
    available : callable or None
        ``available()`` lists the file's channel names for the message when a channel is
        missing. Default None.
    notes : list of str or None
        The reader's own notes. Default None.

    Returns
    -------
    Recording
        The channels in SI units on the torque's uniform time base.

    Raises
    ------
    InputError
        A channel missing (or a force without its partner), fewer than two samples, a bad
        sample rate or start time, a time base that is not uniform, or channels that share
        too little time.

    Notes
    -----
    The time base comes from, in order: the map's ``sample_rate_hz``, the time channel
    (``time_s`` unless mapped), the torque's own time base (``RawChannel.time_s``/``fs_hz``),
    then ``native_rate``.
    """
    found: dict[str, RawChannel] = {}
    padding: list[str] = []  # slow channels' empty rows cut off (notes)
    for channel in CHANNELS:
        spec = cmap.spec(channel)
        raw = lookup(spec.name)
        if raw is None:
            if channel in OPTIONAL_CHANNELS and not spec.explicit:
                continue  # an optional channel the file does not hold
            raise _missing(spec, path, available)
        found[channel] = _with_own_time(spec, raw, lookup, path, available, padding)
    forces = [c for c in ("fx_n", "fz_n") if c in found]
    if len(forces) == 1 or ("fy_n" in found and not forces):
        lacking = "fz_n" if "fx_n" in found else "fx_n"
        have = [f"'{cmap.spec(c).name}'" for c in ("fx_n", "fy_n", "fz_n") if c in found]
        raise InputError(f"no channel '{cmap.spec(lacking).name}' in the file although "
                         f"{' and '.join(have)} {'is' if len(have) == 1 else 'are'}: the "
                         "forces need Fx and Fz together (Fy is optional)"
                         f"{_available_text(available)}", path=path, channel=lacking,
                         hint="map the missing force in [channels], or leave all force "
                              "channels out (the CoA then comes from the torque)")
    notes = [*(notes or []), *padding]
    channels = {c: _converted(cmap.spec(c), raw, path, notes) for c, raw in found.items()}
    n = channels[TORQUE].size
    if n < 2:
        raise InputError(f"fewer than two samples ({n})", path=path, channel=TORQUE)
    fitted: list[tuple[np.ndarray, _Grid]] = []
    grids = {c: _own_grid(raw, channels[c].size, path, c, fitted) for c, raw in found.items()}
    del fitted
    if cmap.sample_rate_hz is not None:
        _check_one_time_base(grids, n, path)
        grid = _Grid(cmap.sample_rate_hz, cmap.t0_s)
        lo = 0
    else:
        grid = _recording_grid(cmap, lookup, grids[TORQUE], native_rate, n, path)
        channels, lo = _align(channels, grids, grids[TORQUE] or grid, path, notes)
    fs, t0 = grid.fs_hz, grid.t0_s + lo / grid.fs_hz
    if not math.isfinite(fs) or fs <= 0:
        raise InputError(f"sample rate {fs} Hz is not a positive number", path=path,
                         channel=TIME)
    if not math.isfinite(t0):
        raise InputError(f"start time {t0} s is not finite", path=path, channel=TIME)
    if "fx_n" in channels and "fy_n" not in channels:
        notes.append("no lateral force channel: CoA = |Fx|/Fz")
    return Recording(channels, float(fs), float(t0), source, notes)
