"""An independent rig for checking the processing chain's phase (imports nothing of torquemod).

The rig's equations are written out here, apart from the twin (:mod:`torquemod.twins.vtrack.rig`): a
motor
drives the wheel through an elastic shaft; the wheel rolls on a platform whose speed is
prescribed (an ideal speed loop) and may wobble; the creep force follows Polach's law with
constant friction (Polach, Wear 258 (2005) 992-1000, Eq. 7 with the reduction factors kA, kS):

    F(xi) = (2 N mu / pi) [kA e / (1 + (kA e)^2) + atan(kS e)],  e = C xi / (N mu)

with xi = (w R - W Rp)/(W Rp) and C [N] the contact's lumped stiffness. States: shaft twist,
motor speed, wheel speed; scipy's DOP853 integrates them (rtol 1e-10) and its dense output
gives the samples.

The phase of a record (the definition in docs/processing.md, "The phase of a moving
operating point"): the same run is simulated twice, with and without the torque modulation,
from the same state and with the same wobble; the difference of the two is the part of each
channel that the modulation causes. Over the span analysed, the phase is that of its
least-squares sinusoid at the modulation frequency fitted beside the 2nd and 3rd harmonics
and the variation slower than 0.4 x the modulation frequency (Legendre polynomials and
Slepian sequences, scipy's): ``arg(C_T / C_w)``, positive when the wheel speed lags the
shaft torque. For a slowly moving operating point it is the lag of the span-averaged complex
answer of the wheel, ``arg(<A_T(t)> / <A_w(t)>)``; with a steady speed it is the periodic
orbit's phase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar


@dataclass(frozen=True)
class OrbitRig:
    """A V-Track-like rig (values chosen here; SI units)."""

    wheel_radius_m: float = 0.0675
    platform_radius_m: float = 2.0
    speed_m_s: float = 7.0 / 3.6
    normal_load_n: float = 4200.0
    wheel_inertia_kg_m2: float = 4.0
    drive_inertia_kg_m2: float = 0.8
    shaft_stiffness_nm_rad: float = 2.0e4
    shaft_damping_nm_s_rad: float = 15.0
    mu: float = 0.25
    k_a: float = 0.2
    k_s: float = 0.2
    contact_stiffness_n: float = 4.25e5

    @property
    def revolution_s(self) -> float:
        """One platform revolution at the nominal speed [s]."""
        return 2.0 * math.pi * self.platform_radius_m / self.speed_m_s


@dataclass(frozen=True)
class Wobble:
    """Relative platform-speed variation ``sum a sin(2 pi f t + p)`` over ``lines`` (a, f [Hz],
    p [rad]) plus ``sum a sin(k W0 t + p)`` over ``orders`` (a, k, p): once and twice per
    nominal revolution."""

    lines: tuple[tuple[float, float, float], ...] = ()
    orders: tuple[tuple[float, int, float], ...] = ()

    def ratio(self, t: float, w0: float) -> float:
        s = 1.0
        for a, f, p in self.lines:
            s += a * math.sin(2.0 * math.pi * f * t + p)
        for a, k, p in self.orders:
            s += a * math.sin(k * w0 * t + p)
        return s


def creep_force_n(rig: OrbitRig, xi: float) -> float:
    """Longitudinal creep force [N] at creepage ``xi`` [-] (Polach's law, constant mu)."""
    n, mu = rig.normal_load_n, rig.mu
    e = rig.contact_stiffness_n * abs(xi) / (n * mu)
    f = 2.0 * n * mu / math.pi * (rig.k_a * e / (1.0 + (rig.k_a * e) ** 2)
                                  + math.atan(rig.k_s * e))
    return math.copysign(f, xi)


def peak(rig: OrbitRig) -> tuple[float, float]:
    """(creepage, wheel torque [N*m]) at the creep curve's maximum."""
    res = minimize_scalar(lambda x: -creep_force_n(rig, x), bounds=(1e-6, 0.2),
                          method="bounded", options={"xatol": 1e-12})
    return float(res.x), -float(res.fun) * rig.wheel_radius_m


def dc_creepage(rig: OrbitRig, torque_nm: float) -> float:
    """Steady creepage [-] at wheel torque ``torque_nm`` (below the peak)."""
    xi_pk, _ = peak(rig)
    return brentq(lambda x: rig.wheel_radius_m * creep_force_n(rig, x) - torque_nm,
                  0.0, xi_pk, xtol=1e-15)


@dataclass(frozen=True)
class Run:
    """One recorded platform revolution (or ``duration_s``) after ``run_in_s``."""

    rig: OrbitRig
    dc_torque_nm: float
    modulation_hz: float
    modulation_nm: float = 8.0
    modulation_phase_rad: float = 0.0
    wobble: Wobble = field(default_factory=Wobble)
    fs_hz: float = 2000.0
    run_in_s: float = 10.0
    duration_s: float | None = None


def simulate(run: Run, *, modulation: bool = True) -> dict[str, np.ndarray]:
    """Channels of the recorded span: ``torque_nm`` (shaft), ``wheel_speed_rad_s``,
    ``platform_speed_rad_s``, ``fx_n``, ``fz_n``, sampled at ``run.fs_hz`` [Hz]."""
    rig = run.rig
    r, rp = rig.wheel_radius_m, rig.platform_radius_m
    w0 = rig.speed_m_s / rp
    k, c = rig.shaft_stiffness_nm_rad, rig.shaft_damping_nm_s_rad
    om = 2.0 * math.pi * run.modulation_hz
    amp = run.modulation_nm if modulation else 0.0
    xi0 = dc_creepage(rig, run.dc_torque_nm)
    ww0 = w0 * rp * (1.0 + xi0) / r
    y0 = [run.dc_torque_nm / k, ww0, ww0]

    def rhs(t, y):
        tw, wm, ww = y
        wp = w0 * run.wobble.ratio(t, w0)
        tsh = k * tw + c * (wm - ww)
        tm = run.dc_torque_nm + amp * math.sin(om * t + run.modulation_phase_rad)
        f = creep_force_n(rig, (ww * r - wp * rp) / (wp * rp))
        return [wm - ww, (tm - tsh) / rig.drive_inertia_kg_m2,
                (tsh - r * f) / rig.wheel_inertia_kg_m2]

    duration = run.duration_s if run.duration_s is not None else rig.revolution_s
    t = run.run_in_s + np.arange(int(duration * run.fs_hz)) / run.fs_hz
    sol = solve_ivp(rhs, (0.0, t[-1] + 1e-9), y0, method="DOP853", rtol=1e-10, atol=1e-12,
                    dense_output=True, max_step=0.02)
    if not sol.success:
        raise RuntimeError(sol.message)
    tw, wm, ww = sol.sol(t)
    wp = w0 * np.array([run.wobble.ratio(float(x), w0) for x in t])
    xi = (ww * r - wp * rp) / (wp * rp)
    return {"torque_nm": k * tw + c * (wm - ww), "wheel_speed_rad_s": ww,
            "platform_speed_rad_s": wp,
            "fx_n": np.array([creep_force_n(rig, float(x)) for x in xi]),
            "fz_n": np.full(t.size, rig.normal_load_n)}


def slow_space(n: int, fs_hz: float, max_hz: float, *, degree: int = 5, extra: int = 2
               ) -> np.ndarray:
    """Columns spanning the variation slower than ``max_hz`` [Hz] over ``n`` samples at
    ``fs_hz``: Legendre polynomials up to ``degree`` and the first ``round(2 T W) + extra``
    discrete prolate spheroidal sequences of half-bandwidth W = ``max_hz`` (scipy's)."""
    from numpy.polynomial import legendre
    from scipy.signal.windows import dpss
    nw = n / fs_hz * max_hz
    cols = [legendre.legvander(np.linspace(-1.0, 1.0, n), degree)]
    if nw >= 0.5:
        cols.append(np.atleast_2d(dpss(n, nw, round(2 * nw) + extra)).T)
    return np.column_stack(cols)


def _coefficient(x: np.ndarray, fs_hz: float, f_hz: float, slow: np.ndarray | None = None,
                 n_periods: int | None = None) -> complex:
    """Least-squares complex amplitude at ``f_hz`` of ``x``, with the 2nd and 3rd harmonics
    beside it and either the columns ``slow`` over the whole record or, without them, a
    constant and a line over the middle ``n_periods`` whole periods."""
    if slow is None:
        length = round(n_periods * fs_hz / f_hz)
        start = (x.size - length) // 2
        x = x[start:start + length]
        slow = np.column_stack([np.ones(length), np.linspace(-1.0, 1.0, length)])
    t = (np.arange(x.size) - (x.size - 1) / 2) / fs_hz
    cols = []
    for h in (1, 2, 3):
        cols += [np.cos(2 * math.pi * h * f_hz * t), np.sin(2 * math.pi * h * f_hz * t)]
    coef = np.linalg.lstsq(np.column_stack([*cols, slow]), x, rcond=None)[0]
    return complex(coef[0], -coef[1])  # A cos(wt + p) = A cos p cos wt - A sin p sin wt


def record_phase_deg(on: dict[str, np.ndarray], off: dict[str, np.ndarray], fs_hz: float,
                     modulation_hz: float, *, span_s: tuple[float, float] | None = None,
                     slow_hz: float | None = None, middle_periods: int | None = None) -> float:
    """The phase [deg] by the definition above from a run ``on`` and its twin without the
    modulation ``off``: over the samples within ``span_s`` (s from the record's start;
    default all), beside the variation slower than ``slow_hz`` (default 0.4 x the
    modulation frequency, the chain's slow band); or, with ``middle_periods``, over that
    many whole periods in the middle of the span beside a constant and a line."""
    d_t = on["torque_nm"] - off["torque_nm"]
    d_w = on["wheel_speed_rad_s"] - off["wheel_speed_rad_s"]
    if span_s is not None:
        t = np.arange(d_t.size) / fs_hz
        keep = (t >= span_s[0]) & (t <= span_s[1])
        d_t, d_w = d_t[keep], d_w[keep]
    if middle_periods is None:
        kw = {"slow": slow_space(d_t.size, fs_hz, 0.4 * modulation_hz if slow_hz is None
                                 else slow_hz)}
    else:
        kw = {"n_periods": middle_periods}
    ct = _coefficient(d_t, fs_hz, modulation_hz, **kw)
    cw = _coefficient(d_w, fs_hz, modulation_hz, **kw)
    return math.degrees(np.angle(ct / cw))
