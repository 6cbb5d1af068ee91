"""The per-cycle steps of the V-Track processing chain (Section 2.4 of the paper).

Pure functions over one cycle's samples; the orchestration over an experiment is in
:mod:`torquemod.pipeline`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import ProcessingConfig
from .data import Recording, Rig
from .dsp import filters
from .dsp.align import alignment_lag
from .dsp.phase import peak_valley_phase, sinefit_phase
from .dsp.spectrum import peak_frequency
from .errors import InputError, ProcessingError


@dataclass
class CycleSignals:
    """One cycle after steps 1-5 and 8: resampled/notched/filtered signals on a uniform grid
    at ``fs_hz`` [Hz], the peak frequencies [Hz] and the creep-curve point."""

    fs_hz: float
    t0_s: float  # time of the first resampled sample after the cycle start [s]
    torque_peak_hz: float
    wheel_peak_hz: float
    modulation_hz: float
    wheel_rotation_hz: float
    platform_rotation_hz: float
    torque_resampled: np.ndarray
    wheel_resampled: np.ndarray
    torque_notched: np.ndarray
    wheel_notched: np.ndarray
    torque_filtered: np.ndarray
    wheel_filtered: np.ndarray
    creepage: float
    coa: float
    means: dict = field(default_factory=dict)
    notches_hz: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # warnings for the user and provenance
    creepage_drift: float = float("nan")  # creepage change over the cycle [-] (slip check)


def creepage_coa(wheel_speed_rad_s: float, platform_speed_rad_s: float, fx_n: float, fy_n: float,
                 fz_n: float, *, wheel_radius_m: float, platform_radius_m: float
                 ) -> tuple[float, float]:
    """Eq. (3) and (4) of the V-Track paper from mean values:
    ``xi = (w*Rw - W*Rp)/(W*Rp)``, ``CoA = sqrt(Fx^2 + Fy^2)/Fz``."""
    v_platform = platform_speed_rad_s * platform_radius_m
    xi = (wheel_speed_rad_s * wheel_radius_m - v_platform) / v_platform
    coa = np.hypot(fx_n, fy_n) / fz_n
    return float(xi), float(coa)


def check_cycle_length(n_samples: int, fs_hz: float, f_nominal_hz: float,
                       cfg: ProcessingConfig, *, where: str) -> None:
    """A cycle must hold the phase window plus the trimmed edges."""
    need = (cfg.phase.n_periods + 2 * cfg.phase.edge_trim_periods) / f_nominal_hz
    have = n_samples / fs_hz
    if have < need:
        raise InputError(f"cycle is {have:.2f} s long, too short for {cfg.phase.n_periods} "
                         f"modulation periods after trimming {cfg.phase.edge_trim_periods} "
                         f"period(s) at each end (needs {need:.2f} s)", path=where,
                         hint="record longer cycles")


def check_operating_point(means: dict[str, float], platform_std_rad_s: float, *,
                          where: str) -> None:
    """Refuse a cycle whose means make Eq. (3) and (4) meaningless: a platform that does not
    turn (its mean speed [rad/s] within its own scatter), wheel and platform turning in
    opposite directions, or a normal force [N] that is not positive."""
    w_p, w_w, fz = (means["platform_speed_rad_s"], means["wheel_speed_rad_s"], means["fz_n"])
    if not abs(w_p) > platform_std_rad_s:
        raise InputError(f"the platform is not turning (mean speed {w_p:.3g} rad/s, scatter "
                         f"{platform_std_rad_s:.3g} rad/s)", path=where,
                         channel="platform_speed_rad_s",
                         hint="record while the platform runs, or check the channel mapping "
                         "and unit in [channels]")
    if w_w * w_p < 0:
        raise InputError(f"wheel and platform speeds have opposite signs (mean {w_w:.4g} and "
                         f"{w_p:.4g} rad/s)", path=where, channel="wheel_speed_rad_s",
                         hint="flip the sign of one speed channel so both are positive "
                         "when rolling forward")
    if not fz > 0:
        raise InputError(f"mean normal force is {fz:.4g} N; it must be positive (compression)",
                         path=where, channel="fz_n",
                         hint="check the channel mapping, its unit and the load cell's sign")


#: Channels resampled in step 2 (the forces for their step-8 means).
_RESAMPLED = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")


def _rotation_frequency(speed_rad_s: np.ndarray, fs_hz: float, harmonics: tuple[int, ...]
                        ) -> float:
    """Rotation frequency [Hz] = mean angular speed / 2 pi, the mean taken free of the
    encoder's own eccentricity tones (one refinement of the plain mean, whose bias from a
    large tone over a non-integer number of revolutions would misplace the notches)."""
    f0 = float(np.mean(speed_rad_s)) / (2 * np.pi)
    tones = [h * abs(f0) for h in harmonics]
    return filters.tone_free_mean(speed_rad_s, fs_hz, tones) / (2 * np.pi)


def process_cycle(rec: Recording, rig: Rig, cfg: ProcessingConfig, *, where: str) -> CycleSignals:
    """Steps 1-5 and 8 on one cycle of a recording."""
    fs = rec.fs_hz
    up, down = filters.resample_ratio(fs, cfg.resample.target_hz,
                                      max_denominator=cfg.resample.max_denominator)
    fs_r = fs * up / down
    if fs < cfg.resample.target_hz:
        raise InputError(f"sample rate {fs:.6g} Hz is below the chain's resampling rate "
                         f"{cfg.resample.target_hz} Hz", path=where, channel="time_s",
                         hint="record at a higher rate or lower [processing] resample.target_hz")
    ch = rec.channels
    # Step 2 (done first: step 1's spectral peak is the same on the resampled record, whose
    # anti-alias filter is flat across the search band, and costs 300x less there). The
    # output samples the FIR's zero padding touches are cut off.
    edge = filters.resampler_edge_samples(up, down)
    stacked = np.vstack([ch[k] for k in _RESAMPLED])
    resampled = filters.resample(stacked, up, down,
                                 kaiser_beta=cfg.resample.kaiser_beta)[:, edge:-edge]
    tq, wh, pl, fx, fy, fz = resampled
    if tq.size < 8:
        raise InputError(f"only {tq.size} samples after resampling to {fs_r:.4g} Hz",
                         path=where, hint="the recording is too short")
    # Step 1: modulation frequency = mean of the torque's and wheel speed's peaks. The wheel's
    # rotation tones are removed before its spectrum (see spectrum.peak_frequency).
    nq = cfg.notch
    f_wheel = _rotation_frequency(wh, fs_r, nq.wheel_harmonics)
    f_plat = _rotation_frequency(pl, fs_r, nq.platform_harmonics)
    wheel_notches = filters.notch_frequencies(abs(f_wheel), nq.wheel_harmonics, fs_r)
    plat_notches = filters.notch_frequencies(abs(f_plat), nq.platform_harmonics, fs_r)
    fp = cfg.frequency
    peaks = {}
    for name, x in (("torque_nm", tq), ("wheel_speed_rad_s", wh)):
        try:
            peaks[name] = peak_frequency(x, fs_r, band_hz=fp.band_hz, window=fp.window,
                                         detrend=fp.detrend, zero_pad=fp.zero_pad,
                                         remove_tones_hz=tuple(wheel_notches))
        except ProcessingError as exc:
            raise InputError(f"no modulation found: {exc}", path=where, channel=name,
                             hint="check the modulation was on and [processing] "
                             "frequency.band_hz") from None
    f_t, f_w = peaks["torque_nm"], peaks["wheel_speed_rad_s"]
    f_mod = 0.5 * (f_t + f_w)
    # Step 3: notches at the wheel's rotation harmonics, zero phase (platform: see step 8).
    notes = [f"{where}: wheel-speed notch at {f0:.3f} Hz lies within {nq.warn_within_hz} Hz "
             f"of the modulation frequency {f_mod:.3f} Hz; it also attenuates the modulation"
             for f0 in wheel_notches if abs(f0 - f_mod) < nq.warn_within_hz]
    hp = filters.design_highpass(cfg.highpass.cutoff_hz, cfg.highpass.order, fs_r)
    bp = filters.design_bandpass(f_mod, cfg.bandpass.width_hz, cfg.bandpass.order, fs_r)
    notch_ba = {f0: filters.design_notch(f0, nq.q, fs_r) for f0 in wheel_notches}
    pad = max(filters.settling_samples(ba) for ba in [hp, bp, *notch_ba.values()])
    tones = [f_mod, *wheel_notches]

    def chain_3_to_5(x: np.ndarray, freqs: list[float]) -> tuple[np.ndarray, np.ndarray]:
        xp, level, slope = filters.model_padded(x, fs_r, tones, pad)
        for f0 in freqs:
            xp = filters.zero_phase(notch_ba[f0], xp, method="none")
        xf = filters.zero_phase(bp, filters.zero_phase(hp, xp, method="none"), method="none")
        t = np.arange(x.size) / fs_r
        return xp[pad:pad + x.size] + level + slope * (t - t.mean()), xf[pad:pad + x.size]

    wh_n, wh_f = chain_3_to_5(wh, wheel_notches)
    tq_n, tq_f = chain_3_to_5(tq, [])
    # Step 8: creepage and CoA from means. Each mean is the constant term of a least-squares
    # fit with the modulation and the rotation harmonics (filters.tone_free_mean): the value
    # the notched signal averages to, without edge transients, and free of the partial
    # modulation period a cycle holds (12.9 periods at V-Track: a 0.1 rad/s wheel-speed or
    # 100 N creep-force answer to the modulation would otherwise bias the creepage by 5e-5
    # and the CoA by 3e-4). The platform's 1st and 2nd harmonics cannot be notched apart
    # within one revolution; the fit separates them.
    rotation = [*wheel_notches, *plat_notches]
    means = {
        "wheel_speed_rad_s": filters.tone_free_mean(wh, fs_r, [f_mod, *wheel_notches]),
        "platform_speed_rad_s": filters.tone_free_mean(pl, fs_r, [f_mod, *plat_notches]),
        **{k: filters.tone_free_mean(x, fs_r, [f_mod, *rotation])
           for k, x in (("fx_n", fx), ("fy_n", fy), ("fz_n", fz))},
        "torque_nm": float(np.mean(ch["torque_nm"])),
    }
    check_operating_point(means, float(np.std(pl)), where=where)
    xi, coa = creepage_coa(means["wheel_speed_rad_s"], means["platform_speed_rad_s"],
                           means["fx_n"], means["fy_n"], means["fz_n"],
                           wheel_radius_m=rig.wheel_radius_m,
                           platform_radius_m=rig.platform_radius_m)
    drift = creepage_drift(wh, pl, fs_r, wheel_tones_hz=tones,
                           platform_tones_hz=[f_mod, *plat_notches],
                           wheel_radius_m=rig.wheel_radius_m,
                           platform_radius_m=rig.platform_radius_m)
    return CycleSignals(fs_r, edge / fs_r, f_t, f_w, f_mod, abs(f_wheel), abs(f_plat), tq, wh,
                        tq_n, wh_n, tq_f, wh_f, xi, coa, means,
                        {"wheel": wheel_notches, "platform": plat_notches}, notes,
                        creepage_drift=drift)


def creepage_drift(wheel_rad_s: np.ndarray, platform_rad_s: np.ndarray, fs_hz: float, *,
                   wheel_tones_hz: list[float], platform_tones_hz: list[float],
                   wheel_radius_m: float, platform_radius_m: float) -> float:
    """Change of the creepage of Eq. (3) from the start to the end of a record [-], from the
    lines fitted jointly with the given tones [Hz] (modulation, rotation harmonics) to the
    wheel and platform speeds [rad/s]: ``T * Rw/Rp * (w'/W - w*W'/W^2)``. A wheel that starts
    to slip shows as a creepage rising within the cycle."""
    def level_slope(x: np.ndarray, tones: list[float]) -> tuple[float, float]:
        # every tone is kept, however close (the platform's 1st and 2nd harmonics are one
        # resolution apart over a revolution, and either left out would tilt the line)
        kept = [f for f in tones if 0 < f < fs_hz / 2]
        design = filters.tone_design(np.arange(x.size) / fs_hz, kept, line=True)
        coef, *_ = np.linalg.lstsq(design, np.asarray(x, float), rcond=None)
        return float(coef[0]), float(coef[1])

    duration = wheel_rad_s.size / fs_hz
    w, dw = level_slope(wheel_rad_s, wheel_tones_hz)
    p, dp = level_slope(platform_rad_s, platform_tones_hz)
    if p == 0:
        return float("nan")
    return float(duration * wheel_radius_m / platform_radius_m * (dw / p - w * dp / p**2))


def align_lags(cycles: list[CycleSignals], cfg: ProcessingConfig) -> list[int]:
    """Step 6: lag [samples] of each cycle's band-passed torque against the first cycle's."""
    if not cfg.align.enabled or len(cycles) < 2:
        return [0] * len(cycles)
    ref = cycles[0]
    max_lag = round(cfg.align.max_lag_periods * ref.fs_hz / ref.modulation_hz)
    return [0] + [alignment_lag(ref.torque_filtered, c.torque_filtered, max_lag)
                  for c in cycles[1:]]


def cycle_phase(c: CycleSignals, cfg: ProcessingConfig, *, center_index: float
                ) -> tuple[float, float, tuple[float, float]]:
    """Step 7: (phase [deg], standard error [deg] or NaN, window [s]) of one cycle.

    ``center_index`` is where the phase window is centred (the aligned middle).
    """
    n = c.torque_filtered.size
    period_n = c.fs_hz / c.modulation_hz
    if cfg.phase.method == "paper":
        half = (cfg.phase.n_periods / 2 + cfg.phase.edge_trim_periods) * period_n
        center = min(max(center_index, half), n - half)
        res = peak_valley_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                                center_s=center / c.fs_hz, n_periods=cfg.phase.n_periods)
        hw = cfg.phase.n_periods / 2 / c.modulation_hz
        return res.phase_deg, float("nan"), (center / c.fs_hz - hw, center / c.fs_hz + hw)
    nuisance = tuple(c.notches_hz["wheel"]) + tuple(c.notches_hz["platform"])
    if cfg.phase.sinefit_input == "bandpassed":
        res = sinefit_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend,
                            noise_from=(c.torque_notched, c.wheel_notched))
    else:
        res = sinefit_phase(c.torque_notched, c.wheel_notched, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend)
    return res.phase_deg, res.phase_stderr_deg, res.window_s
