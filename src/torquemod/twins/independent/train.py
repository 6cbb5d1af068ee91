"""An independent train run for checking the on-board estimator on data that the
project's own twin (:mod:`torquemod.twins.train`) did not make.

Written from scratch on purpose: it imports nothing of ``torquemod.twins.train``,
``torquemod.twins.vtrack.rig``
or ``torquemod.analysis.contact``, and it differs from the twin where a hidden run could differ:

* **Creep law**: not Polach. Either a saturating constant-friction curve
  ``CoA = mu*tanh(k0*xi/mu)`` (``law="tanh"``) or the Burckhardt form
  ``CoA = mu_B*(1 - exp(-c*xi)) - d*xi`` (``law="burckhardt"``; Burckhardt 1993, as used in
  road-tyre ABS models), parametrised here by its initial slope ``k0``, its peak ``mu`` and
  the fall ``d = d_over_mu*mu`` beyond the peak: ``c = (k0 - d*ln(1 + k0/d))/mu`` and
  ``mu_B = (k0 + d)/c`` put the maximum exactly at ``mu`` (derived by setting dCoA/dxi = 0).
  The truth's ``mu`` is the available adhesion: the curve's maximum (its asymptote for tanh).
  A control, ``law="polach"``: Polach's constant-friction curve (Polach 2005 Eq. 8, written
  here in reduced form) ``CoA = mu*(2/pi)*(r*x/(1 + (r*x)^2) + arctan(x))`` with
  ``x = xi*k0*pi/(2*mu*(1 + r))`` (so that dCoA/dxi = k0 at zero creepage) and
  ``r = kA/kS = polach_ratio``: the shape the estimator's model family contains, so that a
  failure on tanh/Burckhardt runs can be told from a failure of the run itself.
* **Vehicle**: one powered axle, a rigid drive line (or, optionally, a compliant coupling
  between the motor and the wheelset, the encoder then seeing the motor), a first-order
  traction motor (its torque
  follows the command with ``motor_time_constant_s``), the vehicle's share of mass; the other
  axles cancel this axle's DC tractive force and the running resistance (a measurement train
  shifting torque between axles) with only a weak speed-holding term, so the speed stays
  near ``speed_m_s``. Axle load varies with a few track-irregularity wavelengths.
* **Friction map**: segments of (name, start, mu, k0) with linear transitions.
* **Probe**: a DC torque staircase ``levels`` x the available adhesion (the smallest mu a
  little behind and ahead of the axle), a step every ``step_m`` metres, rate-limited, plus
  the modulation ``amplitude_nm*sin(2*pi*f*t)`` at the axle; or a constant demand
  ``constant_torque_nm`` (a driver's, blind to the friction), with a simple anti-slip cut
  when the creepage exceeds 0.03.
* **Sensors**: torque and speed recorded at the MOTOR (axle torque / gear ratio, axle speed x
  gear ratio, in rpm), the torque with a first-order lag, a gain error and white noise; the
  speed from an encoder with once-per-motor-revolution eccentricity, a once-per-axle ripple,
  a short counting gate and quantisation; a radar speed in km/h at ``radar_rate_hz`` with its
  own clock offset, scale error and noise, in its own MDF4 channel group; NO position
  channel; logger names ``EM1_Trq``, ``EM1_Spd``, ``Radar_v``; logger time starting at ``t0_s``.

:func:`write_independent_run` writes ``run.mf4`` (or a logger-style ``run.h5``), ``run.toml``
(docs/format.md) and
``truth.parquet`` (one row per modulation period, on the logger's clock; NOT named in
run.toml, as a hidden run would not name it).

Integration: fixed-step classical RK4 (``substeps`` steps per logger sample) compiled with
numba; the stiffest mode is the contact damping, ``R^2*N*k0/(V*J)`` ~ 600 1/s, far inside
RK4's stability limit at the default 1/8 ms step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

TANH, BURCKHARDT, POLACH = 0, 1, 2
_LAWS = {"tanh": TANH, "burckhardt": BURCKHARDT, "polach": POLACH}


@dataclass(frozen=True)
class FrictionSegment:
    """One stretch of rail.

    Attributes
    ----------
    name : str
        Its name (the truth's condition).
    start_m : float
        Where it starts [m].
    mu : float
        Its available adhesion [-].
    k0 : float
        Initial slope of its creep curve, dCoA/dxi at zero creepage [-].
    """

    name: str
    start_m: float
    mu: float
    k0: float


DEFAULT_SEGMENTS = (FrictionSegment("dry", 0.0, 0.35, 110.0),
                    FrictionSegment("wet", 700.0, 0.20, 70.0),
                    FrictionSegment("leaves", 1400.0, 0.10, 40.0),
                    FrictionSegment("dry2", 2000.0, 0.35, 110.0))


@dataclass(frozen=True)
class IndependentRunSpec:
    """Everything of one independent run (SI units; module docstring).

    Attributes
    ----------
    segments : tuple of FrictionSegment
        The friction map.
    length_m : float
        Track length [m].
    transition_m : float
        Linear transitions between segments [m].
    law : {"tanh", "burckhardt", "polach"}
        The creep law.
    burckhardt_d_over_mu : float
        Fall beyond the peak of the Burckhardt law, d/mu [-].
    polach_ratio : float
        r = kA/kS of the Polach control law [-].
    wheel_radius_m : float
        Wheel radius [m].
    normal_load_n : float
        Axle load [N].
    inertia_kg_m2 : float
        Wheelset, gears and rotor referred to the axle [kg*m^2].
    mass_kg : float
        The vehicle mass this axle moves [kg].
    gear_ratio : float
        Motor turns per axle turn [-].
    motor_time_constant_s : float
        The motor torque follows its command with this lag [s].
    coupling_stiffness_nm_rad : float or None
        A compliant coupling between motor and wheelset [N*m/rad]; None: a rigid drive line.
    coupling_damping_nm_s_rad : float
        Its damping [N*m*s/rad].
    motor_inertia_kg_m2 : float
        The motor's part of ``inertia_kg_m2``, referred to the axle [kg*m^2].
    declare_drive_line : bool
        Write the drive line into run.toml (a hidden run may well not).
    speed_m_s : float
        Speed held [m/s].
    speed_gain_n_s_m : float
        The other axles' weak speed holding [N*s/m].
    load_variation : tuple of tuple of float
        (wavelength [m], relative amplitude [-]) of the axle load's variation.
    modulation_frequency_hz : float
        Modulation frequency [Hz].
    modulation_amplitude_nm : float
        Modulation amplitude at the axle [N*m].
    levels : tuple of float
        The probe's DC torque levels, shares of the available adhesion [-].
    step_m : float
        Length of each level [m].
    constant_torque_nm : float or None
        Instead of the staircase, a driver's constant demand [N*m].
    torque_rate_nm_s : float
        DC torque rate limit at the axle [N*m/s].
    look_behind_m : float
        The probe sizes its levels by the smallest mu this far behind the axle [m]...
    look_ahead_m : float
        ... and this far ahead [m].
    sample_rate_hz : float
        Logger rate [Hz].
    substeps : int
        RK4 steps per logger sample [-].
    t0_s : float
        Logger time of the first sample [s].
    torque_lag_s : float
        First-order lag of the recorded torque [s].
    torque_gain : float
        Gain of the recorded torque (1: no error) [-].
    torque_noise_nm : float
        White noise of the recorded torque, at the motor, per sample [N*m].
    encoder_eccentricity : float
        Once per motor revolution, relative [-].
    axle_ripple : float
        Once per axle revolution, relative [-].
    encoder_gate_samples : int
        The speed is the angle change over this many samples [-].
    declare_sensor_dynamics : bool
        Write ``torque_lag_s`` and ``speed_delay_s`` (half the counting gate) into run.toml.
    speed_quantum_rpm : float
        Quantization of the recorded motor speed [rpm].
    radar_rate_hz : float
        Radar rate [Hz].
    radar_offset_s : float
        The radar's first sample relative to the logger's first [s].
    radar_scale : float
        Radar scale factor [-].
    radar_noise_m_s : float
        Radar noise [m/s].
    seed : int
        Random seed.
    extra_toml : dict
        Further run.toml tables (e.g. ``onboard``).
    """

    segments: tuple[FrictionSegment, ...] = DEFAULT_SEGMENTS
    length_m: float = 2600.0
    transition_m: float = 20.0
    law: str = "tanh"
    burckhardt_d_over_mu: float = 3.0
    polach_ratio: float = 2.5
    # vehicle
    wheel_radius_m: float = 0.43
    normal_load_n: float = 160_000.0
    inertia_kg_m2: float = 250.0          # wheelset + gears + rotor, referred to the axle
    mass_kg: float = 15_000.0             # the vehicle mass this axle moves
    gear_ratio: float = 5.2               # motor turns per axle turn
    motor_time_constant_s: float = 0.005
    # a compliant coupling between motor and wheelset (None: rigid drive line); the motor's
    # inertia is part of inertia_kg_m2, all referred to the axle; declare_drive_line writes
    # them into run.toml (a hidden run may well not)
    coupling_stiffness_nm_rad: float | None = None
    coupling_damping_nm_s_rad: float = 400.0
    motor_inertia_kg_m2: float = 100.0
    declare_drive_line: bool = False
    speed_m_s: float = 22.0
    speed_gain_n_s_m: float = 3000.0      # the other axles' weak speed holding
    load_variation: tuple[tuple[float, float], ...] = ((2.9, 0.012), (9.7, 0.015),
                                                       (31.0, 0.01))  # (wavelength, rel. amp.)
    # probe
    modulation_frequency_hz: float = 4.0
    modulation_amplitude_nm: float = 600.0  # at the axle
    levels: tuple[float, ...] = (0.2, 0.4, 0.6, 0.8)
    step_m: float = 50.0
    constant_torque_nm: float | None = None  # instead of the staircase: a driver's demand
    torque_rate_nm_s: float = 30_000.0    # DC torque rate limit at the axle
    look_behind_m: float = 10.0
    look_ahead_m: float = 40.0
    # sensors and logger
    sample_rate_hz: float = 2000.0
    substeps: int = 4
    t0_s: float = 1532.25
    torque_lag_s: float = 0.001
    torque_gain: float = 1.0
    torque_noise_nm: float = 15.0         # at the motor (white, per sample)
    encoder_eccentricity: float = 0.002   # once per motor revolution, relative
    axle_ripple: float = 0.001            # once per axle revolution, relative
    encoder_gate_samples: int = 2         # speed = angle change over this many samples
    # write the sensors' dynamics into run.toml: torque_lag_s, and speed_delay_s = half the
    # counting gate (a hidden run may well not declare them)
    declare_sensor_dynamics: bool = False
    speed_quantum_rpm: float = 0.25
    radar_rate_hz: float = 10.0
    radar_offset_s: float = -0.037        # its first sample before the logger's first
    radar_scale: float = 1.002
    radar_noise_m_s: float = 0.03
    seed: int = 0
    extra_toml: dict = field(default_factory=dict)

    @property
    def law_code(self) -> int:
        return _LAWS[self.law]

    @property
    def shape(self) -> float:
        """The law's shape parameter: d/mu (Burckhardt) or kA/kS (Polach)."""
        return self.polach_ratio if self.law == "polach" else self.burckhardt_d_over_mu


def friction_map(spec: IndependentRunSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Breakpoints of the piecewise-linear friction map.

    Constant in each segment, linear over ``transition_m`` centred on each segment start.

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.

    Returns
    -------
    x : ndarray
        Positions [m].
    mu : ndarray
        Available adhesion [-].
    k0 : ndarray
        Initial slopes [-].
    """
    xs, mus, ks = [], [], []
    segs = sorted(spec.segments, key=lambda s: s.start_m)
    half = spec.transition_m / 2
    for i, s in enumerate(segs):
        if i == 0:
            xs.append(-1e6)
        else:
            xs.append(s.start_m + half)
        mus.append(s.mu)
        ks.append(s.k0)
        if i + 1 < len(segs):
            xs.append(segs[i + 1].start_m - half)
            mus.append(s.mu)
            ks.append(s.k0)
    xs.append(1e9)
    mus.append(segs[-1].mu)
    ks.append(segs[-1].k0)
    return np.array(xs), np.array(mus), np.array(ks)


def segment_names(spec: IndependentRunSpec, position_m: np.ndarray) -> np.ndarray:
    """The name of the segment at each position (by segment start).

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.
    position_m : ndarray
        Positions [m].

    Returns
    -------
    ndarray of str
        The names.
    """
    segs = sorted(spec.segments, key=lambda s: s.start_m)
    starts = np.array([s.start_m for s in segs])
    idx = np.clip(np.searchsorted(starts, position_m, side="right") - 1, 0, len(segs) - 1)
    return np.array([segs[i].name for i in idx])


def creep_law(xi, mu, k0, law: str = "tanh", d_over_mu: float = 3.0):
    """CoA at a creepage under the run's creep law (module docstring); numpy version.

    Parameters
    ----------
    xi : float or array_like
        Creepage [-].
    mu : float or array_like
        Available adhesion (the curve's maximum) [-].
    k0 : float or array_like
        Initial slope dCoA/dxi [-].
    law : {"tanh", "burckhardt", "polach"}
        The creep law. Default "tanh".
    d_over_mu : float
        Shape parameter of the Burckhardt law, d/mu [-]
        (:attr:`IndependentRunSpec.burckhardt_d_over_mu`). Default 3.

    Returns
    -------
    ndarray
        CoA [-], odd in xi.

    References
    ----------
    .. [1] M. Burckhardt, "Fahrwerktechnik: Radschlupf-Regelsysteme", Vogel, Würzburg 1993.
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).

    Examples
    --------
    >>> round(float(creep_law(1.0, 0.3, 100.0)), 6)
    0.3
    """
    xi, mu, k0 = (np.asarray(a, dtype=float) for a in (xi, mu, k0))
    if law == "tanh":
        return mu * np.tanh(k0 * xi / mu)
    if law == "polach":
        r = d_over_mu
        x = xi * k0 * np.pi / (2 * mu * (1 + r))
        return mu * 2 / np.pi * (r * x / (1 + (r * x) ** 2) + np.arctan(x))
    d = d_over_mu * mu
    c = (k0 - d * np.log1p(k0 / d)) / mu
    mub = (k0 + d) / c
    a = np.abs(xi)
    return np.sign(xi) * (mub * (1 - np.exp(-c * a)) - d * a)


def creep_slope(xi, mu, k0, law: str = "tanh", d_over_mu: float = 3.0):
    """dCoA/dxi of :func:`creep_law` (analytic).

    Parameters
    ----------
    xi : float or array_like
        Creepage [-].
    mu : float or array_like
        Available adhesion (the curve's maximum) [-].
    k0 : float or array_like
        Initial slope dCoA/dxi [-].
    law : {"tanh", "burckhardt", "polach"}
        The creep law. Default "tanh".
    d_over_mu : float
        Shape parameter of the Burckhardt law, d/mu [-]
        (:attr:`IndependentRunSpec.burckhardt_d_over_mu`). Default 3.

    Returns
    -------
    ndarray
        The slope [-].

    Examples
    --------
    >>> float(creep_slope(0.0, 0.3, 100.0))
    100.0
    """
    xi, mu, k0 = (np.asarray(a, dtype=float) for a in (xi, mu, k0))
    if law == "tanh":
        return k0 / np.cosh(k0 * xi / mu) ** 2
    if law == "polach":
        r = d_over_mu
        dx = k0 * np.pi / (2 * mu * (1 + r))
        x = xi * dx
        rx2 = (r * x) ** 2
        return mu * 2 / np.pi * (r * (1 - rx2) / (1 + rx2) ** 2 + 1 / (1 + x * x)) * dx
    d = d_over_mu * mu
    c = (k0 - d * np.log1p(k0 / d)) / mu
    mub = (k0 + d) / c
    return mub * c * np.exp(-c * np.abs(xi)) - d


@njit(cache=True)
def _coa(xi, mu, k0, law, dfac):
    if law == 0:
        return mu * math.tanh(k0 * xi / mu)
    if law == 2:
        x = xi * k0 * math.pi / (2.0 * mu * (1.0 + dfac))
        return mu * 2.0 / math.pi * (dfac * x / (1.0 + (dfac * x) ** 2) + math.atan(x))
    d = dfac * mu
    c = (k0 - d * math.log1p(k0 / d)) / mu
    mub = (k0 + d) / c
    a = abs(xi)
    s = 1.0 if xi >= 0 else -1.0
    return s * (mub * (1.0 - math.exp(-c * a)) - d * a)


@njit(cache=True)
def _interp(x, xs, ys, i):
    """Linear interpolation from index i onwards (xs increasing, x >= xs[i])."""
    n = xs.size
    while i < n - 2 and x > xs[i + 1]:
        i += 1
    f = (x - xs[i]) / (xs[i + 1] - xs[i])
    f = min(max(f, 0.0), 1.0)
    return ys[i] + f * (ys[i + 1] - ys[i])


@njit(cache=True)
def _rhs(t, y, tdc, p, xs, mus, ks, lam, lamp, lama, i0):
    """Derivatives of the state y = (wheel speed [rad/s], vehicle speed [m/s], position [m],
    motor torque [N*m], motor speed [rad/s], coupling twist [rad]), all referred to the axle.
    p = (R, N0, J, M, tau, f, A, law, shape, kp, vref, k_c, c_c, J_m); k_c <= 0: rigid."""
    r, n0, jj, m, tau, f, amp = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    w, v, x, tm, wm, tw = y[0], y[1], y[2], y[3], y[4], y[5]
    mu = _interp(x, xs, mus, i0)
    k0 = _interp(x, xs, ks, i0)
    nl = n0
    for q in range(lam.size):
        nl += n0 * lama[q] * math.sin(2.0 * math.pi * x / lam[q] + lamp[q])
    xi = (w * r - v) / max(v, 0.5)
    fx = nl * _coa(xi, mu, k0, int(p[7]), p[8])
    cmd = tdc + amp * math.sin(2.0 * math.pi * f * t)
    d = np.empty(6)
    if p[11] > 0:  # compliant coupling between the motor (J_m) and the wheelset (J - J_m)
        tc = p[11] * tw + p[12] * (wm - w)
        d[0] = (tc - r * fx) / (jj - p[13])
        d[4] = (tm - tc) / p[13]
        d[5] = wm - w
    else:
        d[0] = (tm - r * fx) / jj
        d[4] = d[0]
        d[5] = 0.0
    d[1] = (fx - tdc / r + p[9] * (p[10] - v)) / m  # the other axles cancel the DC force
    d[2] = v
    d[3] = (cmd - tm) / tau
    return d


@njit(cache=True)
def _simulate(n, fs, sub, p, xs, mus, ks, lam, lamp, lama, lvl, step_m, mu_ahead, rate,
              slip_xi):
    out = np.empty((9, n))
    r = p[0]
    v = p[10]
    tdc = lvl[0] * mu_ahead[0] * p[1] * r
    # start at the creepage of the first DC torque: CoA(xi) = tdc/(N R) by bisection
    target = tdc / (p[1] * r)
    lo, hi = 0.0, 0.5
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _coa(mid, mus[0], ks[0], int(p[7]), p[8]) < target:
            lo = mid
        else:
            hi = mid
    w = v * (1.0 + lo) / r
    y = np.array([w, v, 0.0, tdc, w, tdc / p[11] if p[11] > 0 else 0.0])
    h = 1.0 / (fs * sub)
    t = 0.0
    i0 = 0
    cut = 1.0
    for s in range(n):
        for _ in range(sub):
            x = y[2]
            while i0 < xs.size - 2 and x > xs[i0 + 1]:
                i0 += 1
            # DC target: staircase level x smallest mu around the axle, rate-limited;
            # a simple anti-slip cut when the creepage runs away
            j = min(int(x), mu_ahead.size - 1)
            lev = lvl[int(x // step_m) % lvl.size]
            target = lev * mu_ahead[j] * p[1] * r * cut
            d = target - tdc
            lim = rate * h
            tdc += min(max(d, -lim), lim)
            xi = (y[0] * r - y[1]) / max(y[1], 0.5)
            if xi > slip_xi:
                cut = max(0.2, cut - 4.0 * h)
            elif cut < 1.0 and xi < 0.5 * slip_xi:
                cut = min(1.0, cut + 0.4 * h)
            k1 = _rhs(t, y, tdc, p, xs, mus, ks, lam, lamp, lama, i0)
            k2 = _rhs(t + h / 2, y + h / 2 * k1, tdc, p, xs, mus, ks, lam, lamp, lama, i0)
            k3 = _rhs(t + h / 2, y + h / 2 * k2, tdc, p, xs, mus, ks, lam, lamp, lama, i0)
            k4 = _rhs(t + h, y + h * k3, tdc, p, xs, mus, ks, lam, lamp, lama, i0)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            t += h
        x = y[2]
        while i0 < xs.size - 2 and x > xs[i0 + 1]:
            i0 += 1
        mu = _interp(x, xs, mus, i0)
        k0 = _interp(x, xs, ks, i0)
        nl = p[1]
        for q in range(lam.size):
            nl += p[1] * lama[q] * math.sin(2.0 * math.pi * x / lam[q] + lamp[q])
        xi = (y[0] * r - y[1]) / max(y[1], 0.5)
        out[0, s] = y[3]
        out[1, s] = y[0]
        out[2, s] = y[1]
        out[3, s] = x
        out[4, s] = _coa(xi, mu, k0, int(p[7]), p[8])
        out[5, s] = mu
        out[6, s] = nl
        out[7, s] = tdc
        out[8, s] = y[4]
    return out


@dataclass(frozen=True)
class IndependentRun:
    """A simulated independent run: the true signals and what the sensors recorded.

    Attributes
    ----------
    spec : IndependentRunSpec
        The run's specification.
    t_s : ndarray
        Logger clock [s].
    torque_nm : ndarray
        True axle torque [N*m].
    wheel_speed_rad_s : ndarray
        True axle speed [rad/s].
    speed_m_s : ndarray
        Vehicle speed [m/s].
    position_m : ndarray
        Position [m].
    coa : ndarray
        CoA [-].
    mu : ndarray
        Available adhesion [-].
    k0 : ndarray
        Initial slope of the creep curve [-].
    normal_load_n : ndarray
        Axle load [N].
    dc_torque_nm : ndarray
        DC torque demand [N*m].
    motor_torque_nm : ndarray
        Recorded torque, at the motor [N*m].
    motor_speed_rpm : ndarray
        Recorded speed, at the motor [rpm].
    radar_t_s : ndarray
        Radar sample times, logger clock [s].
    radar_km_h : ndarray
        Radar speed [km/h].
    """

    spec: IndependentRunSpec
    t_s: np.ndarray
    torque_nm: np.ndarray
    wheel_speed_rad_s: np.ndarray
    speed_m_s: np.ndarray
    position_m: np.ndarray
    coa: np.ndarray
    mu: np.ndarray
    k0: np.ndarray
    normal_load_n: np.ndarray
    dc_torque_nm: np.ndarray
    motor_torque_nm: np.ndarray      # recorded, at the motor [N*m]
    motor_speed_rpm: np.ndarray      # recorded, at the motor [rpm]
    radar_t_s: np.ndarray
    radar_km_h: np.ndarray

    @property
    def creepage(self) -> np.ndarray:
        return (self.wheel_speed_rad_s * self.spec.wheel_radius_m - self.speed_m_s) \
            / self.speed_m_s


def _mu_around(spec: IndependentRunSpec, xs, mus) -> np.ndarray:
    """Smallest mu within [x - look_behind, x + look_ahead] on a 1-m grid."""
    grid = np.arange(0.0, spec.length_m + spec.look_ahead_m + 2.0)
    mu = np.interp(grid, xs, mus)
    out = np.empty_like(mu)
    b, a = int(spec.look_behind_m), int(spec.look_ahead_m)
    for i in range(grid.size):
        out[i] = mu[max(0, i - b):i + a + 1].min()
    return out


def simulate_independent(spec: IndependentRunSpec) -> IndependentRun:
    """Integrate the run and apply the sensors (module docstring).

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.

    Returns
    -------
    IndependentRun
        True signals and recordings.
    """
    rng = np.random.default_rng(spec.seed)
    xs, mus, ks = friction_map(spec)
    fs = spec.sample_rate_hz
    n = math.ceil(spec.length_m / spec.speed_m_s * fs)
    lam = np.array([w for w, _ in spec.load_variation], dtype=float)
    lama = np.array([a for _, a in spec.load_variation], dtype=float)
    lamp = rng.uniform(0, 2 * np.pi, lam.size)
    p = np.array([spec.wheel_radius_m, spec.normal_load_n, spec.inertia_kg_m2, spec.mass_kg,
                  spec.motor_time_constant_s, spec.modulation_frequency_hz,
                  spec.modulation_amplitude_nm, float(spec.law_code),
                  spec.shape, spec.speed_gain_n_s_m, spec.speed_m_s,
                  spec.coupling_stiffness_nm_rad or 0.0, spec.coupling_damping_nm_s_rad,
                  spec.motor_inertia_kg_m2])
    if spec.constant_torque_nm is None:
        levels, mu_around = np.asarray(spec.levels, dtype=float), _mu_around(spec, xs, mus)
    else:  # the demand as one "level" of a friction of 1
        levels = np.array([spec.constant_torque_nm / (spec.normal_load_n * spec.wheel_radius_m)])
        mu_around = np.ones(int(spec.length_m) + 2)
    out = _simulate(n, fs, spec.substeps, p, xs, mus, ks, lam, lamp, lama, levels,
                    spec.step_m, mu_around, spec.torque_rate_nm_s, 0.03)
    tm, w, v, x, coa, mu, nl, tdc, wm = out
    t = spec.t0_s + np.arange(n) / fs
    # torque sensor: first-order lag (exact discretisation), gain, noise; at the motor
    g = spec.gear_ratio
    a = math.exp(-1.0 / (fs * spec.torque_lag_s)) if spec.torque_lag_s > 0 else 0.0
    from scipy.signal import lfilter
    lagged = lfilter([1 - a], [1, -a], tm, zi=[a * tm[0]])[0]
    motor_torque = spec.torque_gain * lagged / g + rng.normal(0, spec.torque_noise_nm, n)
    # encoder on the motor shaft: its angle, ripple, a counting gate, quantisation
    theta_axle = np.concatenate([[0.0], np.cumsum(0.5 * (wm[1:] + wm[:-1]) / fs)])
    theta_m = g * theta_axle + rng.uniform(0, 2 * np.pi)
    ripple_phase = rng.uniform(0, 2 * np.pi)
    angle = theta_m + spec.encoder_eccentricity * np.sin(theta_m) \
        + g * spec.axle_ripple * np.sin(theta_axle + ripple_phase)
    gate = max(1, spec.encoder_gate_samples)
    omega_m = np.empty(n)
    omega_m[gate:] = (angle[gate:] - angle[:-gate]) * fs / gate
    omega_m[:gate] = omega_m[gate]
    rpm = omega_m * 60 / (2 * np.pi)
    rpm = np.round(rpm / spec.speed_quantum_rpm) * spec.speed_quantum_rpm
    # radar: own clock, own rate, scale error and noise, km/h
    t_r = np.arange(t[0] + spec.radar_offset_s, t[-1] + 0.2, 1.0 / spec.radar_rate_hz)
    v_r = np.interp(t_r, t, v) * spec.radar_scale + rng.normal(0, spec.radar_noise_m_s,
                                                                t_r.size)
    k0 = np.interp(x, xs, ks)
    return IndependentRun(spec, t, tm, w, v, x, coa, mu, k0, nl, tdc, motor_torque, rpm,
                          t_r, v_r * 3.6)


def truth_table(run: IndependentRun):
    """One row per modulation period: ``time_s`` (centre, logger clock), ``position_m``,
    ``speed_m_s``, ``condition``, ``mu`` (available adhesion), ``coa`` (period mean),
    ``utilisation`` (coa/mu), ``creepage`` and ``creep_coefficient`` (slope of the law at the
    period's mean creepage), ``normal_load_n``, ``dc_torque_nm``.

    Parameters
    ----------
    run : IndependentRun
        The run.

    Returns
    -------
    pandas.DataFrame
        One row per modulation period (SI units; mu, coa, utilisation, creepage and creep
        coefficient dimensionless).
    """
    import pandas as pd
    s = run.spec
    per = round(s.sample_rate_hz / s.modulation_frequency_hz)
    m = run.t_s.size // per
    cut = slice(0, m * per)

    def mean(a):
        return a[cut].reshape(m, per).mean(axis=1)

    xi = mean(run.creepage)
    mu, k0 = mean(run.mu), mean(run.k0)
    coa = mean(run.coa)
    pos = mean(run.position_m)
    return pd.DataFrame({
        "time_s": mean(run.t_s), "position_m": pos, "speed_m_s": mean(run.speed_m_s),
        "condition": segment_names(s, pos), "mu": mu, "coa": coa, "utilisation": coa / mu,
        "creepage": xi,
        "creep_coefficient": creep_slope(xi, mu, k0, s.law, s.shape),
        "normal_load_n": mean(run.normal_load_n), "dc_torque_nm": mean(run.dc_torque_nm)})


def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def _write_mdf4(run: IndependentRun, path: Path) -> None:
    from asammdf import MDF, Signal
    mdf = MDF(version="4.10")
    mdf.append([Signal(run.motor_torque_nm, run.t_s, name="EM1_Trq", unit="Nm"),
                Signal(run.motor_speed_rpm, run.t_s, name="EM1_Spd", unit="rpm")],
               comment="traction motor 1")
    mdf.append([Signal(run.radar_km_h, run.radar_t_s, name="Radar_v", unit="km/h")],
               comment="Doppler radar")
    mdf.save(path, overwrite=True)
    mdf.close()


def _write_hdf5(run: IndependentRun, path: Path) -> None:
    """A logger export: groups ``logger`` (time ``t`` in ms, EM1_Trq, EM1_Spd) and ``radar``
    (its own time ``t`` in ms, ``v``); no unit attributes (the manifest gives them)."""
    import h5py
    with h5py.File(path, "w") as f:
        f["logger/t"] = run.t_s * 1e3
        f["logger/EM1_Trq"] = run.motor_torque_nm
        f["logger/EM1_Spd"] = run.motor_speed_rpm
        f["radar/t"] = run.radar_t_s * 1e3
        f["radar/v"] = run.radar_km_h


def write_independent_run(spec: IndependentRunSpec, folder: str | Path, *, fmt: str = "mdf4"
                          ) -> tuple[Path, IndependentRun]:
    """Simulate ``spec`` and write the recording, ``run.toml`` and ``truth.parquet`` into
    ``folder``. ``fmt="mdf4"``: ``run.mf4``, channel group 0 EM1_Trq [Nm] and EM1_Spd [rpm]
    at ``sample_rate_hz``, group 1 Radar_v [km/h] at ``radar_rate_hz`` (each group with its
    own master); ``fmt="hdf5"``: ``run.h5`` as :func:`_write_hdf5` (times in ms, the radar's
    own time vector named in ``[channels]``). Returns (run.toml path, the run).

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.
    folder : str or pathlib.Path
        The folder.
    fmt : {"mdf4", "hdf5"}
        Recording format. Default "mdf4".

    Returns
    -------
    path : pathlib.Path
        The run.toml.
    run : IndependentRun
        The run.

    Raises
    ------
    ValueError
        An unknown ``fmt``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    run = simulate_independent(spec)
    if fmt == "mdf4":
        name = "run.mf4"
        _write_mdf4(run, folder / name)
        channels = ['torque = { name = "EM1_Trq", unit = "N*m" }',
                    'wheel_speed = { name = "EM1_Spd", unit = "rpm" }',
                    'vehicle_speed = { name = "Radar_v", unit = "km/h" }']
    elif fmt == "hdf5":
        name = "run.h5"
        _write_hdf5(run, folder / name)
        channels = ['time = { name = "logger/t", unit = "ms" }',
                    'torque = { name = "logger/EM1_Trq", unit = "N*m" }',
                    'wheel_speed = { name = "logger/EM1_Spd", unit = "rpm" }',
                    'vehicle_speed = { name = "radar/v", unit = "km/h", '
                    'time = { name = "radar/t", unit = "ms" } }']
    else:
        raise ValueError(f"fmt must be 'mdf4' or 'hdf5', not {fmt!r}")
    truth_table(run).to_parquet(folder / "truth.parquet", index=False)
    lines = ["# independent test run (torquemod.twins.independent.train): "
             "not made by torquemod's twin",
             "[vehicle]",
             f"wheel_radius_m = {spec.wheel_radius_m!r}",
             f"normal_load_n = {spec.normal_load_n!r}",
             f"inertia_kg_m2 = {spec.inertia_kg_m2!r}",
             f"gear_ratio = {spec.gear_ratio!r}",
             'vehicle = "independent test loco"',
             *([f"motor_inertia_kg_m2 = {spec.motor_inertia_kg_m2!r}",
                f"coupling_stiffness_nm_rad = {spec.coupling_stiffness_nm_rad!r}",
                f"coupling_damping_nm_s_rad = {spec.coupling_damping_nm_s_rad!r}"]
               if spec.declare_drive_line and spec.coupling_stiffness_nm_rad else []),
             *([f"torque_lag_s = {spec.torque_lag_s!r}",
                f"speed_delay_s = {spec.encoder_gate_samples / (2 * spec.sample_rate_hz)!r}"]
               if spec.declare_sensor_dynamics else []),
             "", "[test]",
             f"modulation_frequency_hz = {spec.modulation_frequency_hz!r}",
             f"modulation_amplitude_nm = {spec.modulation_amplitude_nm!r}",
             "", "[[recording]]", f'file = "{name}"', "axle = 1",
             "", "[channels]", *channels]
    for table, body in spec.extra_toml.items():
        lines += ["", f"[{table}]"] + [f"{k} = {_toml_value(v)}" for k, v in body.items()]
    path = folder / "run.toml"
    path.write_text("\n".join(lines) + "\n")
    return path, run


__all__ = ["FrictionSegment", "IndependentRun", "IndependentRunSpec", "creep_law",
           "creep_slope", "friction_map", "segment_names", "simulate_independent",
           "truth_table", "write_independent_run"]
