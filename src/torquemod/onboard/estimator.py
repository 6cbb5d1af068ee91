"""The on-board estimator (issue 10): sliding windows over a run's torque and axle speed,
and the friction along the track from the creep-coefficient progression.

:class:`OnboardEstimator` takes chunks as they arrive (``feed``) and returns the rows of the
windows that completed; the batch command feeds a recording through the same class, so both
give identical rows. Memory is bounded: one window of samples and the windows of the last
``memory_m`` metres.

mu along the track
------------------
The windows of the last ``memory_m`` metres (slips left out) are grouped by CoA into bins;
each bin gives one point (inverse-variance means; the standard error widened by the
windows' overlap). Every creep coefficient is turned into the phase it would have at the
current constant ``C = Omega*J*V/(R^2*N)`` (rigid relation ``tan(phi) = C/k``, V-Track paper
Eq. 1), so points at other speeds enter one fit, :func:`torquemod.phasefit.fit_mu_from_phase`
(C known). mu and its 95 % interval are given when that fit determines them; otherwise mu is
empty and ``mu_low_95`` carries the lower bound: the largest CoA (less two standard errors)
of the windows of the last ``bound_m`` metres only, because adhesion cannot exceed the
friction *where it was measured* (a longer memory carries a higher friction into a
low-adhesion patch). The fit is redone every ``refit_m`` metres.

Flags
-----
``slip``: the creepage exceeds ``slip_creepage`` or the axle accelerates faster than the
vehicle by ``slip_accel_m_s2``. ``low_adhesion``: the creep coefficient has fallen below
``low_adhesion_ratio`` of the reference (the 90th percentile of the creep coefficient over
the last ``baseline_m`` metres, i.e. its value at low utilisation), or the axle slips.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import asdict, dataclass, fields

import numpy as np

from ..errors import InputError, ProcessingError
from ..io.manifest import check_keys
from ..io.run import Vehicle
from ..phasefit import R_BOUNDS, fit_mu_from_phase
from .window import WindowResult, measure_window

#: The columns of track.parquet, in order (issue 10).
TRACK_COLUMNS = ("time_s", "position_m", "speed_m_s", "coa", "phase_deg", "phase_se_deg",
                 "creep_coefficient", "mu", "mu_low_95", "mu_high_95", "utilisation",
                 "low_adhesion", "slip")


@dataclass(frozen=True)
class OnboardConfig:
    """Settings of the estimator (``[onboard]`` in run.toml; defaults here)."""

    window_periods: int = 5
    hop_s: float = 0.25
    memory_m: float = 300.0
    bound_m: float = 40.0
    refit_m: float = 100.0
    n_bins: int = 8
    min_windows: int = 12
    min_coa_ratio: float = 2.0
    ratio_bounds: tuple[float, float] = R_BOUNDS
    baseline_m: float = 600.0
    low_adhesion_ratio: float = 0.35
    slip_creepage: float = 0.03
    slip_accel_m_s2: float = 0.8

    @classmethod
    def from_dict(cls, table: dict | None, *, source: str = "[onboard]") -> OnboardConfig:
        table = dict(table or {})
        check_keys(table, [f.name for f in fields(cls)], "[onboard]", source, error=InputError)
        if "ratio_bounds" in table:
            table["ratio_bounds"] = tuple(float(v) for v in table["ratio_bounds"])
        cfg = cls(**table)
        for f in fields(cls):
            v = getattr(cfg, f.name)
            if f.name != "ratio_bounds" and not (isinstance(v, int | float) and v > 0):
                raise InputError(f"[onboard] {f.name} must be a positive number, got {v!r}",
                                 path=source)
        return cfg

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


class MuTracker:
    """mu from the windows of the last ``memory_m`` metres (module docstring)."""

    def __init__(self, vehicle: Vehicle, frequency_hz: float, config: OnboardConfig,
                 overlap: float):
        self.v, self.f, self.cfg = vehicle, frequency_hz, config
        self.overlap = max(1.0, overlap)
        self.mem: deque[WindowResult] = deque()
        self.recent: deque[WindowResult] = deque()
        self.fit: _Fit | None = None
        self.n_fits = 0

    def add(self, w: WindowResult, slip: bool) -> None:
        if not slip:
            self.recent.append(w)
        while self.recent and self.recent[0].position_m < w.position_m - self.cfg.bound_m:
            self.recent.popleft()
        if not slip and math.isfinite(w.creep_coefficient) and w.creep_coefficient > 0:
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
        edges = np.linspace(coa.min(), coa.max(), self.cfg.n_bins + 1)
        idx = np.clip(np.searchsorted(edges, coa, side="right") - 1, 0, self.cfg.n_bins - 1)
        pts = []
        for b in range(self.cfg.n_bins):
            sel = idx == b
            if sel.sum() < 2:
                continue
            wgt = 1.0 / k_se[sel] ** 2
            k_b = float(np.sum(wgt * k[sel]) / wgt.sum())
            se_b = math.sqrt(self.overlap / wgt.sum())
            scatter = float(np.std(k[sel], ddof=1)) / math.sqrt(sel.sum() / self.overlap)
            pts.append((float(coa[sel].mean()), k_b, max(se_b, scatter)))
        return np.array(pts) if len(pts) >= 4 else None

    def _fit(self, w: WindowResult) -> _Fit:
        pts = self._points()
        if pts is None:
            return _Fit(w.position_m, None, math.nan, None)
        v = max(w.speed_m_s, 0.5)
        c = 2 * math.pi * self.f * self.v.inertia_kg_m2 * v / (
            self.v.wheel_radius_m ** 2 * self.v.normal_load_n)
        coa, k, k_se = pts.T
        phase = np.degrees(np.arctan(c / k))
        phase_se = np.degrees(c / (k * k + c * c) * k_se)
        self.n_fits += 1
        try:
            res = fit_mu_from_phase(coa, phase, phase_se, constant=c,
                                    ratio_bounds=self.cfg.ratio_bounds)
        except InputError:
            return _Fit(w.position_m, None, math.nan, None)
        if res.mu_determined and res.mu is not None:
            lo, hi = res.mu_interval_95
            return _Fit(w.position_m, float(res.mu), float(lo), float(hi))
        return _Fit(w.position_m, None, math.nan, None)

    def lower_bound(self) -> float:
        """Largest CoA less two standard errors over the last ``bound_m`` metres [-]."""
        return max((max(m.coa - 2 * m.coa_se, 0.0) for m in self.recent), default=math.nan)


class OnboardEstimator:
    """Sliding-window estimator over one axle; feed chunks of samples as they arrive.

    ``feed(torque_nm, wheel_speed_rad_s, vehicle_speed_m_s, position_m)`` (equal-length
    arrays at ``fs_hz``, the run's sample times from ``t0_s``) returns the rows of the
    windows completed by that chunk, as dicts with :data:`TRACK_COLUMNS` (and a few more).
    Windows start every ``hop`` samples from the first sample, so how the run is cut into
    chunks does not change any row.
    """

    def __init__(self, vehicle: Vehicle, frequency_hz: float, fs_hz: float, *,
                 config: OnboardConfig | None = None, t0_s: float = 0.0):
        self.v, self.f, self.fs, self.t0 = vehicle, float(frequency_hz), float(fs_hz), t0_s
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
        self.tracker = MuTracker(vehicle, self.f, self.cfg, self.n_win / self.hop)
        self.k_hist: deque[tuple[float, float]] = deque()

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

    def _baseline(self, w: WindowResult) -> float:
        while self.k_hist and self.k_hist[0][0] < w.position_m - self.cfg.baseline_m:
            self.k_hist.popleft()
        if len(self.k_hist) < 8:
            return math.nan
        return float(np.percentile([k for _, k in self.k_hist], 90))

    def _window(self, seg: np.ndarray, t_end: float) -> dict | None:
        try:
            w = measure_window(seg[0], seg[1], seg[2], seg[3], self.fs, t_end, self.v, self.f)
        except ProcessingError:
            return None
        slip = (w.creepage > self.cfg.slip_creepage
                or w.wheel_excess_accel_m_s2 > self.cfg.slip_accel_m_s2)
        k = w.creep_coefficient
        ref = self._baseline(w)
        low = bool(slip or (math.isfinite(k) and math.isfinite(ref)
                            and k < self.cfg.low_adhesion_ratio * ref))
        if math.isfinite(k) and not slip:
            self.k_hist.append((w.position_m, k))
        self.tracker.add(w, slip)
        fit = self.tracker.fit
        mu = fit.mu if fit is not None else None
        if mu is not None:
            lo, hi = fit.low, fit.high
        else:
            lo, hi = self.tracker.lower_bound(), None
        return {"time_s": w.time_s, "position_m": w.position_m, "speed_m_s": w.speed_m_s,
                "coa": w.coa, "phase_deg": w.phase_deg, "phase_se_deg": w.phase_se_deg,
                "creep_coefficient": k, "mu": math.nan if mu is None else mu,
                "mu_low_95": lo, "mu_high_95": math.nan if hi is None else hi,
                "utilisation": math.nan if mu is None else w.coa / mu,
                "low_adhesion": low, "slip": bool(slip),
                "creepage": w.creepage, "dc_torque_nm": w.dc_torque_nm,
                "accel_m_s2": w.accel_m_s2, "creep_coefficient_ref": ref}
