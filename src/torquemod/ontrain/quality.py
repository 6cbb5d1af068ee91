"""Does a window of a train run hold what the method needs? Pure functions.

The creep coefficient comes from the torque's modulation line and the axle's answer to it
while the wheel rolls forward (V-Track paper, Eq. 1: the phase lag of the speed behind the
modulated torque). A window gives numbers only when

* the torque carries the modulation line: its amplitude at the declared frequency is at least
  ``min_modulation_ratio`` of the declared ``[test] modulation_amplitude_nm``
  (``no_modulation`` otherwise: constant torque, a modulation switched off, or a declared
  frequency the torque does not have);
* the train rolls: the reference speed is at least ``min_speed_m_s`` (``standstill``; below it
  the creepage's reference speed is floored and rolling contact is not established);
* it rolls forward: the reference speed and the axle speed are positive (``reverse``; the sign
  conventions of creepage, CoA and phase assume forward running).

:data:`QUALITY_OK` windows carry numbers; the others keep their time, position and speed and
leave the rest empty (``quality`` in track.parquet says why). :func:`stretches` groups them
along the track for the warnings, and :func:`modulation_line_hz` finds the line the torque
really has when the declared one is absent (a mis-declared ``modulation_frequency_hz``).
"""

from __future__ import annotations

import math

import numpy as np

from torquemod.errors import InputError

#: the window holds the method's premise
QUALITY_OK = "ok"
#: what each flag means, as the warnings say it
REASONS = {"no_modulation": "no modulation line at the declared frequency in the torque",
           "standstill": "speed below what the method needs (standstill)",
           "reverse": "the train runs backwards (negative speed)"}


def stepping(dc_step_nm, amplitude_nm: float | None, max_step_ratio: float):
    """Whether the mean torque steps inside windows by more than a share of the modulation.

    Such a window's modulation line cannot be judged alone (a step leaks into the sine fit).

    Parameters
    ----------
    dc_step_nm : float or array_like
        Change of the mean torque from a window's first to its last modulation period [N*m].
    amplitude_nm : float or None
        Declared modulation amplitude [N*m]; None or 0: nothing steps.
    max_step_ratio : float
        Largest step, as a share of ``amplitude_nm``, that does not count [-].

    Returns
    -------
    bool or ndarray of bool
        True where ``dc_step_nm > max_step_ratio*amplitude_nm``.

    Examples
    --------
    >>> stepping([10.0, 300.0], 1000.0, 0.25).tolist()
    [False, True]
    """
    return (np.asarray(dc_step_nm, dtype=float) > max_step_ratio * amplitude_nm
            if amplitude_nm else np.zeros(np.shape(dc_step_nm), dtype=bool))


def window_quality(speed_m_s: float, wheel_speed_rad_s: float, torque_amplitude_nm: float, *,
                   amplitude_nm: float | None, min_speed_m_s: float,
                   min_modulation_ratio: float, dc_step_nm: float = 0.0,
                   max_step_ratio: float = math.inf) -> str:
    """The window's quality flag: :data:`QUALITY_OK` or a key of :data:`REASONS`.

    A window whose torque steps (:func:`stepping`) is not judged by its line here (a step
    leaks into the sine fit either way; :func:`without_line_nearby` judges it by its
    neighbours).

    Parameters
    ----------
    speed_m_s : float
        Mean reference speed [m/s].
    wheel_speed_rad_s : float
        Mean axle angular speed [rad/s].
    torque_amplitude_nm : float
        The torque's amplitude at the modulation frequency [N*m].
    amplitude_nm : float or None
        Declared modulation amplitude [N*m]; None: the line is not checked.
    min_speed_m_s : float
        Speed below which the train stands [m/s] (``OnboardConfig.min_speed_m_s``).
    min_modulation_ratio : float
        Share of ``amplitude_nm`` the line must reach [-]
        (``OnboardConfig.min_modulation_ratio``).
    dc_step_nm : float
        DC torque step inside the window [N*m]. Default 0.
    max_step_ratio : float
        Largest step, as a share of ``amplitude_nm``, for the line to be judged [-].
        Default inf.

    Returns
    -------
    str
        ``"reverse"`` (either speed negative), ``"standstill"``, ``"no_modulation"`` or
        ``"ok"``, checked in that order.

    Examples
    --------
    >>> window_quality(20.0, 43.0, 900.0, amplitude_nm=1000.0, min_speed_m_s=1.0,
    ...                min_modulation_ratio=0.25)
    'ok'
    >>> window_quality(0.2, 0.4, 900.0, amplitude_nm=1000.0, min_speed_m_s=1.0,
    ...                min_modulation_ratio=0.25)
    'standstill'
    """
    if speed_m_s < 0 or wheel_speed_rad_s < 0:
        return "reverse"
    if not speed_m_s >= min_speed_m_s:
        return "standstill"
    if (amplitude_nm and not stepping(dc_step_nm, amplitude_nm, max_step_ratio)
            and not torque_amplitude_nm >= min_modulation_ratio * amplitude_nm):
        return "no_modulation"
    return QUALITY_OK


