"""The independent generator's model of a train run: the friction segments along the track, the
creep laws (tanh, Burckhardt, Polach), the run's settings and the one-axle vehicle it integrates
(see :mod:`torquemod.twins.independent.train` for what differs from the project's twin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

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
def simulate_vehicle(n, fs, sub, p, xs, mus, ks, lam, lamp, lama, lvl, step_m, mu_ahead, rate,
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


__all__ = ["FrictionSegment", "IndependentRunSpec", "creep_law", "creep_slope", "friction_map",
           "segment_names", "simulate_vehicle"]
