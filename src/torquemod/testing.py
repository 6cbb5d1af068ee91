"""Synthetic recordings with a known truth, for tests, benchmarks and the example experiment.

The signals are written down directly (no dynamics): the torque is a DC level plus the
modulation plus the torque that accelerates the wheel's inertia; the wheel speed carries the
modulation delayed by a chosen phase lag; encoders multiply the true speeds by once- and
twice-per-revolution eccentricity errors (of the true, integrated angles); forces carry the
sleeper-passing tone; every channel gets vibration tones and white noise.

The rolling speed moves as on a real rig or train: a slow wobble of the speed loop (a few
sinusoids below 1.2 Hz plus terms at once and twice the platform revolution) and an optional
ramp ``acceleration_m_s2``; the wheel follows the platform kinematically, so the creepage stays
exactly ``creepage`` throughout. What the chain must recover (phase, creepage, CoA, modulation
frequency) is therefore known exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from torquemod.io.experiment import Recording


@dataclass(frozen=True)
class SyntheticSpec:
    """Parameters of one synthetic recording (SI units).

    Defaults are V-Track-like: 7 km/h, a 0.0675 m wheel on a 2 m ring, 4200 N, an 8 N*m
    modulation at 2 Hz, 16 670 Hz sampling.

    Attributes
    ----------
    fs_hz : float
        Sample rate [Hz].
    n_revolutions : float
        Platform revolutions recorded [-].
    speed_m_s : float
        Nominal rolling speed V [m/s].
    wheel_radius_m : float
        Wheel radius [m].
    platform_radius_m : float
        Radius of the wheel path on the ring [m].
    creepage : float
        Longitudinal creepage [-], exact throughout (the wheel follows the platform
        kinematically).
    normal_load_n : float
        Normal load Fz [N].
    lateral_force_n : float
        Lateral force Fy [N].
    dc_torque_nm : float
        DC torque [N*m].
    modulation_hz : float
        Modulation frequency [Hz].
    modulation_amplitude_nm : float
        Modulation amplitude [N*m].
    modulation_phase_rad : float
        Phase of the torque modulation at t = 0 [rad].
    phase_lag_deg : float
        Lag of the wheel-speed modulation behind the torque modulation [deg].
    wheel_mod_amplitude_rad_s : float
        Amplitude of the wheel-speed modulation [rad/s].
    wheel_eccentricity : tuple of float
        Relative encoder errors at once and twice per wheel revolution [-].
    platform_eccentricity : tuple of float
        The same for the platform encoder [-].
    torque_noise_nm : float
        White-noise standard deviation of the torque [N*m].
    wheel_noise_rad_s : float
        Of the wheel speed [rad/s].
    platform_noise_rad_s : float
        Of the platform speed [rad/s].
    force_noise_n : float
        Of the forces [N].
    vibration_hz : tuple of float
        Vibration tones on every channel [Hz].
    torque_vibration_nm : float
        Their amplitude on the torque [N*m].
    wheel_vibration_rad_s : float
        Their amplitude on the wheel speed [rad/s].
    sleeper_force_n : float
        Amplitude of the sleeper-passing tone on the forces [N].
    force_mod_amplitude_n : float
        The creep force's answer to the modulation, in phase [N]. Default 0.
    speed_wobble : tuple of tuple of float
        Slow speed variation: (relative amplitude [-], frequency [Hz], phase [rad]) per term;
        the default is 0.2 % RMS in all (assumed, within the 0.1-0.3 % a rig's loop shows).
    speed_wobble_rev : tuple of tuple of float
        Terms at once and twice the platform revolution: (relative amplitude [-], phase
        [rad]).
    acceleration_m_s2 : float
        Speed ramp through the nominal middle [m/s^2]. Default 0.
    inertia_kg_m2 : float
        Wheel-side inertia whose acceleration torque is in the torque [kg*m^2].
    creepage_rate_per_s : float
        Wheel slip: the creepage runs away at this rate through the nominal middle [1/s].
        Default 0.
    slip_force_drop : float
        The creep force falls by this share over the record [-]. Default 0.
    seed : int
        Random seed of the noise.
    """

    fs_hz: float = 16_670.0
    n_revolutions: float = 1.0
    speed_m_s: float = 7.0 / 3.6
    wheel_radius_m: float = 0.0675
    platform_radius_m: float = 2.0
    creepage: float = 2e-3
    normal_load_n: float = 4200.0
    lateral_force_n: float = 40.0
    dc_torque_nm: float = 30.0
    modulation_hz: float = 2.0
    modulation_amplitude_nm: float = 8.0
    modulation_phase_rad: float = 0.3
    phase_lag_deg: float = 20.0
    wheel_mod_amplitude_rad_s: float = 2e-3
    wheel_eccentricity: tuple[float, float] = (7e-3, 3e-3)
    platform_eccentricity: tuple[float, float] = (5e-3, 2e-3)
    torque_noise_nm: float = 0.5
    wheel_noise_rad_s: float = 2e-3
    platform_noise_rad_s: float = 1e-3
    force_noise_n: float = 20.0
    vibration_hz: tuple[float, ...] = (15.5, 37.0, 120.0)
    torque_vibration_nm: float = 0.5
    wheel_vibration_rad_s: float = 1e-3
    sleeper_force_n: float = 60.0
    force_mod_amplitude_n: float = 0.0  # creep-force answer to the modulation, in phase [N]
    #: slow speed variation: (relative amplitude [-], frequency [Hz], phase [rad]) per term;
    #: the default is 0.2 % RMS in all (assumed, within the 0.1-0.3 % a rig's loop shows)
    speed_wobble: tuple[tuple[float, float, float], ...] = (
        (2.0e-3, 0.27, 0.4), (1.2e-3, 0.55, 2.1), (0.8e-3, 0.9, 4.0))
    #: terms at once and twice the platform revolution (relative amplitude [-], phase [rad])
    speed_wobble_rev: tuple[tuple[float, float], ...] = ((1.0e-3, 0.8), (0.5e-3, 2.6))
    acceleration_m_s2: float = 0.0  # speed ramp through the nominal middle [m/s^2]
    inertia_kg_m2: float = 4.0  # wheel-side inertia whose acceleration torque is in the torque
    #: wheel slip: the creepage runs away at this rate through the nominal middle [1/s] and
    #: the creep force falls by ``slip_force_drop`` (relative) over the record
    creepage_rate_per_s: float = 0.0
    slip_force_drop: float = 0.0
    seed: int = 0

    @property
    def platform_speed_rad_s(self) -> float:
        return self.speed_m_s / self.platform_radius_m

    @property
    def wheel_speed_rad_s(self) -> float:
        return self.speed_m_s * (1 + self.creepage) / self.wheel_radius_m

    @property
    def coa(self) -> float:
        fx = self.dc_torque_nm / self.wheel_radius_m
        return float(np.hypot(fx, self.lateral_force_n) / self.normal_load_n)


def speed_profile(spec: SyntheticSpec, t: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray]:
    """The relative rolling speed of a spec's wobble and ramp, its derivative and integral.

    Analytic (no numerical integration). The revolution terms are taken at the nominal
    platform angle ``Omega*t`` (their frequencies are once and twice the nominal revolution).

    Parameters
    ----------
    spec : SyntheticSpec
        The recording's parameters.
    t : ndarray
        Times [s].

    Returns
    -------
    rel : ndarray
        v(t)/V [-].
    d_rel : ndarray
        Its time derivative [1/s].
    integral : ndarray
        Its integral from t = 0 [s].
    """
    t = np.asarray(t, dtype=np.float64)
    rel = np.ones_like(t)
    d_rel = np.zeros_like(t)
    integral = t.copy()
    t_mid = spec.n_revolutions * np.pi / spec.platform_speed_rad_s  # nominal middle [s]
    terms = [(a, f, ph) for a, f, ph in spec.speed_wobble]
    f_rev = spec.platform_speed_rad_s / (2 * np.pi)
    terms += [(a, (k + 1) * f_rev, ph) for k, (a, ph) in enumerate(spec.speed_wobble_rev)]
    for a, f, ph in terms:
        w = 2 * np.pi * f
        rel += a * np.cos(w * t + ph)
        d_rel -= a * w * np.sin(w * t + ph)
        integral += a * (np.sin(w * t + ph) - np.sin(ph)) / w
    acc = spec.acceleration_m_s2 / spec.speed_m_s
    rel += acc * (t - t_mid)
    d_rel += acc
    integral += acc * (0.5 * t * t - t_mid * t)
    return rel, d_rel, integral


def synthetic_recording(spec: SyntheticSpec) -> Recording:
    """A recording that follows a spec exactly (module docstring).

    Parameters
    ----------
    spec : SyntheticSpec
        The parameters.

    Returns
    -------
    Recording
        The channels (SI units) at ``spec.fs_hz``.
    """
    rng = np.random.default_rng(spec.seed)
    omega_p = spec.platform_speed_rad_s
    duration = spec.n_revolutions * 2 * np.pi / omega_p
    if spec.n_revolutions > 1:  # long enough that the moving platform completes them all
        grid = np.linspace(0.0, 2.0 * duration, 200_001)
        turned = omega_p * speed_profile(spec, grid)[2]
        duration = float(grid[np.searchsorted(turned, spec.n_revolutions * 2 * np.pi)]) \
            + 0.05 * duration / spec.n_revolutions
    n = round(duration * spec.fs_hz)
    t = np.arange(n) / spec.fs_hz
    rel, _, integral = speed_profile(spec, t)
    w_mod = 2 * np.pi * spec.modulation_hz
    arg = w_mod * t + spec.modulation_phase_rad
    t_mid = spec.n_revolutions * np.pi / spec.platform_speed_rad_s
    xi_extra = spec.creepage_rate_per_s * (t - t_mid) / (1 + spec.creepage)
    kin = spec.wheel_speed_rad_s * rel * (1 + xi_extra)  # kinematic wheel speed [rad/s]
    torque = (spec.dc_torque_nm + spec.modulation_amplitude_nm * np.cos(arg)
              + spec.inertia_kg_m2 * np.gradient(kin, 1 / spec.fs_hz))
    omega_w = kin + spec.wheel_mod_amplitude_rad_s * np.cos(arg - np.radians(spec.phase_lag_deg))
    omega_p = omega_p * rel
    if spec.creepage_rate_per_s:
        theta_w = np.concatenate([[0.0], np.cumsum(0.5 * (kin[1:] + kin[:-1]))]) / spec.fs_hz
        theta_w += 0.7
    else:
        theta_w = spec.wheel_speed_rad_s * integral + 0.7
    theta_p = spec.platform_speed_rad_s * integral + 1.1
    e1, e2 = spec.wheel_eccentricity
    wheel = omega_w * (1 + e1 * np.cos(theta_w) + e2 * np.cos(2 * theta_w + 0.4))
    p1, p2 = spec.platform_eccentricity
    platform = omega_p * (1 + p1 * np.cos(theta_p) + p2 * np.cos(2 * theta_p + 1.3))
    vib_t = np.zeros(n)
    vib_w = np.zeros(n)
    for k, f in enumerate(spec.vibration_hz):
        vib_t += spec.torque_vibration_nm * np.cos(2 * np.pi * f * t + 0.5 * k)
        vib_w += spec.wheel_vibration_rad_s * np.cos(2 * np.pi * f * t + 1.5 * k)
    sleeper = spec.sleeper_force_n * np.cos(100 * theta_p)
    fx = spec.dc_torque_nm / spec.wheel_radius_m * (
        1 - spec.slip_force_drop * (t - t_mid) / (2 * t_mid))
    channels = {
        "torque_nm": torque + vib_t + spec.torque_noise_nm * rng.standard_normal(n),
        "wheel_speed_rad_s": wheel + vib_w + spec.wheel_noise_rad_s * rng.standard_normal(n),
        "platform_speed_rad_s": platform + spec.platform_noise_rad_s * rng.standard_normal(n),
        "fx_n": fx + spec.force_mod_amplitude_n * np.cos(arg) + 0.2 * sleeper
        + spec.force_noise_n * rng.standard_normal(n),
        "fy_n": spec.lateral_force_n + spec.force_noise_n * rng.standard_normal(n),
        "fz_n": spec.normal_load_n + sleeper + spec.force_noise_n * rng.standard_normal(n),
    }
    return Recording(channels, spec.fs_hz, 0.0, "synthetic")


def write_synthetic_experiment(folder, *, n_steps: int = 6, n_cycles: int = 3,
                               files_per_cycle: bool = True, fmt: str = "csv", seed: int = 0,
                               base: SyntheticSpec | None = None,
                               lags_deg: tuple[float, ...] | None = None) -> dict:
    """Write an experiment folder of synthetic recordings; return the truth per cycle.

    The phase lag grows with the step and every recording has its own modulation phase and a
    small frequency offset, as a motor controller's free-running clock would give.

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder.
    n_steps : int
        Torque steps [-]. Default 6.
    n_cycles : int
        Cycles per step [-]. Default 3.
    files_per_cycle : bool
        One file per cycle; False: one file per step spanning ``n_cycles`` revolutions.
        Default True.
    fmt : str
        Recording format ("csv", "hdf5", "parquet", "mat"). Default "csv".
    seed : int
        Random seed. Default 0.
    base : SyntheticSpec or None
        The base parameters; None: the defaults.
    lags_deg : tuple of float or None
        Phase lag per step [deg]; None: 8..38 deg.

    Returns
    -------
    dict
        ``{"cycles": [...]}``: per cycle ``step``, ``cycle``, ``phase_deg`` [deg],
        ``modulation_hz`` [Hz], ``creepage`` [-] and ``coa`` [-].
    """
    from pathlib import Path

    from torquemod.io import write_manifest, write_recording

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = base or SyntheticSpec()
    rng = np.random.default_rng(seed)
    lags = lags_deg or tuple(8.0 + 6.0 * k for k in range(n_steps))
    dc = (0.23, 22.84, 44.47, 55.22, 60.45, 65.82)
    entries, truth = [], {"cycles": []}
    suffix = {"csv": "csv", "hdf5": "h5"}[fmt]
    for k in range(n_steps):
        step = k + 1
        common = dict(phase_lag_deg=lags[k], dc_torque_nm=dc[k % len(dc)],
                      creepage=base.creepage * (1 + 0.5 * k),
                      modulation_hz=base.modulation_hz + float(rng.uniform(-4e-3, 4e-3)))
        chunks = range(1, n_cycles + 1) if files_per_cycle else [None]
        for cyc in chunks:
            wobble = tuple((a, f, float(rng.uniform(0, 2 * np.pi)))
                           for a, f, _ in base.speed_wobble)
            rev = tuple((a, float(rng.uniform(0, 2 * np.pi))) for a, _ in base.speed_wobble_rev)
            spec = SyntheticSpec(**{**base.__dict__, **common,
                                    "n_revolutions": 1.0 if cyc else float(n_cycles),
                                    "modulation_phase_rad": float(rng.uniform(0, 2 * np.pi)),
                                    "speed_wobble": wobble, "speed_wobble_rev": rev,
                                    "seed": int(rng.integers(2**31))})
            rec = synthetic_recording(spec)
            name = f"step{step}_cycle{cyc}.{suffix}" if cyc else f"step{step}.{suffix}"
            write_recording(folder / name, rec, fmt=fmt)
            entry = {"step": step, "dc_torque_nm": spec.dc_torque_nm, "file": name}
            if cyc:
                entry["cycle"] = cyc
            entries.append(entry)
            truth["cycles"].append({"step": step, "cycle": cyc, "phase_deg": spec.phase_lag_deg,
                                    "modulation_hz": spec.modulation_hz,
                                    "creepage": spec.creepage, "coa": spec.coa})
    write_manifest(folder / "experiment.toml",
                   rig={"wheel_radius_m": base.wheel_radius_m,
                        "platform_radius_m": base.platform_radius_m},
                   test={"normal_load_n": base.normal_load_n,
                         "modulation_frequency_hz": 2.0,
                         "modulation_amplitude_nm": base.modulation_amplitude_nm},
                   recordings=entries)
    return truth


def write_creep_experiment(folder, *, mu: float = 0.3, k_a: float = 1.0, k_s: float = 0.4,
                           stiffness: float = 250.0,
                           saturation_fractions=(0.003, 0.3, 0.55, 0.7, 0.8, 0.9),
                           n_cycles: int = 2, seed: int = 0, fmt: str = "csv") -> dict:
    """An experiment folder whose steps lie on one Polach creep curve.

    Step i runs at a mean ``CoA = saturation_fractions[i]*mu`` with the DC torque
    ``CoA*N*R`` and the wheel-speed answer of the rigid wheel to the 8 N*m modulation,
    ``dw = T/(j*Omega*J + R^2*N*k/V)`` (lag ``atan(C/k)``, [2]_); k is the curve's
    describing-function slope over the creepage swing ``|dw|*R/V`` and the mean creepage is
    the one whose swing-averaged CoA is the step's (found together, self-consistently). The
    manifest gives the wheel-side inertia, so the theory constant comes from the rig. This is
    the README's example: both estimates of mu are determined when the steps reach ~90 % of
    saturation.

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder.
    mu : float
        Friction coefficient [-]. Default 0.3.
    k_a : float
        Reduction factor kA [-]. Default 1.
    k_s : float
        Reduction factor kS [-]. Default 0.4.
    stiffness : float
        Lumped contact stiffness s [-]. Default 250.
    saturation_fractions : sequence of float
        Each step's CoA as a share of mu [-].
    n_cycles : int
        Cycles per step [-]. Default 2.
    seed : int
        Random seed. Default 0.
    fmt : str
        Recording format. Default "csv".

    Returns
    -------
    dict
        The truth: ``mu`` [-], ``theory_constant`` [-] and per step ``creepage`` [-], ``coa``
        [-], ``phase_deg`` [deg], ``dc_torque_nm`` [N*m].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8).
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    from torquemod.analysis.contact.polach import swing_average, swing_slope
    from torquemod.analysis.creep import phase_from_constant_deg, theory_constant
    from torquemod.analysis.polachcurve import polach_coa, polach_slope
    from torquemod.io import write_manifest, write_recording

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = SyntheticSpec(lateral_force_n=0.0)
    rng = np.random.default_rng(seed)
    theta = np.array([mu, k_a * stiffness, k_s * stiffness])
    omega = 2 * np.pi * base.modulation_hz
    c = theory_constant(inertia_kg_m2=base.inertia_kg_m2, speed_m_s=base.speed_m_s,
                        wheel_radius_m=base.wheel_radius_m, normal_load_n=base.normal_load_n,
                        frequency_hz=base.modulation_hz)
    entries, steps = [], []
    def curve(x):
        return np.sign(x) * polach_coa(np.abs(x), theta)

    def slope(x):
        return polach_slope(np.abs(x), theta)

    for i, frac in enumerate(saturation_fractions, start=1):
        coa = float(frac) * mu
        swing, imp = 0.0, None
        for _ in range(8):  # the swing, the mean creepage and the slope agree
            lo, hi = 0.0, 1.0
            for _ in range(100):  # the creepage whose swing-averaged CoA is this CoA
                mid = 0.5 * (lo + hi)
                low = float(swing_average(curve, mid, swing)) < coa
                lo, hi = (mid, hi) if low else (lo, mid)
            xi = 0.5 * (lo + hi)
            k = float(swing_slope(curve, xi, swing, slope=slope))
            imp = 1j * omega * base.inertia_kg_m2 + (
                base.wheel_radius_m**2 * base.normal_load_n * k / base.speed_m_s)
            swing = base.modulation_amplitude_nm / abs(imp) * base.wheel_radius_m \
                / base.speed_m_s
        phase = float(phase_from_constant_deg(c, k))
        dc = coa * base.normal_load_n * base.wheel_radius_m
        steps.append({"step": i, "creepage": xi, "coa": coa, "phase_deg": phase,
                      "dc_torque_nm": dc})
        for cyc in range(1, n_cycles + 1):
            spec = SyntheticSpec(**{**base.__dict__, "creepage": xi, "dc_torque_nm": dc,
                                    "phase_lag_deg": phase,
                                    "wheel_mod_amplitude_rad_s":
                                        base.modulation_amplitude_nm / abs(imp),
                                    "modulation_hz": base.modulation_hz
                                    + float(rng.uniform(-4e-3, 4e-3)),
                                    "modulation_phase_rad": float(rng.uniform(0, 2 * np.pi)),
                                    "seed": int(rng.integers(2**31))})
            name = f"step{i}_cycle{cyc}.{ {'csv': 'csv', 'hdf5': 'h5'}[fmt]}"
            write_recording(folder / name, synthetic_recording(spec), fmt=fmt)
            entries.append({"step": i, "cycle": cyc, "dc_torque_nm": dc, "file": name})
    write_manifest(folder / "experiment.toml",
                   rig={"wheel_radius_m": base.wheel_radius_m,
                        "platform_radius_m": base.platform_radius_m,
                        "wheel_inertia_kg_m2": base.inertia_kg_m2},
                   test={"normal_load_n": base.normal_load_n,
                         "modulation_frequency_hz": base.modulation_hz,
                         "modulation_amplitude_nm": base.modulation_amplitude_nm},
                   recordings=entries)
    return {"mu": mu, "theory_constant": c, "steps": steps}


