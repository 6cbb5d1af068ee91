"""The per-cycle steps of the V-Track processing chain (Section 2.4 of the paper).

Pure functions over one cycle's samples; the orchestration over an experiment is in
:mod:`torquemod.processing.pipeline`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from torquemod.dsp import filters, resampling
from torquemod.dsp.align import alignment_lag
from torquemod.dsp.basis import needs_wide_band
from torquemod.dsp.padfilter import chain_filtered
from torquemod.dsp.phase import (
    SineFitResult,
    local_noise_psd,
    peak_valley_phase,
    sinefit_phase,
    wrapped_angle,
)
from torquemod.dsp.spectrum import peak_frequencies, peak_frequency
from torquemod.errors import InputError, ProcessingError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Recording, Rig
from torquemod.processing.creepage import creepage_and_drift
from torquemod.processing.cyclechecks import check_operating_point, record_std
from torquemod.processing.jointmodel import hypot
from torquemod.processing.speedmodel import (
    SpeedModel,
    _SlowOrdersRemoval,
    fit_speed_model,
    modulation_harmonics,
)
from torquemod.processing.trackedorders import _slow_and_orders


@dataclass
class CycleSignals:
    """One cycle after steps 1-5 and 8 of the V-Track paper's processing [1]_.

    Attributes
    ----------
    fs_hz : float
        Sample rate of the resampled signals [Hz].
    t0_s : float
        Time of their first sample [s].
    torque_peak_hz : float
        Spectral peak of the torque in the modulation band [Hz] (step 1).
    wheel_peak_hz : float
        Spectral peak of the wheel speed [Hz].
    modulation_hz : float
        The modulation frequency used for the cycle [Hz].
    wheel_rotation_hz : float
        Wheel rotation frequency [Hz].
    platform_rotation_hz : float
        Platform rotation frequency [Hz].
    torque_resampled : ndarray
        Torque after resampling [N*m] (step 2).
    wheel_resampled : ndarray
        Wheel speed after resampling [rad/s].
    torque_notched : ndarray
        Torque after the notch filters [N*m] (step 3).
    wheel_notched : ndarray
        Wheel speed after the notch filters [rad/s].
    torque_filtered : ndarray
        Torque after the high- and band-pass filters [N*m] (steps 4-5).
    wheel_filtered : ndarray
        Wheel speed after those filters [rad/s].
    creepage : float
        Longitudinal creepage of Eq. (3) [-] (step 8; NaN without the platform speed).
    coa : float
        Coefficient of adhesion of Eq. (4) [-] (or the torque-based one without forces).
    means : dict
        Mean of each channel over the cycle (SI units).
    notches_hz : dict
        The notch frequencies used, by rotation ("wheel", "platform") [Hz].
    notes : list of str
        What was done that the user should know.
    creepage_drift : float
        Change of the creepage over the cycle [-] (:func:`creepage_and_drift`). Default NaN.
    extra : dict
        Further results, e.g. the joint ``speed_model`` of the cycle.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """

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
    #: torque_amplitude_nm, wheel_amplitude_rad_s, creepage_swing [-], speed_m_s [m/s],
    #: coa_torque [-], coa_source ("forces" or "torque"), slow_band_hz (the speed model's slow
    #: band's top [Hz], dsp.basis.needs_wide_band)
    extra: dict = field(default_factory=dict)


def creepage_coa(wheel_speed_rad_s: float, platform_speed_rad_s: float, fx_n: float, fy_n: float,
                 fz_n: float, *, wheel_radius_m: float, platform_radius_m: float
                 ) -> tuple[float, float]:
    """Creepage and CoA of Eqs. (3) and (4) of the V-Track paper [1]_ from mean values.

    Parameters
    ----------
    wheel_speed_rad_s : float
        Mean wheel speed w [rad/s].
    platform_speed_rad_s : float
        Mean platform speed W [rad/s].
    fx_n, fy_n, fz_n : float
        Mean contact forces [N].
    wheel_radius_m : float
        Wheel radius Rw [m].
    platform_radius_m : float
        Radius of the wheel path on the platform Rp [m].

    Returns
    -------
    creepage : float
        ``xi = (w*Rw - W*Rp)/(W*Rp)`` [-].
    coa : float
        ``CoA = sqrt(Fx^2 + Fy^2)/Fz`` [-].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eqs. (3) and (4).

    Examples
    --------
    >>> xi, coa = creepage_coa(10.1, 1.0, 300.0, 400.0, 5000.0, wheel_radius_m=0.1,
    ...                        platform_radius_m=1.0)
    >>> round(xi, 12), round(coa, 12)
    (0.01, 0.1)
    """
    v_platform = platform_speed_rad_s * platform_radius_m
    xi = (wheel_speed_rad_s * wheel_radius_m - v_platform) / v_platform
    coa = np.hypot(fx_n, fy_n) / fz_n
    return float(xi), float(coa)


@functools.lru_cache(maxsize=16)
def _resample_plan(fs_hz: float, target_hz: float, max_denominator: int
                   ) -> tuple[int, int, float, int]:
    """Step 2's ``(up, down)`` (:func:`~torquemod.dsp.resampling.resample_ratio`), the
    resampled rate ``fs*up/down`` [Hz] and the output samples cut at each end
    (:func:`~torquemod.dsp.resampling.resampler_edge_samples`), cached: the same for every
    cycle of a recording."""
    up, down = resampling.resample_ratio(fs_hz, target_hz, max_denominator=max_denominator)
    return up, down, fs_hz * up / down, resampling.resampler_edge_samples(up, down)


#: Channels resampled in step 2 when present (the forces for their step-8 means).
_RESAMPLED = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")


def _cleaned_parts(model: SpeedModel, name: str) -> tuple[np.ndarray, ...]:
    """The parts of channel ``name`` that steps 3-5 take off its record: the speed model's
    slow part, rotation orders and modulation harmonics (:meth:`SpeedModel.part`)."""
    return (model.part(name, "slow"), model.part(name, "orders"),
            model.part(name, "harmonics"))


def _coa_from_torque(model: SpeedModel, fs_hz: float, *, wheel_radius_m: float,
                     normal_load_n: float | None, inertia_kg_m2: float | None) -> float:
    """The adhesion the drive uses, ``(T_dc - J*dw/dt)/(N*Rw)`` [-]: the mean torque less
    the torque that accelerated the wheel over the cycle (J [kg m^2] when the rig gives it;
    the slow part's change of speed over the record), over N [N] times Rw [m]. It ignores
    bearing and rolling losses and the lateral share (see docs/format.md)."""
    if not normal_load_n:
        return float("nan")
    w_slow = model.part("wheel_speed_rad_s", "slow")
    accel = (w_slow[-1] - w_slow[0]) / (w_slow.size / fs_hz)
    torque = model.mean("torque_nm") - (inertia_kg_m2 or 0.0) * accel
    return float(torque / (normal_load_n * wheel_radius_m))


#: The slow band's top stays at least this many frequency resolutions (1/T, T the cycle's
#: duration) below the nominal modulation frequency. Its extra Slepian sequences reach
#: beyond it, and a slow basis that overlaps the modulation's main lobe makes the joint fit
#: nearly collinear: at 0.5 Hz on a 14 s record the scaled 0.3 Hz band (2.8 resolutions
#: away) left 0.05 deg on noise-free records at 90 % of the peak, 0.2 Hz 0.007 deg
#: (tests/processing/test_chain_orbit.py). At 2 Hz on a V-Track cycle the limit (1.34 Hz) lies above
#: the default 1.2 Hz and changes nothing.
SLOW_GAP_RESOLUTIONS = 4.0


_PEAK_CHANNELS = ("torque_nm", "wheel_speed_rad_s")


def _modulation_peaks(cleaned: np.ndarray, fs_hz: float, cfg: ProcessingConfig, where: str
                      ) -> dict[str, float]:
    """Step 1's spectral peaks [Hz] of the cleaned torque and wheel speed (the columns of
    ``cleaned``), both in one pass (:func:`~torquemod.dsp.spectrum.peak_frequencies`); where
    a column has no modulation line, the error names its channel."""
    fp = cfg.frequency
    kw = dict(band_hz=fp.band_hz, window=fp.window, detrend=fp.detrend, zero_pad=fp.zero_pad)
    try:
        f_torque, f_wheel = peak_frequencies(cleaned, fs_hz, **kw)
        return {"torque_nm": f_torque, "wheel_speed_rad_s": f_wheel}
    except ProcessingError:
        pass
    for i, name in enumerate(_PEAK_CHANNELS):  # which channel: the column on its own
        try:
            peak_frequency(np.ascontiguousarray(cleaned[:, i]), fs_hz, **kw)
        except ProcessingError as exc:
            raise InputError(f"no modulation found: {exc}", path=where, channel=name,
                             hint="check the modulation was on and [processing] "
                             "frequency.band_hz") from None
    raise AssertionError("peak_frequencies failed where peak_frequency did not")


def _step1_peaks(cleaner: _SlowOrdersRemoval, f_start: float, fs_hz: float,
                 cfg: ProcessingConfig, where: str) -> tuple[dict[str, float], float]:
    """Step 1's peaks of the torque and the wheel speed [Hz] and their mean [Hz]: the
    spectral peaks of the records less the speed model's slow part and orders fitted with
    the modulation at ``f_start``, again with it at the first peaks' mean, then (with
    ``frequency.refine``) each refined (:meth:`_SlowOrdersRemoval.refine_many`). In one
    compiled call where it applies (:meth:`_SlowOrdersRemoval.search`, the same numbers),
    else step by step."""
    fp = cfg.frequency
    found = cleaner.search(band_hz=fp.band_hz, window=fp.window, detrend=fp.detrend,
                           zero_pad=fp.zero_pad, refine=fp.refine, tol_hz=fp.tolerance_hz)
    if found is not None:
        f_t, f_w = found[2]
        return {"torque_nm": f_t, "wheel_speed_rad_s": f_w}, 0.5 * (f_t + f_w)
    f_mod = f_start
    peaks: dict[str, float] = {}
    for _ in range(2):
        cleaned = cleaner.at(f_mod)
        peaks.update(_modulation_peaks(cleaned, fs_hz, cfg, where))
        f_mod = 0.5 * (peaks["torque_nm"] + peaks["wheel_speed_rad_s"])
    if fp.refine:
        peaks["torque_nm"], peaks["wheel_speed_rad_s"] = cleaner.refine_many(
            [0, 1], [peaks["torque_nm"], peaks["wheel_speed_rad_s"]], tol_hz=fp.tolerance_hz)
        f_mod = 0.5 * (peaks["torque_nm"] + peaks["wheel_speed_rad_s"])
    return peaks, f_mod


def process_cycle(rec: Recording, rig: Rig, cfg: ProcessingConfig, *, where: str,
                  nominal_hz: float | None = None, normal_load_n: float | None = None
                  ) -> CycleSignals:
    """Steps 1-5 and 8 of the V-Track paper's processing [1]_ on one cycle of a recording.

    Optional channels (platform speed, forces) may be absent: without the platform speed no
    creepage is measured, without forces the CoA is the torque-based one.

    Parameters
    ----------
    rec : Recording
        The cycle's samples.
    rig : Rig
        The rig geometry.
    cfg : ProcessingConfig
        The chain's settings.
    where : str
        The recording, named in messages.
    nominal_hz : float or None
        The manifest's modulation frequency [Hz], a starting value for step 1; None: the
        middle of the search band.
    normal_load_n : float or None
        Nominal load for the torque-based CoA [N]. Default None.

    Returns
    -------
    CycleSignals
        The cycle's signals and creep-curve point.

    Raises
    ------
    InputError
        A sample rate below the chain's resampling rate, too few samples, no modulation line
        found, or a meaningless operating point
        (:func:`~torquemod.processing.cyclechecks.check_operating_point`).

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """
    fs = rec.fs_hz
    up, down, fs_r, edge = _resample_plan(float(fs), float(cfg.resample.target_hz),
                                          int(cfg.resample.max_denominator))
    if fs < cfg.resample.target_hz:
        raise InputError(f"sample rate {fs:.6g} Hz is below the chain's resampling rate "
                         f"{cfg.resample.target_hz} Hz", path=where, channel="time_s",
                         hint="record at a higher rate or lower [processing] resample.target_hz")
    ch = rec.channels
    names = [k for k in _RESAMPLED if k in ch]
    # Step 2 (done first: step 1's spectral peak is the same on the resampled record, whose
    # anti-alias filter is flat across the search band, and costs 300x less there). The
    # output samples the FIR's zero padding touches are cut off.
    resampled, full_means = resampling.resample_rows([ch[k] for k in names], up, down,
                                                  kaiser_beta=cfg.resample.kaiser_beta,
                                                  method=cfg.resample.method,
                                                  padtype="constant", return_means=True)
    resampled = resampled[:, edge:-edge]  # the zero padding touched only the cut samples
    sig = dict(zip(names, resampled, strict=True))
    n = resampled.shape[1]
    if n < 8:
        raise InputError(f"only {n} samples after resampling to {fs_r:.4g} Hz",
                         path=where, hint="the recording is too short")
    tq, wh = sig["torque_nm"], sig["wheel_speed_rad_s"]
    pl = sig.get("platform_speed_rad_s")
    nq, fp = cfg.notch, cfg.frequency
    # The speed model (ours): slow variation, rotation orders that follow the integrated
    # angles, and the modulation, fitted jointly (SpeedModel).
    f_start = nominal_hz if nominal_hz is not None else 0.5 * sum(fp.band_hz)
    # the slow band stops SLOW_GAP_RESOLUTIONS frequency resolutions below the modulation
    top = f_start - SLOW_GAP_RESOLUTIONS * fs_r / n
    max_hz = min(cfg.slow.max_hz, top) if cfg.slow.enabled else 0.0
    quiet_hz = min(cfg.slow.quiet_max_hz, top)
    if cfg.slow.enabled and 0.0 < quiet_hz < max_hz and not needs_wide_band(
            wh, pl, fs_r, f_start, quiet_hz, max_hz, extra=cfg.slow.extra_sequences,
            degree=cfg.slow.polynomial_degree):
        max_hz = quiet_hz  # the narrower band: no speed variation above it (needs_wide_band)
    slow, orders, rotation_hz = _slow_and_orders(wh, pl, fs_r, f_start, max_hz, cfg)
    mod_harmonics = modulation_harmonics(f_start, fs_r, n, cfg.slow.modulation_harmonics,
                                         above_hz=max_hz, avoid_hz=rotation_hz)
    # Step 1: modulation frequency = mean of the torque's and wheel speed's peaks, taken on
    # the records less their slow part and rotation orders (their leakage would pull the
    # peak); twice, since the model's modulation term starts from the nominal frequency.
    # Each peak is then refined to the frequency at which the speed model explains most of
    # the channel (_SlowOrdersRemoval.refine): the slow basis absorbs part of a mismatched
    # modulation and pulls the plain peak towards the frequency assumed.
    # np.column_stack([tq, wh]) (float64 rows; the first two, _RESAMPLED's order) in one copy
    both = np.ascontiguousarray(resampled[:2].T)
    cleaner = _SlowOrdersRemoval(both, slow, orders, fs_r, mod_harmonics, start_hz=f_start)
    peaks, f_mod = _step1_peaks(cleaner, f_start, fs_r, cfg, where)
    if fp.common == "torque":
        f_mod = peaks["torque_nm"]
    model = fit_speed_model(sig, fs_r, f_mod, slow, orders, mod_harmonics, basis_t=cleaner.qt,
                            columns=np.ascontiguousarray(resampled.T))
    f_t, f_w = peaks["torque_nm"], peaks["wheel_speed_rad_s"]
    f_wheel = abs(model.mean("wheel_speed_rad_s")) / (2 * np.pi)
    f_plat = abs(model.mean("platform_speed_rad_s")) / (2 * np.pi) if pl is not None \
        else float("nan")
    wheel_notches = filters.notch_frequencies(f_wheel, nq.wheel_harmonics, fs_r)
    plat_notches = filters.notch_frequencies(f_plat, nq.platform_harmonics, fs_r) \
        if pl is not None else []
    # Step 3: notches at the wheel's rotation harmonics, zero phase (platform: see step 8),
    # on the records less their slow part and orders.
    notes = [f"{where}: wheel-speed notch at {f0:.3f} Hz lies within {nq.warn_within_hz} Hz "
             f"of the modulation frequency {f_mod:.3f} Hz; it also attenuates the modulation"
             for f0 in wheel_notches if abs(f0 - f_mod) < nq.warn_within_hz]
    # the records less their slow part, orders and harmonics, padded by their tone model
    # (the modulation and the notches' tones) over the filters' longest settling; the wheel
    # speed through its notches, then both records through the high-pass and the band-pass
    # (one compiled call)
    wh_n, tq_n, both_f, _ = chain_filtered(
        wh, tq, fs_r, f_mod, wheel_notches, nq.q, (cfg.highpass.cutoff_hz, cfg.highpass.order),
        (cfg.bandpass.width_hz, cfg.bandpass.order),
        (model.mean("wheel_speed_rad_s"), model.mean("torque_nm")),
        first_less=_cleaned_parts(model, "wheel_speed_rad_s"),
        second_less=_cleaned_parts(model, "torque_nm"))
    wh_f, tq_f = both_f[0], both_f[1]
    # Step 8: creepage and CoA from means, each the mean of the channel less its fitted
    # modulation and rotation orders (SpeedModel.mean): the value the notched signal averages
    # to, free of the partial modulation period a cycle holds and of edge transients, and
    # taken through one model for every channel.
    means = {k: model.mean(k) for k in names}
    means["torque_nm"] = float(full_means[names.index("torque_nm")])  # the raw record's
    check_operating_point(means, record_std(pl) if pl is not None else 0.0, where=where)
    has_forces = "fx_n" in sig and "fz_n" in sig
    inertia = rig.extra.get("wheel_inertia_kg_m2") if isinstance(rig.extra, dict) else None
    coa_t = _coa_from_torque(model, fs_r, wheel_radius_m=rig.wheel_radius_m,
                             normal_load_n=normal_load_n, inertia_kg_m2=inertia)
    if pl is not None:
        xi, drift = creepage_and_drift(model, fs_r, wheel_radius_m=rig.wheel_radius_m,
                                       platform_radius_m=rig.platform_radius_m,
                                       platform_harmonics=nq.platform_harmonics)
        speed = abs(means["platform_speed_rad_s"]) * rig.platform_radius_m
    else:
        xi, drift = float("nan"), float("nan")
        speed = abs(means["wheel_speed_rad_s"]) * rig.wheel_radius_m
    coa = hypot(means["fx_n"], means.get("fy_n", 0.0)) / means["fz_n"] \
        if has_forces else coa_t  # (np.hypot's number)
    wheel_amp = model.amplitude("wheel_speed_rad_s")
    out = CycleSignals(fs_r, edge / fs_r, f_t, f_w, f_mod, f_wheel, f_plat, tq, wh,
                       tq_n, wh_n, tq_f, wh_f, xi, coa, means,
                       {"wheel": wheel_notches, "platform": plat_notches}, notes,
                       creepage_drift=drift)
    out.extra.update({"speed_model": model, "slow_band_hz": float(max_hz),
                      "variance_factor": model.variance_factor(),
                      "noise_kept": model.noise_depletion(basis_t=cleaner.qt),
                      "torque_amplitude_nm": model.amplitude("torque_nm"),
                      "wheel_amplitude_rad_s": wheel_amp,
                      "creepage_swing": wheel_amp * rig.wheel_radius_m / speed,
                      "speed_m_s": speed, "coa_torque": coa_t,
                      "coa_source": "forces" if has_forces else "torque"})
    return out


def align_lags(cycles: list[CycleSignals], cfg: ProcessingConfig) -> list[int]:
    """Step 6: lag of each cycle's band-passed torque against the first cycle's.

    Parameters
    ----------
    cycles : list of CycleSignals
        The step's cycles.
    cfg : ProcessingConfig
        The chain's settings (alignment on or off, largest lag).

    Returns
    -------
    list of int
        Lags [samples]; all 0 when alignment is off.
    """
    if not cfg.align.enabled or len(cycles) < 2:
        return [0] * len(cycles)
    ref = cycles[0]
    max_lag = round(cfg.align.max_lag_periods * ref.fs_hz / ref.modulation_hz)
    return [0] + [alignment_lag(ref.torque_filtered, c.torque_filtered, max_lag)
                  for c in cycles[1:]]


def model_phase(model: SpeedModel, torque: np.ndarray, wheel: np.ndarray, fs_hz: float
                ) -> SineFitResult:
    """The phase from the joint speed model itself.

    The least-squares estimate of the modulation beside the slow part and the orders: lag
    ``phi_T - phi_W`` with the standard error of :func:`~torquemod.dsp.phase.sinefit_phase`
    from the model's residual (Cramér-Rao bound [1]_).

    Parameters
    ----------
    model : SpeedModel
        The joint model of the wheel speed.
    torque : ndarray
        The torque [N*m].
    wheel : ndarray
        The wheel speed [rad/s].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    SineFitResult
        Phase [deg], standard error [deg], amplitudes and phases.

    References
    ----------
    .. [1] D.C. Rife and R.R. Boorstyn, "Single-tone parameter estimation from discrete-time
       observations", IEEE Trans. Inf. Theory 20(5) (1974) 591-598.
    """
    n = model.design.shape[0]
    phases, amps, var = [], [], 0.0
    for name, x in (("torque_nm", torque), ("wheel_speed_rad_s", wheel)):
        j = model.names.index(name)
        c, s = model.coef[:2, j]
        resid = x - model.design @ model.coef[:, j]
        var += local_noise_psd(resid, fs_hz, model.modulation_hz) / ((c * c + s * s) * n / fs_hz)
        phases.append(float(np.arctan2(-s, c)))
        amps.append(float(np.hypot(c, s)))
    lag = float(np.degrees(wrapped_angle(phases[0] - phases[1])))
    return SineFitResult(lag, float(np.degrees(np.sqrt(var))), amps[0], amps[1], phases[0],
                         phases[1], n, (0.0, n / fs_hz))


#: The paper's peak/valley estimator over its three middle periods scatters 1.21-1.32 times
#: the Cramér-Rao bound where the sine fit reaches 0.97-1.07 of it (benchmarks/phase_accuracy.py):
#: its standard error is taken as this factor times the sine fit's on the same data. Over the
#: whole cycle (``phase.paper_window = "cycle"``) it scatters 0.98-1.14 times the bound, so
#: the factor errs on the safe side there.
PAPER_SE_FACTOR = 1.3


def cycle_phase(c: CycleSignals, cfg: ProcessingConfig, *, center_index: float
                ) -> tuple[float, float, tuple[float, float]]:
    """Step 7: the phase of one cycle, its standard error and the window used.

    Parameters
    ----------
    c : CycleSignals
        The cycle.
    cfg : ProcessingConfig
        The chain's settings (phase method, periods).
    center_index : float
        Where the phase window is centred (the aligned middle) [samples].

    Returns
    -------
    phase_deg : float
        Lag of the wheel speed behind the torque [deg].
    stderr_deg : float
        Its standard error [deg].
    window_s : tuple of float
        Start and end of the window [s].
    """
    n = c.torque_filtered.size
    period_n = c.fs_hz / c.modulation_hz
    nuisance = (*c.notches_hz["wheel"], *c.notches_hz["platform"])
    if cfg.phase.sinefit_input == "model" and "speed_model" in c.extra:
        fit = model_phase(c.extra["speed_model"], c.torque_resampled, c.wheel_resampled,
                          c.fs_hz)
    elif cfg.phase.sinefit_input == "bandpassed":
        fit = sinefit_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend,
                            noise_from=(c.torque_notched, c.wheel_notched))
    else:
        fit = sinefit_phase(c.torque_notched, c.wheel_notched, c.fs_hz, c.modulation_hz,
                            nuisance_hz=nuisance, trend=cfg.phase.sinefit_trend)
    # the speed model's removal costs the modulation this much variance, and its fitted
    # columns leave the residual's noise density near the modulation too small (SpeedModel)
    # (sqrt is correctly rounded: math's is numpy's number)
    se_fit = fit.phase_stderr_deg * math.sqrt(c.extra.get("variance_factor", 1.0)
                                              / c.extra.get("noise_kept", 1.0))
    if cfg.phase.method == "sinefit":
        return fit.phase_deg, float(se_fit), fit.window_s
    n_periods = cfg.phase.n_periods
    if cfg.phase.paper_window == "cycle":  # every whole period between the trimmed edges
        n_periods = max(n_periods, math.floor(n / period_n + 1e-9
                                              - 2 * cfg.phase.edge_trim_periods))
    half = (n_periods / 2 + cfg.phase.edge_trim_periods) * period_n
    center = min(max(center_index, half), n - half)
    res = peak_valley_phase(c.torque_filtered, c.wheel_filtered, c.fs_hz, c.modulation_hz,
                            center_s=center / c.fs_hz, n_periods=n_periods)
    hw = n_periods / 2 / c.modulation_hz
    se = PAPER_SE_FACTOR * se_fit
    return res.phase_deg, float(se), (center / c.fs_hz - hw, center / c.fs_hz + hw)
