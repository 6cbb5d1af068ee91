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
    """True where the mean torque changes inside the window by more than ``max_step_ratio``
    of the declared modulation amplitude ``amplitude_nm`` [N*m] (``dc_step_nm`` [N*m]: from
    its first to its last modulation period): such a window's line cannot be judged alone."""
    return (np.asarray(dc_step_nm, dtype=float) > max_step_ratio * amplitude_nm
            if amplitude_nm else np.zeros(np.shape(dc_step_nm), dtype=bool))


def window_quality(speed_m_s: float, wheel_speed_rad_s: float, torque_amplitude_nm: float, *,
                   amplitude_nm: float | None, min_speed_m_s: float,
                   min_modulation_ratio: float, dc_step_nm: float = 0.0,
                   max_step_ratio: float = math.inf) -> str:
    """The window's quality flag: :data:`QUALITY_OK` or a key of :data:`REASONS`.

    ``speed_m_s`` [m/s] the mean reference speed, ``wheel_speed_rad_s`` [rad/s] the axle's,
    ``torque_amplitude_nm`` [N*m] the torque's amplitude at the modulation frequency,
    ``amplitude_nm`` [N*m] the declared modulation amplitude (None: not checked). A window
    whose torque steps (:func:`stepping`) is not judged by its line here (a step leaks
    into the sine fit either way; :func:`without_line_nearby` judges it by its neighbours).
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
    """``quality`` with the torque-stepping windows (``steady`` False, :func:`stepping`) flagged
    ``no_modulation`` where most of the windows around them (``half_width`` each side) that
    can tell lack the line: a DC step inside a window leaks into the sine fit and can fake
    a line's amplitude, so such a window is judged by its neighbours. The others unchanged."""
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
    """Consecutive windows of one flag other than :data:`QUALITY_OK` along the track:
    ``(flag, first position [m], last position [m], windows)``."""
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
    """One warning per flag: the stretches of track without the premise (the longest
    ``max_listed`` of them by position range) and the share of the windows."""
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
    """How often [Hz] the reference speed is really updated: the samples where it changes
    or where its slope changes, whichever are fewer, per second (a speed held between
    updates changes once per update, one interpolated linearly between them bends once; a
    speed sampled at ``fs_hz`` does both at nearly every sample). 0 for a speed that
    neither changes nor bends (constant, or a constant ramp)."""
    v = np.asarray(speed_m_s, dtype=float)
    if v.size < 3:
        return 0.0
    tiny = 1e-9 * max(1.0, float(np.max(np.abs(v))))
    changes = np.count_nonzero(np.abs(np.diff(v)) > tiny)
    bends = np.count_nonzero(np.abs(np.diff(v, 2)) > tiny)
    return float(min(changes, bends)) * fs_hz / v.size


def modulation_line_hz(torque_nm: np.ndarray, fs_hz: float, declared_hz: float,
                       min_amplitude_nm: float = 0.0) -> float | None:
    """The frequency [Hz] of the torque's strongest line within 0.7-1.4 times the declared
    one when the declared frequency holds no line but another one stands out (10x the band's
    median power, an amplitude of at least ``min_amplitude_nm`` [N*m], the declared bin
    below a tenth of its power); else None. Periodogram of the linearly detrended torque
    with a Hann window, zero-padded 4x (resolution fs/n)."""
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
    """``(track, warnings)`` of one axle (``entry``, a :class:`~torquemod.io.run.RunRecording`
    of the :class:`~torquemod.io.run.Run` ``run``, estimated with the
    :class:`~torquemod.ontrain.estimator.OnboardConfig` ``config``): the axle's track with
    the torque-stepping windows judged by their neighbours (:func:`without_line_nearby`),
    and the warnings about the method's premise (:mod:`torquemod.ontrain.quality`): the stretches
    without it, and a run with fewer measurable windows than the friction fit needs. No
    measurable window at all raises :class:`InputError` (as ``process`` refuses a recording
    without a modulation line), naming the line the torque has instead when ``torque_nm``
    (a stretch of the axle's torque at ``fs_hz`` [Hz]) shows one."""
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