def without_line_nearby(quality, steady, *, half_width: int = 10) -> np.ndarray:
    """Judge the torque-stepping windows by their neighbours.

    A DC step inside a window leaks into the sine fit and can fake a line's amplitude, so a
    stepping window is flagged ``no_modulation`` where most of the windows around it that can
    tell lack the line.

    Parameters
    ----------
    quality : array_like of str
        Each window's flag (:func:`window_quality`).
    steady : array_like of bool
        False for the windows whose torque steps (:func:`stepping`).
    half_width : int
        Windows looked at on each side [-]. Default 10.

    Returns
    -------
    ndarray of object
        ``quality`` with those windows flagged; the others unchanged.
    """
    q = np.asarray(quality, dtype=object).copy()
    st = np.asarray(steady, dtype=bool)
    missing = (q == "no_modulation").astype(int)
    present = ((q == QUALITY_OK) & st).astype(int)
    c_missing = np.concatenate([[0], np.cumsum(missing)])
    c_present = np.concatenate([[0], np.cumsum(present)])
    for i in np.flatnonzero((q == QUALITY_OK) & ~st):
        a, b = max(0, i - half_width), min(q.size, i + half_width + 1)
        if c_missing[b] - c_missing[a] > c_present[b] - c_present[a]:
            q[i] = "no_modulation"
    return q


def stretches(position_m, quality) -> list[tuple[str, float, float, int]]:
    """Runs of consecutive windows with one flag other than :data:`QUALITY_OK`.

    Parameters
    ----------
    position_m : array_like
        Position of each window [m].
    quality : array_like of str
        Each window's flag.

    Returns
    -------
    list of tuple
        ``(flag, first position [m], last position [m], windows)`` in track order.

    Examples
    --------
    >>> stretches([0.0, 10.0, 20.0, 30.0], ["ok", "standstill", "standstill", "ok"])
    [('standstill', 10.0, 20.0, 2)]
    """
    pos = np.asarray(position_m, dtype=float)
    q = np.asarray(quality, dtype=object)
    out: list[tuple[str, float, float, int]] = []
    i = 0
    while i < q.size:
        j = i
        while j + 1 < q.size and q[j + 1] == q[i]:
            j += 1
        if q[i] != QUALITY_OK:
            out.append((str(q[i]), float(pos[i]), float(pos[j]), j - i + 1))
        i = j + 1
    return out


def quality_warnings(position_m, quality, *, axle: int, frequency_hz: float,
                     max_listed: int = 3) -> list[str]:
    """One warning per flag: the stretches of track without the method's premise.

    Parameters
    ----------
    position_m : array_like
        Position of each window [m].
    quality : array_like of str
        Each window's flag.
    axle : int
        The axle, named in the warning.
    frequency_hz : float
        Declared modulation frequency [Hz], named in the warning.
    max_listed : int
        Longest stretches listed per flag [-]. Default 3.

    Returns
    -------
    list of str
        The warnings, with the share of the windows affected.
    """
    q = np.asarray(quality, dtype=object)
    out = []
    for flag, text in REASONS.items():
        parts = [s for s in stretches(position_m, q) if s[0] == flag]
        if not parts:
            continue
        n = sum(s[3] for s in parts)
        parts.sort(key=lambda s: s[3], reverse=True)
        where = ", ".join(f"{a:.0f}-{b:.0f} m" for _, a, b, _ in sorted(parts[:max_listed],
                                                                        key=lambda s: s[1]))
        more = f" and {len(parts) - max_listed} more stretches" if len(parts) > max_listed \
            else ""
        what = text.replace("the declared frequency", f"{frequency_hz:g} Hz")
        out.append(f"axle {axle}: {what} over {where}{more} ({n} of {q.size} windows, "
                   f"{100.0 * n / max(q.size, 1):.0f} %): no friction numbers there")
    return out


def reference_rate_hz(speed_m_s: np.ndarray, fs_hz: float) -> float:
    """How often the reference speed is really updated.

    The samples where the speed changes or where its slope changes, whichever are fewer, per
    second: a speed held between updates changes once per update, one interpolated linearly
    between them bends once; a speed sampled at ``fs_hz`` does both at nearly every sample.

    Parameters
    ----------
    speed_m_s : ndarray
        Reference speed [m/s].
    fs_hz : float
        Its sampling rate [Hz].

    Returns
    -------
    float
        Update rate [Hz]; 0 for a speed that neither changes nor bends (constant, or a
        constant ramp).

    Examples
    --------
    >>> reference_rate_hz([1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 4.0], 100.0)
    37.5
    """
    v = np.asarray(speed_m_s, dtype=float)
    if v.size < 3:
        return 0.0
    tiny = 1e-9 * max(1.0, float(np.max(np.abs(v))))
    changes = np.count_nonzero(np.abs(np.diff(v)) > tiny)
    bends = np.count_nonzero(np.abs(np.diff(v, 2)) > tiny)
    return float(min(changes, bends)) * fs_hz / v.size