#: V-Track's torque steps (Table 1 of the paper) as fractions of the highest
VTRACK_STEP_FRACTIONS = (0.0035, 0.35, 0.68, 0.84, 0.92, 1.0)


def synthetic_phase_progression(mu: float, ratio_ka_ks: float, k_scale: float, u_max: float,
                                *, constant: float = 10.2, swing: bool = False,
                                fractions=VTRACK_STEP_FRACTIONS):
    """CoA, phase and creepage swing of torque steps on a Polach curve.

    ``CoA = mu*h(k_scale*xi/mu; kA/kS)`` [1]_ up to the utilisation ``u_max``, by the
    rigid-wheel law ``tan(phi) = C/k`` [2]_. With ``swing`` the creepage swing of V-Track's
    8 N*m, 2 Hz modulation (J = 4 kg m^2, R = 0.0675 m, N = 4200 N, V = 1.944 m/s:
    ``|dw| = T/|j*Omega*J + R^2*N*k/V|``, swing = ``|dw|*R/V``) is found self-consistently and k
    is the describing-function slope over it.

    Parameters
    ----------
    mu : float
        Friction coefficient [-].
    ratio_ka_ks : float
        kA/kS [-].
    k_scale : float
        Initial slope scale kS*s [-].
    u_max : float
        Highest utilisation [-].
    constant : float
        C = Omega*J*V/(R^2*N) [-]. Default 10.2 (V-Track's).
    swing : bool
        Model the creepage swing. Default False.
    fractions : sequence of float
        The steps' utilisations as shares of ``u_max`` [-]. Default V-Track's.

    Returns
    -------
    coa : ndarray
        [-].
    phase_deg : ndarray
        [deg].
    swing : ndarray or None
        Creepage swing amplitude [-]; None without ``swing``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    from torquemod.analysis.contact.polach import swing_average, swing_slope
    from torquemod.analysis.polachshape import invert_polach_h, polach_h, polach_h_slope

    r = ratio_ka_ks
    u = np.asarray(fractions, dtype=float) * u_max
    x = invert_polach_h(u, r)
    k = k_scale * polach_h_slope(x, r)
    sw = None
    if swing:
        om, j, radius, load, v = 4 * np.pi, 4.0, 0.0675, 4200.0, 1.944
        for _ in range(4):
            sw = 8.0 / np.abs(1j * om * j + radius**2 * load * k / v) * radius / v
            a = sw * k_scale / mu
            lo, hi = x * 0.999, 4 * x + 4 * a + 1e-6
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                low = swing_average(lambda z: polach_h(z, r), mid, a) < u
                lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
            k = k_scale * swing_slope(lambda z: polach_h(z, r), 0.5 * (lo + hi), a,
                                      slope=lambda z: polach_h_slope(z, r))
    return u * mu, np.degrees(np.arctan2(constant, k)), sw


def write_short_train_run(folder, *, length_m: float, seed: int) -> Path:
    """The default train twin's run cut to a length of track, written into a folder.

    As ``torquemod simulate --train``: run.toml + MDF4, run_h5.toml + HDF5, truth.parquet.

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder.
    length_m : float
        Track length [m].
    seed : int
        Random seed.

    Returns
    -------
    pathlib.Path
        ``folder``.
    """
    from dataclasses import replace

    from torquemod.twins.train import load_train_config, run_train_simulation
    cfg = load_train_config()
    cfg = replace(cfg, track=replace(cfg.track, length_m=length_m))
    run_train_simulation(cfg, folder, seed=seed)
    return Path(folder)
