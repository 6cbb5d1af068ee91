"""The on-board estimator: sliding windows over a run's torque and axle speed,
and the friction along the track from the creep-coefficient progression.

:class:`OnboardEstimator` takes chunks as they arrive (``feed``) and returns the rows of the
windows that completed; the batch command feeds a recording through the same class, so both
give identical rows. Memory is bounded: one window of samples and the windows of the last
``memory_m`` metres.

mu along the track
------------------
The steady windows since the last friction change (at most ``memory_m`` metres; slips and
windows with a DC torque step inside left out) are sorted by CoA and grouped (up to
``n_bins`` groups); each group gives one point (inverse-variance mean of k; its standard error
the larger of the windows' own, widened by their overlap, and the group's scatter, plus a
relative model error ``model_rel_error``). :func:`torquemod.ontrain.mufit.fit_creep_progression`
(the one estimator of :mod:`torquemod.analysis.friction`) fits a broad family of creep laws (Polach
with constant and falling friction, Burckhardt, saturating laws) and gives the **available
adhesion** (the maximum of the adhesion-creepage curve; track.parquet's ``mu``) with its 95 %
profile interval over the whole family. mu is reported
only when that interval is closed and within ``max_rel_half_width``, no change is suspected,
the current window is steady (or, while the torque steps, the last steady window's row gave
mu less than half a window's length back and the window's CoA plus its whole step is not above
mu: a step's windows cannot confirm the curve, but the fit does not depend on them), its
CoA is not above the fit, and a window worked at
``info_utilisation`` of mu or more within the last ``info_m`` metres (at low utilisation the
creep coefficient hardly depends on mu, so a fit is not carried far past its evidence).
Otherwise mu is empty and ``mu_low_95`` is the lower bound: the CoA less two standard errors
of the windows of the last ``bound_m`` metres (by default the current window alone), because
adhesion cannot exceed the friction where it was measured. The fit is redone every
``refit_m`` metres.

Per segment
-----------
When the run has ended (:meth:`OnboardEstimator.finish`), each segment between detected
friction changes is fitted once more from all its steady windows held, leaving out those
within a window's length of a change (they may mix two frictions):
:class:`~torquemod.ontrain.mufit.SegmentFit`, the table ``segments.csv``. A live row
cannot have that fit (it uses windows after the row), so the rows' mu stays the causal one.

Friction changes
----------------
:class:`ChangeDetector`: a two-sided CUSUM of each steady window's log creep coefficient
against the current fitted curve; at an alarm the memory is cut at the change's start. A
window whose CoA lies beyond the fitted curve counts as strong evidence even when stepping.

Flags
-----
``slip``: the creepage exceeds ``slip_creepage`` or the axle accelerates faster than the
vehicle by ``slip_accel_m_s2``. ``low_adhesion``: the creep coefficient has fallen below
``low_adhesion_ratio`` of the reference (the median creep coefficient of the windows of the
last ``baseline_m`` metres whose CoA is in the lowest 40 %: its value at low utilisation,
robust to the heavy-tailed k of single windows; a 90th percentile was inflated 4x at 8 Hz)
in a steady window (a DC torque step inside a window corrupts its k: measured, all false
flags on dry rail came from such windows), or the axle slips.

The premise of a window
-----------------------
A window whose torque has no modulation line at the declared frequency, whose train stands
or runs backwards gives no numbers: its row keeps time, position and speed, ``quality`` says
why (:mod:`torquemod.ontrain.quality`), and it leaves the state alone.

Delay between torque and speed
------------------------------
A net delay of the torque signal behind the speed's that run.toml does not declare biases k
(~4 % per ms at 4 Hz). With ``calibrate_delay`` (default) :class:`~torquemod.ontrain.delay.
DelayCalibrator` measures it from the steady windows seen so far (the vehicle's impedance
does not change with the operating point); once its standard error is below
``delay_max_se_s`` every window's phase and k are taken with it, and the windows the mu fit
holds are corrected too (when the estimate moves by more than a quarter of that). An
estimate that is not trusted (too few operating points yet, or the crossing lost) leaves the
last trusted one in place. Delays are searched in both directions (a speed counted over a
gate is half a gate late: 5 ms at 200 Hz with a two-sample gate), within ``delay_max_s``
and a sixth of the modulation period (:func:`~torquemod.ontrain.delay.delay_grid`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    Check,
    between,
    default_checks,
    one_of,
    read_table,
)
from torquemod.analysis.phasefit import R_BOUNDS
from torquemod.errors import InputError, ProcessingError
from torquemod.io.run import Vehicle
from torquemod.ontrain.delay import DelayCalibrator, delay_grid
from torquemod.ontrain.mufit import (
    CreepFit,
    SegmentFit,
    fit_creep_progression,
    fit_segment,
    group_points,
)
from torquemod.ontrain.quality import QUALITY_OK, window_quality
from torquemod.ontrain.window import WindowResult, measure_window, with_delay

#: The columns of track.parquet, in order.
TRACK_COLUMNS = ("time_s", "position_m", "speed_m_s", "coa", "phase_deg", "phase_se_deg",
                 "creep_coefficient", "mu", "mu_low_95", "mu_high_95", "utilisation",
                 "low_adhesion", "slip", "quality")


@dataclass(frozen=True)
class OnboardConfig:
    """Settings of the on-board estimator (``[onboard]`` in run.toml).

    The defaults are the field defaults here (chosen on the twin's and the independent
    generator's train runs; :mod:`torquemod.ontrain.estimator` explains each mechanism).
    :meth:`from_dict` reads and checks a run.toml table.

    Attributes
    ----------
    window_periods : int
        Modulation periods per window [-]. Default 5.
    hop_s : float
        Time between the starts of consecutive windows [s]. Default 0.25.
    memory_m : float
        Longest stretch of track whose windows the mu fit holds [m]. Default 1500.
    bound_m : float
        Stretch over which the lower bound ``mu_low_95`` is taken [m]. Default 1 (the current
        window alone).
    refit_m : float
        Distance between refits of the creep progression [m]. Default 100.
    change_drift : float
        Drift (allowance) of the CUSUM friction-change detector per window, in standard
        deviations of the log creep coefficient [-]. Default 1.
    change_threshold : float
        Alarm threshold of the CUSUM sums [-] (same unit). Default 10.
    max_rel_half_width : float
        Largest relative half-width of mu's 95 % profile interval for mu to be reported [-].
        Default 0.25.
    model_rel_error : float
        Relative systematic error of each grouped point's creep coefficient [-]. Default 0.02:
        on the independent train runs the median measured/true creep coefficient differs
        between the staircase's levels by up to 0.04 (benchmarks/onboard_independent.py).
    max_dc_step_ratio : float
        Largest DC torque step within a window, over the modulation amplitude, for the window
        to count as steady [-]. Default 0.25.
    info_utilisation : float
        Share of mu a steady window must have worked at within ``info_m`` for mu to be
        reported [-]. Default 0.5.
    info_m : float
        Distance over which that evidence counts [m]. Default 30.
    n_bins : int
        Largest number of CoA groups the windows are pooled into for the fit [-]. Default 12.
    min_windows : int
        Fewest steady windows before a fit is tried [-]. Default 12.
    min_coa_ratio : float
        Smallest ratio of the highest to the lowest group CoA for a fit [-]. Default 2.
    ratio_bounds : tuple of float
        Bounds of the fitted ratio of mu to the largest measured CoA [-]. Default
        :data:`torquemod.analysis.phasefit.R_BOUNDS`.
    power_shapes : int
        1: include the saturating power-law shapes in the family of creep laws; 0: leave them
        out. Default 1.
    model_swing : int
        1: fit the windows' slopes as the describing function of the curve over the
        modulation's creepage swing; 0: as small-signal slopes. Default 1.
    baseline_m : float
        Stretch whose low-CoA windows give the reference creep coefficient of the
        ``low_adhesion`` flag [m]. Default 600.
    low_adhesion_ratio : float
        ``low_adhesion`` when k falls below this share of the reference [-]. Default 0.25.
    slip_creepage : float
        ``slip`` when the creepage exceeds this [-]. Default 0.03.
    slip_accel_m_s2 : float
        ``slip`` when the axle accelerates faster than the vehicle by this [m/s^2].
        Default 0.8.
    calibrate_delay : int
        1: estimate the net torque-to-speed delay from the run
        (:class:`~torquemod.ontrain.delay.DelayCalibrator`); 0: do not. Default 1.
    delay_max_s : float
        Largest delay searched, either sign [s]. Default 0.02.
    delay_max_se_s : float
        Standard error below which a delay estimate is used [s]. Default 5e-4.
    delay_min_windows : int
        Fewest steady windows before a delay is estimated [-]. Default 40.
    min_speed_m_s : float
        Reference speed below which the train counts as standing [m/s]. Default 1 (twice the
        0.5 m/s floor of the creepage's reference speed).
    min_modulation_ratio : float
        Share of the declared modulation amplitude the torque's line must reach [-].
        Default 0.25 (windows of the twin's and the independent runs reach > 0.3 even across
        a DC step).
    """

    window_periods: int = 5
    hop_s: float = 0.25
    memory_m: float = 1500.0
    bound_m: float = 1.0
    refit_m: float = 100.0
    change_drift: float = 1.0
    change_threshold: float = 10.0
    max_rel_half_width: float = 0.25
    #: each point's relative systematic error: on the independent train runs the median
    #: measured/true creep coefficient differs between the staircase's levels by up to
    #: 0.04 (0.987 at 20 %, 1.028 at 60 % of the adhesion; benchmarks/onboard_independent.py)
    model_rel_error: float = 0.02
    max_dc_step_ratio: float = 0.25
    info_utilisation: float = 0.5
    info_m: float = 30.0
    n_bins: int = 12
    min_windows: int = 12
    min_coa_ratio: float = 2.0
    ratio_bounds: tuple[float, float] = R_BOUNDS
    power_shapes: int = 1
    #: fit the windows' slopes as the describing function of the curve over the
    #: modulation's creepage swing (1) or as small-signal slopes (0)
    model_swing: int = 1
    baseline_m: float = 600.0
    low_adhesion_ratio: float = 0.25
    slip_creepage: float = 0.03
    slip_accel_m_s2: float = 0.8
    calibrate_delay: int = 1
    delay_max_s: float = 0.02
    delay_max_se_s: float = 5e-4
    delay_min_windows: int = 40
    #: the premise of a window (:mod:`torquemod.ontrain.quality`): the reference speed
    #: [m/s] below which the train counts as standing (twice the 0.5 m/s floor of the
    #: creepage's reference speed; ours) and the share of the declared modulation amplitude
    #: the torque's line must reach (ours: windows of the twin's and the independent runs
    #: reach > 0.3 even across a DC step)
    min_speed_m_s: float = 1.0
    min_modulation_ratio: float = 0.25

    @classmethod
    def from_dict(cls, table: dict | None, *, source: str = "[onboard]") -> OnboardConfig:
        """The settings from run.toml's ``[onboard]`` table.

        Parameters
        ----------
        table : dict or None
            The table; None gives the defaults.
        source : str
            What to name in error messages (the file). Default ``"[onboard]"``.

        Returns
        -------
        OnboardConfig
            The checked settings.

        Raises
        ------
        InputError
            An unknown key (with the nearest known one), a value of the wrong type or out of
            its range (:func:`torquemod._util.tomlcheck.read_table`; ``ratio_bounds``
            ``[low, high]`` with 0 < low < high); the message names ``source`` and the key.
        """
        return read_table(cls, table, section="onboard", path=source, checks=_CHECKS)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["ratio_bounds"] = list(self.ratio_bounds)
        return d


@dataclass
class _Fit:
    position_m: float
    mu: float | None
    low: float
    high: float | None
    model: CreepFit | None = None


#: ranges of the [onboard] settings (besides their types): positive unless listed here
_CHECKS = default_checks(OnboardConfig, {
    "power_shapes": one_of(0, 1), "calibrate_delay": one_of(0, 1),
    "model_swing": one_of(0, 1),
    "window_periods": between(1, None), "n_bins": between(1, None),
    "min_windows": between(1, None), "delay_min_windows": between(1, None),
    "info_utilisation": between(0.0, 1.0, lo_open=True),
    "min_modulation_ratio": between(0.0, 1.0),
    "low_adhesion_ratio": between(0.0, 1.0, lo_open=True),
    "change_drift": NON_NEGATIVE, "delay_max_s": NON_NEGATIVE,
    "ratio_bounds": Check(lo=0.0, lo_open=True, test=lambda b: b[0] < b[1],
                          need="[low, high] with 0 < low < high")})


class ChangeDetector:
    """Two-sided CUSUM detector of friction changes along the track.

    The statistic is each window's log creep coefficient against the current fitted curve,
    ``z = ln(k/k_fit(CoA))/s`` with ``s^2 = (k_se/k)^2 + model_rel^2``; a window above the
    fitted mu counts as ``+z_cap``. An alarm when either sum exceeds ``threshold`` returns the
    position where that sum last left zero: where the friction changed.

    Parameters
    ----------
    drift : float
        Allowance subtracted from |z| at each window [-] (standard deviations).
    threshold : float
        Alarm level of either cumulative sum [-].
    model_rel : float
        Relative model error added to each window's relative standard error [-].
        Default 0.25.
    z_cap : float
        Largest |z| one window contributes [-]. Default 6.

    Notes
    -----
    Upper sum ``S+ = max(0, S+ + z - drift)``, lower sum ``S- = max(0, S- - z - drift)``;
    alarm when ``max(S+, S-) > threshold`` [1]_.

    References
    ----------
    .. [1] E.S. Page, "Continuous inspection schemes", Biometrika 41(1/2) (1954) 100-115.
    """

    def __init__(self, drift: float, threshold: float, model_rel: float = 0.25,
                 z_cap: float = 6.0):
        self.drift, self.threshold, self.model_rel, self.z_cap = drift, threshold, model_rel, z_cap
        self.reset()

    def reset(self) -> None:
        self.up = self.down = 0.0
        self.last_z = 0.0
        self.up_start = self.down_start = math.nan

    def update(self, w: WindowResult, model: CreepFit | None, steady: bool = True
               ) -> float | None:
        """Add a window; the change position when the CUSUM alarms, else None. An unsteady
        window (a DC step inside it) counts only when its CoA lies beyond the curve."""
        k = w.creep_coefficient
        if model is None:
            return None
        pred = float(model.creep_coefficient(w.coa))
        beyond = not (math.isfinite(pred) and pred > 0)
        if not beyond and not (steady and math.isfinite(k) and k > 0):
            return None
        if beyond:
            z = self.z_cap
        else:
            rel = w.creep_coefficient_se / k if math.isfinite(w.creep_coefficient_se) else 1.0
            z = math.log(k / pred) / math.hypot(rel, self.model_rel)
            z = max(-self.z_cap, min(self.z_cap, z))
        if self.up == 0.0:
            self.up_start = w.position_m
        if self.down == 0.0:
            self.down_start = w.position_m
        self.up = max(0.0, self.up + z - self.drift)
        self.down = max(0.0, self.down - z - self.drift)
        self.last_z = z
        if self.up > self.threshold or self.down > self.threshold:
            start = self.up_start if self.up > self.threshold else self.down_start
            self.reset()
            return start
        return None

    @property
    def suspicious(self) -> bool:
        """A change may be under way: a sum above a third of the threshold, or the last
        window far off the curve (then the fitted mu is withheld, not reported)."""
        return (max(self.up, self.down) > self.threshold / 3
                or abs(self.last_z) >= self.z_cap / 2)


class MuTracker:
    """mu from the windows since the last friction change.

    Holds at most ``config.memory_m`` metres of steady windows, refits the creep progression
    (:func:`~torquemod.ontrain.mufit.fit_creep_progression`) every ``config.refit_m`` metres
    and cuts the memory at a detected change (:class:`ChangeDetector`); see the module
    docstring for when mu is reported.

    Parameters
    ----------
    vehicle : torquemod.io.run.Vehicle
        The vehicle.
    frequency_hz : float
        Modulation frequency [Hz].
    config : OnboardConfig
        The estimator's settings.
    overlap : float
        How many windows overlap each sample (window length over hop) [-]; at least 1. Widens
        the grouped points' standard errors.
    window_s : float
        One window's duration [s]: windows this close to a change are left out of the
        segments' fits. Default 0.
    """

    def __init__(self, vehicle: Vehicle, frequency_hz: float, config: OnboardConfig,
                 overlap: float, window_s: float = 0.0):
        self.v, self.f, self.cfg = vehicle, frequency_hz, config
        self.overlap = max(1.0, overlap)
        self.window_s = window_s  # one window's duration [s]: the segments' guard
        self.seg_start: float | None = None  # where the current segment began [m]
        self.seg_from_change = False  # it began at a detected change (not the run's start)
        self.segments: list[SegmentFit] = []
        self._finished = False
        self.mem: deque[WindowResult] = deque()
        self.recent: deque[WindowResult] = deque()
        self.fit: _Fit | None = None
        self.n_fits = 0
        self.detector = ChangeDetector(config.change_drift, config.change_threshold)
        self.changes: list[float] = []

    def add(self, w: WindowResult, slip: bool) -> None:
        model = self.fit.model if self.fit is not None else None
        steady = w.dc_step_ratio <= self.cfg.max_dc_step_ratio
        change = None if slip else self.detector.update(w, model, steady)
        if self.seg_start is None:
            self.seg_start = w.position_m
        if change is not None:
            self.changes.append(change)
            self.segments.append(self._segment(self.seg_start, change, end_guard=True))
            self.seg_start, self.seg_from_change = change, True
            # the fit keeps the windows from half a window past the change on (one reaching
            # further back mixes the two frictions); the lower bound all since the change
            cut_m = change + 0.5 * self.window_s * w.speed_m_s
            while self.mem and self.mem[0].position_m < cut_m:
                self.mem.popleft()
            while self.recent and self.recent[0].position_m < change:
                self.recent.popleft()
            self.fit = None
        if not slip:
            self.recent.append(w)
        while self.recent and self.recent[0].position_m < w.position_m - self.cfg.bound_m:
            self.recent.popleft()
        steady = w.dc_step_ratio <= self.cfg.max_dc_step_ratio
        if (not slip and steady and math.isfinite(w.creep_coefficient)
                and w.creep_coefficient > 0):
            self.mem.append(w)
        while self.mem and self.mem[0].position_m < w.position_m - self.cfg.memory_m:
            self.mem.popleft()
        due = self.fit is None or w.position_m - self.fit.position_m >= self.cfg.refit_m
        if due and len(self.mem) >= self.cfg.min_windows:
            self.fit = self._fit(w)
        elif self.fit is not None and w.position_m - self.fit.position_m > self.cfg.memory_m:
            self.fit = None

    def _points(self):
        coa = np.array([m.coa for m in self.mem])
        k = np.array([m.creep_coefficient for m in self.mem])
        k_se = np.array([m.creep_coefficient_se for m in self.mem])
        ok = (coa > 0) & np.isfinite(k_se) & (k_se > 0)
        coa, k, k_se = coa[ok], k[ok], k_se[ok]
        if coa.size < self.cfg.min_windows or coa.max() < self.cfg.min_coa_ratio * coa.min():
            return None
        swing = np.array([m.creepage_swing for m in self.mem])[ok]
        return group_points(coa, k, k_se, overlap=self.overlap, n_bins=self.cfg.n_bins,
                            model_rel_error=self.cfg.model_rel_error,
                            swing=np.nan_to_num(swing) if self.cfg.model_swing else None)

    def _segment(self, start_m: float, end_m: float, *, end_guard: bool) -> SegmentFit:
        """The fit of the segment ``[start_m, end_m]`` [m] from the windows held: those
        more than a window's length [m] inside a detected change (a window reaching across
        it mixes the two frictions; the change's position is itself uncertain by about
        that much), or all of them when fewer than ``min_windows`` remain so."""
        held = [m for m in self.mem if start_m <= m.position_m <= end_m]
        speed = float(np.median([m.speed_m_s for m in held])) if held else 0.0
        guard = self.window_s * speed
        a = start_m + (guard if self.seg_from_change else 0.0)
        b = end_m - (guard if end_guard else 0.0)
        inner = [m for m in held if a <= m.position_m <= b]
        use = inner if len(inner) >= self.cfg.min_windows else held
        c = self.cfg
        return fit_segment([m.coa for m in use], [m.creep_coefficient for m in use],
                           [m.creep_coefficient_se for m in use], start_m, end_m,
                           swing=[m.creepage_swing for m in use] if c.model_swing else None,
                           overlap=self.overlap, n_bins=c.n_bins,
                           model_rel_error=c.model_rel_error, min_windows=c.min_windows,
                           min_coa_ratio=c.min_coa_ratio, ratio_bounds=c.ratio_bounds,
                           power=bool(c.power_shapes), max_rel_half_width=c.max_rel_half_width,
                           speed_m_s=speed or None)

    def finish(self, end_m: float | None = None) -> list[SegmentFit]:
        """Close the last segment (at ``end_m`` [m], by default the last window held) and
        return every segment's fit, in order (:class:`~torquemod.ontrain.mufit.SegmentFit`).
        Idempotent: a second call returns the same list."""
        if self.seg_start is not None and not self._finished:
            last = end_m if end_m is not None else max(
                (m.position_m for m in self.mem), default=self.seg_start)
            self.segments.append(self._segment(self.seg_start, last, end_guard=False))
            self._finished = True
        return list(self.segments)

    def _fit(self, w: WindowResult) -> _Fit:
        pts = self._points()
        speed = float(np.median([m.speed_m_s for m in self.mem])) if self.mem else None
        res = None if pts is None else fit_creep_progression(
            *pts[:, :3].T, coa_now=w.coa, ratio_bounds=self.cfg.ratio_bounds,
            power=bool(self.cfg.power_shapes),
            max_rel_half_width=self.cfg.max_rel_half_width, speed_m_s=speed,
            swing=pts[:, 3] if pts.shape[1] > 3 else None)
        self.n_fits += pts is not None
        if res is None:
            return _Fit(w.position_m, None, math.nan, None)
        if res.determined:
            return _Fit(w.position_m, res.mu, res.mu_low, res.mu_high, res)
        return _Fit(w.position_m, None, math.nan, None, res)

    def shift_delay(self, delay_s: float) -> None:
        """Take a further net delay ``delay_s`` [s] out of the windows held (the delay
        estimate moved); the next regular refit uses them."""
        for q in (self.mem, self.recent):
            kept = [with_delay(m, self.v, self.f, delay_s) for m in q]
            q.clear()
            q.extend(kept)

    def informed(self, position_m: float, mu: float) -> bool:
        """A steady window worked at ``info_utilisation`` of mu or more within the last
        ``info_m`` metres: at low utilisation the creep coefficient hardly depends on mu
        (wet and leaf-covered rail look alike there), so a fit is only carried that far."""
        level = self.cfg.info_utilisation * mu
        for m in reversed(self.mem):
            if m.position_m < position_m - self.cfg.info_m:
                return False
            if m.coa >= level:
                return True
        return False

    def lower_bound(self) -> float:
        """Largest CoA less two standard errors over the last ``bound_m`` metres [-]."""
        return max((max(m.coa - 2 * m.coa_se, 0.0) for m in self.recent), default=math.nan)


class OnboardEstimator:
    """Sliding-window estimator of the friction over one axle; feed chunks as they arrive.

    ``feed(torque_nm, wheel_speed_rad_s, vehicle_speed_m_s, position_m)`` (equal-length
    arrays at ``fs_hz``, the run's sample times from ``t0_s``) returns the rows of the windows
    completed by that chunk, as dicts with :data:`TRACK_COLUMNS` (and a few more). Windows
    start every ``hop`` samples from the first sample, so how the run is cut into chunks does
    not change any row.

    Parameters
    ----------
    vehicle : torquemod.io.run.Vehicle
        The vehicle (radius, load, inertia, drive line, sensor dynamics).
    frequency_hz : float
        Modulation frequency [Hz].
    fs_hz : float
        Sampling rate of the chunks [Hz].
    config : OnboardConfig or None
        The settings; None: :class:`OnboardConfig` defaults.
    t0_s : float
        Time of the first sample [s]. Default 0.
    amplitude_nm : float or None
        Declared modulation amplitude [N*m]; when given, each window's line is checked against
        it (``min_modulation_ratio``). Default None.

    Raises
    ------
    InputError
        A window of ``window_periods`` periods holds fewer than 8 samples at ``fs_hz``.
    """

    def __init__(self, vehicle: Vehicle, frequency_hz: float, fs_hz: float, *,
                 config: OnboardConfig | None = None, t0_s: float = 0.0,
                 amplitude_nm: float | None = None):
        self.v, self.f, self.fs, self.t0 = vehicle, float(frequency_hz), float(fs_hz), t0_s
        self.amplitude_nm = amplitude_nm  # declared [N*m]: a window's line is checked
        self.cfg = config or OnboardConfig()
        n_win = self.cfg.window_periods * self.fs / self.f
        self.n_win = round(n_win)
        self.hop = max(1, round(self.cfg.hop_s * self.fs))
        if self.n_win < 8:
            raise InputError(f"a window of {self.cfg.window_periods} periods holds only "
                             f"{self.n_win} samples at {self.fs:g} Hz",
                             hint="record faster or use more periods per window")
        self.buf = np.empty((4, 0))
        self.buf_start = 0  # global index of buf[:, 0]
        self.next_start = 0  # global index of the next window's first sample
        self.tracker = MuTracker(vehicle, self.f, self.cfg, self.n_win / self.hop,
                                 self.n_win / self.fs)
        self.k_hist: deque[tuple[float, float, float]] = deque()  # (position, CoA, k)
        c = self.cfg
        self.delay = DelayCalibrator(vehicle, self.f, delay_grid(c.delay_max_s, self.f),
                                     min_windows=c.delay_min_windows,
                                     max_se_s=c.delay_max_se_s)
        self.delay_s = 0.0  # the net delay taken out of every window now [s]
        self._steady_gave_at: float | None = None  # where the last steady row gave mu [m]

    def feed(self, torque_nm, wheel_speed_rad_s, vehicle_speed_m_s, position_m) -> list[dict]:
        chunk = np.vstack([np.asarray(a, dtype=np.float64) for a in
                           (torque_nm, wheel_speed_rad_s, vehicle_speed_m_s, position_m)])
        self.buf = np.concatenate([self.buf, chunk], axis=1)
        rows = []
        end = self.buf_start + self.buf.shape[1]
        while self.next_start + self.n_win <= end:
            a = self.next_start - self.buf_start
            seg = self.buf[:, a:a + self.n_win]
            t_end = self.t0 + (self.next_start + self.n_win - 1) / self.fs
            row = self._window(seg, t_end)
            if row is not None:
                rows.append(row)
            self.next_start += self.hop
        drop = self.next_start - self.buf_start
        if drop > 0:
            self.buf = self.buf[:, drop:].copy()
            self.buf_start = self.next_start
        return rows

    def finish(self) -> list[dict]:
        """The run has ended: the per-segment table (rows of
        :data:`~torquemod.ontrain.mufit.SEGMENT_COLUMNS`), each segment between detected
        friction changes fitted from all its windows (:meth:`MuTracker.finish`)."""
        return [s.to_dict(i + 1) for i, s in enumerate(self.tracker.finish())]

    def _baseline(self, w: WindowResult) -> float:
        while self.k_hist and self.k_hist[0][0] < w.position_m - self.cfg.baseline_m:
            self.k_hist.popleft()
        if len(self.k_hist) < 8:
            return math.nan
        coa = np.array([c for _, c, _ in self.k_hist])
        k = np.array([kk for _, _, kk in self.k_hist])
        low = k[coa <= np.percentile(coa, 40)]  # the low-utilisation windows: k near k0
        return float(np.median(low))

    def _window(self, seg: np.ndarray, t_end: float) -> dict | None:
        w = self.measure(seg, t_end)
        return None if w is None else self.update(w)

    def measure(self, seg: np.ndarray, t_end: float) -> WindowResult | None:
        """The window ``seg`` (4 x ``n_win``: torque, wheel speed, reference speed,
        position) ending at ``t_end`` [s] measured on its own (no state; None when it
        cannot be measured): the part of the work that chunks of a run can do apart."""
        try:
            return measure_window(seg[0], seg[1], seg[2], seg[3], self.fs, t_end, self.v,
                                  self.f)
        except ProcessingError:
            return None

    def _calibrated(self, w: WindowResult, steady: bool) -> WindowResult:
        """``w`` with the net delay measured so far taken out (module docstring)."""
        if steady and math.isfinite(w.creep_coefficient):
            self.delay.add(w.torque_speed_ratio, math.radians(w.phase_se_deg))
            est = self.delay.estimate() if self.delay.n % 4 == 0 else None  # every 4th
            # an estimate that is not (or no longer) trusted leaves the last trusted one
            if est is not None and est.trusted and abs(est.delay_s - self.delay_s) > \
                    0.25 * self.cfg.delay_max_se_s:
                self.tracker.shift_delay(est.delay_s - self.delay_s)
                self.delay_s = est.delay_s
        return with_delay(w, self.v, self.f, self.delay_s)

    def update(self, w: WindowResult) -> dict:
        """The row of a measured window, advancing the state (slip, reference creep
        coefficient, mu tracker); windows must come in order. A window without the
        method's premise (:func:`~torquemod.ontrain.quality.window_quality`) keeps its time,
        position and speed, the rest empty, and leaves the state alone."""
        step_nm = w.dc_step_ratio * max(w.torque_amplitude_nm, 1e-12)
        quality = window_quality(w.speed_m_s, w.wheel_speed_rad_s, w.torque_amplitude_nm,
                                 amplitude_nm=self.amplitude_nm,
                                 min_speed_m_s=self.cfg.min_speed_m_s,
                                 min_modulation_ratio=self.cfg.min_modulation_ratio,
                                 dc_step_nm=step_nm, max_step_ratio=self.cfg.max_dc_step_ratio)
        if quality != QUALITY_OK:
            nan = math.nan
            return {"time_s": w.time_s, "position_m": w.position_m, "speed_m_s": w.speed_m_s,
                    "coa": w.coa if quality == "no_modulation" else nan, "phase_deg": nan,
                    "phase_se_deg": nan, "creep_coefficient": nan, "mu": nan,
                    "mu_low_95": nan, "mu_high_95": nan, "utilisation": nan,
                    "low_adhesion": False, "slip": False, "quality": quality,
                    "creepage": nan, "dc_torque_nm": w.dc_torque_nm,
                    "accel_m_s2": w.accel_m_s2, "creep_coefficient_ref": nan,
                    "dc_step_ratio": w.dc_step_ratio, "dc_step_nm": step_nm,
                    "delay_s": self.delay_s}
        slip = (w.creepage > self.cfg.slip_creepage
                or w.wheel_excess_accel_m_s2 > self.cfg.slip_accel_m_s2)
        steady = w.dc_step_ratio <= self.cfg.max_dc_step_ratio  # a step corrupts k
        if self.cfg.calibrate_delay:
            w = self._calibrated(w, steady and not slip)
        k = w.creep_coefficient
        ref = self._baseline(w)
        low = bool(slip or (steady and math.isfinite(k) and math.isfinite(ref)
                            and k < self.cfg.low_adhesion_ratio * ref))
        if math.isfinite(k) and not slip and steady:
            self.k_hist.append((w.position_m, w.coa, k))
        self.tracker.add(w, slip)
        fit = self.tracker.fit
        mu = fit.mu if fit is not None and not self.tracker.detector.suspicious else None
        stepping = w.dc_step_ratio > self.cfg.max_dc_step_ratio
        if stepping and mu is not None:
            # the torque is stepping: the window cannot confirm the curve; it keeps mu only
            # when the last steady window gave it less than half a window's length back (a
            # window centred further on reaches mostly past that evidence: measured, such
            # rows carried a leaf segment's mu into dry rail) and the adhesion the step may
            # reach (its mean CoA plus the whole step) is not above mu
            near = self._steady_gave_at is not None and (
                w.position_m - self._steady_gave_at <= 0.5 * self.n_win / self.fs * w.speed_m_s)
            top = w.coa + step_nm / (self.v.normal_load_n * self.v.wheel_radius_m)
            if not near or top - 2 * w.coa_se > mu:
                mu = None
        if mu is not None and w.coa - 2 * w.coa_se > mu:
            mu = None  # the window's adhesion is above the fitted friction: the fit is stale
        if mu is not None and not self.tracker.informed(w.position_m, mu):
            mu = None  # no window near saturation lately: a change would go unseen
        if not stepping:
            self._steady_gave_at = w.position_m if mu is not None else None
        if mu is not None and fit is not None:
            lo, hi = fit.low, fit.high
        else:
            lo, hi = self.tracker.lower_bound(), None
        return {"time_s": w.time_s, "position_m": w.position_m, "speed_m_s": w.speed_m_s,
                "coa": w.coa, "phase_deg": w.phase_deg, "phase_se_deg": w.phase_se_deg,
                "creep_coefficient": k, "mu": math.nan if mu is None else mu,
                "mu_low_95": lo, "mu_high_95": math.nan if hi is None else hi,
                "utilisation": math.nan if mu is None else w.coa / mu,
                "low_adhesion": low, "slip": bool(slip), "quality": QUALITY_OK,
                "creepage": w.creepage, "dc_torque_nm": w.dc_torque_nm,
                "accel_m_s2": w.accel_m_s2, "creep_coefficient_ref": ref,
                "dc_step_ratio": w.dc_step_ratio, "dc_step_nm": step_nm,
                "delay_s": self.delay_s}