def modulation_line_hz(torque_nm: np.ndarray, fs_hz: float, declared_hz: float,
                       min_amplitude_nm: float = 0.0) -> float | None:
    """The frequency of the torque's strongest line near a declared one that holds none.

    The strongest line within 0.7-1.4 times the declared frequency, when the declared
    frequency holds no line but another one stands out (10x the band's median power, an
    amplitude of at least ``min_amplitude_nm``, the declared bin below a tenth of its power).

    Parameters
    ----------
    torque_nm : ndarray
        A stretch of the axle torque [N*m].
    fs_hz : float
        Its sampling rate [Hz].
    declared_hz : float
        Declared modulation frequency [Hz].
    min_amplitude_nm : float
        Smallest amplitude of the line [N*m]. Default 0.

    Returns
    -------
    float or None
        The line's frequency [Hz]; None when the declared frequency holds the line or no other
        line stands out.

    Notes
    -----
    Periodogram of the linearly detrended torque with a Hann window, zero-padded 4x; the
    amplitude of a bin is ``2*|X|/sum(w)``.
    """
    x = np.asarray(torque_nm, dtype=float)
    n = x.size
    if n < 16 or not math.isfinite(declared_hz) or declared_hz <= 0:
        return None
    t = np.arange(n)
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    w = np.hanning(n)
    spec = np.abs(np.fft.rfft(x * w, 4 * n)) ** 2
    f = np.fft.rfftfreq(4 * n, 1.0 / fs_hz)
    band = (f >= 0.7 * declared_hz) & (f <= 1.4 * declared_hz)
    if band.sum() < 8:
        return None
    p = spec[band]
    peak = int(np.argmax(p))
    amplitude = 2.0 * math.sqrt(p[peak]) / w.sum()
    at_declared = spec[int(np.argmin(np.abs(f - declared_hz)))]
    if (p[peak] >= 10.0 * np.median(p) and amplitude >= min_amplitude_nm
            and at_declared < 0.1 * p[peak] and abs(f[band][peak] - declared_hz) > 2 * fs_hz / n):
        return float(f[band][peak])
    return None


def premise_warnings(run, entry, track, config, torque_nm=None, fs_hz: float | None = None):
    """One axle's track with the premise judged, and the warnings about it.

    Torque-stepping windows are judged by their neighbours (:func:`without_line_nearby`;
    those that lose the premise have their numbers emptied), and the warnings name the
    stretches without the premise and a run with fewer measurable windows than the friction
    fit needs.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run (declared modulation frequency and amplitude).
    entry : torquemod.io.run.RunRecording
        The axle's recording.
    track : pandas.DataFrame
        The axle's track (track.parquet columns plus ``dc_step_nm``).
    config : torquemod.ontrain.estimator.OnboardConfig
        The settings it was estimated with.
    torque_nm : ndarray or None
        A stretch of the axle's torque [N*m]. Accepted and not used: the line the torque
        has instead of the declared one is named before the estimate
        (:func:`torquemod.ontrain.run.check_modulation_line`). Default None.
    fs_hz : float or None
        Sampling rate of ``torque_nm`` [Hz]; not used. Default None.

    Returns
    -------
    track : pandas.DataFrame
        The track, judged.
    warnings : list of str
        The warnings.

    Raises
    ------
    InputError
        No window of the axle can be measured (as ``process`` refuses a recording without a
        modulation line), naming the recording, the commonest reason and what to do.
    """
    f = run.modulation_frequency_hz
    q = without_line_nearby(track["quality"].to_numpy(object), ~stepping(
        track["dc_step_nm"], run.modulation_amplitude_nm, config.max_dc_step_ratio))
    lost = q != track["quality"].to_numpy(object)
    if lost.any():
        track = track.copy()
        track.loc[lost, ["phase_deg", "phase_se_deg", "creep_coefficient", "mu", "mu_low_95",
                         "mu_high_95", "utilisation", "creepage",
                         "creep_coefficient_ref"]] = math.nan
        track.loc[lost, ["low_adhesion", "slip"]] = False
        track["quality"] = q
    n_ok = int((q == QUALITY_OK).sum())
    if n_ok == 0:
        flags = {k: int((q == k).sum()) for k in REASONS}
        worst = max(flags, key=flags.get)
        what = REASONS[worst].replace("the declared frequency", f"{f:g} Hz")
        hint = {"no_modulation": "record with the torque modulation on, or check [test] "
                                 "modulation_frequency_hz and modulation_amplitude_nm",
                "standstill": "record while the train runs (at least [onboard] "
                              f"min_speed_m_s = {config.min_speed_m_s:g} m/s)",
                "reverse": "the method needs forward running; if the run went forward, "
                           "the speed channels' sign is wrong"}[worst]
        raise InputError(f"no window of axle {entry.axle} can be measured: {what} "
                         f"({flags[worst]} of {q.size} windows)", path=entry.path, hint=hint)
    out = quality_warnings(track["position_m"], q, axle=entry.axle, frequency_hz=f)
    if n_ok < config.min_windows:
        out.append(f"axle {entry.axle}: only {n_ok} measurable windows, fewer than the "
                   f"{config.min_windows} the friction fit needs ([onboard] min_windows): "
                   "the run is too short for a friction estimate (mu stays empty)")
    return track, out
