"""One window of a train run: phase, DC torque, speeds, acceleration, CoA and the creep
coefficient from the phase. Pure functions; the same DSP core as the rig chain
(:func:`torquemod.dsp.phase.sinefit_phase`).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, replace

import numpy as np

from torquemod.dsp.phase import sinefit_phase
from torquemod.io.run import Vehicle


@dataclass(frozen=True)
class WindowResult:
    """Measurements of one window of whole modulation periods on a train.

    A row of the along-track table: the window's phase, DC torque, speeds, acceleration,
    CoA and the creep coefficient from the phase (:func:`measure_window`). Time and
    position are at the window's centre (the row describes the stretch the window covers;
    a live system has it half a window later, at the window's end).

    Attributes
    ----------
    time_s : float
        Time of the window's centre [s].
    position_m : float
        Mean position along the track over the window [m].
    speed_m_s : float
        Mean reference (vehicle) speed V [m/s].
    wheel_speed_rad_s : float
        Mean axle angular speed w [rad/s].
    dc_torque_nm : float
        Mean axle torque [N*m].
    accel_m_s2 : float
        Acceleration of the reference dV/dt [m/s^2] (least-squares slope).
    coa : float
        Coefficient of adhesion (T - J*dw/dt)/(N*R) [-].
    coa_se : float
        Standard error of ``coa`` [-].
    creepage : float
        Longitudinal creepage (w*R - V)/V [-].
    phase_deg : float
        Lag of the wheel speed behind the torque at the modulation frequency [deg]
        (declared sensor dynamics divided out).
    phase_se_deg : float
        Standard error of ``phase_deg`` at the Cramer-Rao bound [deg].
    creep_coefficient : float
        Creep coefficient k = dCoA/dxi from the phase and amplitude ratio [-].
    creep_coefficient_se : float
        Standard error of ``creep_coefficient`` [-].
    creepage_swing : float
        Amplitude of the creepage oscillation the modulation causes, R*|w~|/V [-].
    wheel_excess_accel_m_s2 : float
        R*dw/dt - dV/dt [m/s^2]: the wheel accelerating faster than the vehicle (a slip).
    dc_step_ratio : float
        Change of the mean torque from the first to the last modulation period over the
        modulation's amplitude [-] (a DC step inside the window leaks into the sine fit).
        Default 0.
    torque_speed_ratio : complex
        Complex ratio T/w at the modulation frequency [N*m*s/rad], declared sensor dynamics
        divided out; phase and k come from it (:func:`with_delay`). Default NaN.
    torque_amplitude_nm : float
        Amplitude of the torque at the modulation frequency [N*m] (the premise of the
        method: :func:`torquemod.ontrain.quality.window_quality`). Default NaN.
    """

    time_s: float
    position_m: float
    speed_m_s: float
    wheel_speed_rad_s: float
    dc_torque_nm: float
    accel_m_s2: float
    coa: float
    coa_se: float
    creepage: float
    phase_deg: float
    phase_se_deg: float
    creep_coefficient: float
    creep_coefficient_se: float
    creepage_swing: float
    wheel_excess_accel_m_s2: float
    dc_step_ratio: float = 0.0
    torque_speed_ratio: complex = complex("nan")
    torque_amplitude_nm: float = math.nan


def load_impedance(ratio: complex, vehicle: Vehicle, frequency_hz: float) -> complex:
    """The impedance G the wheelset's speed meets beyond its own inertia.

    G is the contact and, behind it, the vehicle, from the measured complex ratio ``T/w`` of
    the torque to the axle speed at the modulation frequency. Rigid drive line:
    ``T = (j*Omega*J + G)*w``.

    Parameters
    ----------
    ratio : complex
        Measured ratio T/w at the modulation frequency [N*m*s/rad].
    vehicle : torquemod.io.run.Vehicle
        The vehicle: wheelset inertia J [kg*m^2] and, when declared, the drive line (motor
        inertia J_m, coupling stiffness k_c and damping c_c referred to the axle, gear ratio).
    frequency_hz : float
        Modulation frequency Omega/(2*pi) [Hz].

    Returns
    -------
    complex
        G [N*m*s/rad].

    Notes
    -----
    With a drive line (motor inertia J_m, coupling Z = k_c/(j*Omega) + c_c; the torque acts on
    the motor) the model ``T = j*Omega*J_m*w_m + Z*(w_m - w)``, ``Z*(w_m - w) = (j*Omega*J_w +
    G)*w`` gives, for the axle speed ``w``::

        G = Z/(j*Omega*J_m + Z) * T/w - j*Omega*J_w - Z*j*Omega*J_m/(j*Omega*J_m + Z)

    and, when ``vehicle.gear_ratio`` says torque and speed were recorded at the motor (the
    coupling and the wheelset in series)::

        1/(T/w_m - j*Omega*J_m) = 1/Z + 1/(j*Omega*J_w + G)

    Examples
    --------
    >>> from torquemod.io.run import Vehicle
    >>> v = Vehicle(wheel_radius_m=0.46, normal_load_n=80e3, inertia_kg_m2=100.0)
    >>> g = load_impedance(complex(2000.0, 0.0) + 2j * 3.141592653589793 * 5.0 * 100.0, v, 5.0)
    >>> round(g.real, 6), round(g.imag, 6)
    (2000.0, 0.0)
    """
    jw_om = 2j * math.pi * frequency_hz
    if not vehicle.has_drive_line:
        return ratio - jw_om * vehicle.inertia_kg_m2
    jm = vehicle.motor_inertia_kg_m2
    jw = vehicle.inertia_kg_m2 - jm
    z = vehicle.coupling_stiffness_nm_rad / jw_om + vehicle.coupling_damping_nm_s_rad
    if vehicle.gear_ratio:  # the speed is the motor's (referred to the axle): see above
        return 1.0 / (1.0 / (ratio - jw_om * jm) - 1.0 / z) - jw_om * jw
    return z / (jw_om * jm + z) * ratio - jw_om * jw - z * jw_om * jm / (jw_om * jm + z)


def damping_from_ratio(ratio: complex, vehicle: Vehicle, frequency_hz: float
                       ) -> tuple[float, float]:
    """Contact damping D and the vehicle inertia seen at the wheel from the ratio T/w.

    The contact (D) and the vehicle (Z_v = c' + j*Omega*M') act in series between wheel and
    track, ``1/G = 1/D + 1/Z_v``, with G from :func:`load_impedance`. A train moves with the
    modulating force (the rig's platform hardly does).

    Parameters
    ----------
    ratio : complex
        Measured ratio T/w at the modulation frequency [N*m*s/rad] (needs the torque's
        calibration: its amplitude counts, not only its phase).
    vehicle : torquemod.io.run.Vehicle
        The vehicle: radius R [m], inertias, drive line and declared damping
        ``vehicle_damping_n_s_m`` [N*s/m] (0: the vehicle is a pure inertia).
    frequency_hz : float
        Modulation frequency [Hz].

    Returns
    -------
    damping : float
        D = R^2*N*k/V [N*m*s/rad]; NaN when ``Re(1/G) <= x`` or the declared damping exceeds
        what the measured inertia allows (``2*c'*|y| > 1``).
    inertia : float
        M' = M*R^2 [kg*m^2]; inf when ``Im(1/G) >= 0``.

    Notes
    -----
    D is real, so ``Im(1/G) = Im(1/Z_v) = y``; with ``c' = vehicle_damping_n_s_m*R^2`` the real
    part ``Re(1/Z_v) = x`` solves ``c'*(x^2 + y^2) = x`` (the root with Omega*M' > c')::

        x = 2*c'*y^2 / (1 + sqrt(1 - 4*c'^2*y^2)),   D = 1/(Re(1/G) - x),
        M' = -y/((x^2 + y^2)*Omega)

    The rigid-wheel relation ``tan(phi) = Omega*J/D`` of [1]_ (Eq. 1) is the limit
    M' -> infinity.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    g = load_impedance(ratio, vehicle, frequency_hz)
    if g == 0:
        return math.nan, math.nan
    inv = 1.0 / g
    y = inv.imag
    c = vehicle.vehicle_damping_n_s_m * vehicle.wheel_radius_m ** 2
    disc = 1.0 - 4.0 * c * c * y * y
    if disc < 0.0:
        return math.nan, math.nan
    x = 2.0 * c * y * y / (1.0 + math.sqrt(disc))
    d = 1.0 / (inv.real - x) if inv.real > x else math.nan
    om = 2 * math.pi * frequency_hz
    m = -y / ((x * x + y * y) * om) if y < 0 else math.inf
    return d, m


def rotation_orders_hz(f_rot_hz: float, gear_ratio: float | None, fs_hz: float,
                       duration_s: float) -> tuple[float, ...]:
    """The encoder's once- and twice-per-revolution lines fitted out of a window.

    Eccentricity and tooth errors put lines at the axle's rotation frequency and its double
    and, when the speed was recorded at the motor, at ``gear_ratio`` times those.

    Parameters
    ----------
    f_rot_hz : float
        Axle rotation frequency [Hz].
    gear_ratio : float or None
        Motor-to-axle gear ratio [-] when the speed was recorded at the motor, else None.
    fs_hz : float
        Sampling rate [Hz].
    duration_s : float
        Window length [s]; 1/duration_s is the resolution step.

    Returns
    -------
    tuple of float
        The line frequencies [Hz]: lines below 0.2 Hz or above 0.45*fs are left out, and a
        line within one resolution step of one already kept (the fit would be rank deficient).

    Examples
    --------
    >>> rotation_orders_hz(3.0, None, 200.0, 2.0)
    (3.0, 6.0)
    """
    lines = [f_rot_hz, 2 * f_rot_hz]
    if gear_ratio:
        lines += [gear_ratio * f_rot_hz, 2 * gear_ratio * f_rot_hz]
    kept: list[float] = []
    for f in lines:
        if 0.2 < f < 0.45 * fs_hz and all(abs(f - k) > 1.0 / duration_s for k in kept):
            kept.append(f)
    return tuple(kept)


def measure_window(torque_nm: np.ndarray, wheel_speed_rad_s: np.ndarray,
                   speed_m_s: np.ndarray, position_m: np.ndarray, fs_hz: float,
                   t_end_s: float, vehicle: Vehicle, frequency_hz: float) -> WindowResult:
    """Measure one window of whole modulation periods (the arrays are the window).

    Parameters
    ----------
    torque_nm : ndarray
        Axle torque [N*m].
    wheel_speed_rad_s : ndarray
        Axle angular speed [rad/s].
    speed_m_s : ndarray
        Reference (vehicle) speed [m/s].
    position_m : ndarray
        Position along the track [m].
    fs_hz : float
        Sampling rate [Hz].
    t_end_s : float
        Time of the window's last sample [s].
    vehicle : torquemod.io.run.Vehicle
        Wheel radius R, normal load N, inertia J, drive line and sensor dynamics.
    frequency_hz : float
        Modulation frequency [Hz].

    Returns
    -------
    WindowResult
        The window's measurements.

    Notes
    -----
    Phase: the sine fit at the modulation frequency with a line and the first two orders of
    the axle's (and the motor's, :func:`rotation_orders_hz`) revolution as nuisance terms,
    standard error at the Cramer-Rao bound [1]_; the declared sensor dynamics
    (:meth:`~torquemod.io.run.Vehicle.sensor_response`) are divided out of the
    torque-to-speed ratio, so ``phase_deg`` is the lag behind the true torque.
    ``CoA = (T - J*dw/dt)/(N*R)`` with dw/dt the least-squares slope of the axle speed.
    Creep coefficient ``k = D*V/(R^2*N)`` with D from the phase and amplitude ratio
    (:func:`damping_from_ratio`; [2]_, Eq. 1); its standard error from k's change over one
    standard error of the phase and of the (log) amplitude ratio. V is |V|, at least 0.5 m/s.

    References
    ----------
    .. [1] D.C. Rife and R.R. Boorstyn, "Single-tone parameter estimation from discrete-time
       observations", IEEE Trans. Inf. Theory 20(5) (1974) 591-598.
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig).
    """
    r, n_load, j = vehicle.wheel_radius_m, vehicle.normal_load_n, vehicle.inertia_kg_m2
    n = torque_nm.size
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    w_mean = float(wheel_speed_rad_s.mean())
    f_rot = abs(w_mean) / (2 * math.pi)
    nuisance = rotation_orders_hz(f_rot, vehicle.gear_ratio, fs_hz, n / fs_hz)
    fit = sinefit_phase(torque_nm, wheel_speed_rad_s, fs_hz, frequency_hz,
                        nuisance_hz=nuisance, trend=True)
    tt = t - t.mean()
    den = float(tt @ tt)
    dw_dt = float(tt @ (wheel_speed_rad_s - w_mean)) / den
    v_mean = float(speed_m_s.mean())
    dv_dt = float(tt @ (speed_m_s - v_mean)) / den
    t_dc = float(torque_nm.mean())
    coa = (t_dc - j * dw_dt) / (n_load * r)
    coa_se = float(np.std(torque_nm)) / math.sqrt(n) / (n_load * r)
    v_ref = _reference_speed(v_mean)
    creepage = (w_mean * r - v_mean) / v_ref
    # the ratio of the true signals: the declared sensor dynamics divided out
    ratio = fit.torque_amplitude / fit.wheel_amplitude * cmath.exp(
        1j * math.radians(fit.phase_deg)) / vehicle.sensor_response(frequency_hz)
    phase = math.degrees(cmath.phase(ratio))
    k, k_se = _creep_coefficient(ratio, math.radians(fit.phase_stderr_deg), v_ref, vehicle,
                                 frequency_hz)
    per = max(1, round(fs_hz / frequency_hz))
    step = abs(float(torque_nm[-per:].mean() - torque_nm[:per].mean()))
    return WindowResult(
        time_s=float(t_end_s) - (n - 1) / (2 * fs_hz), position_m=float(position_m.mean()),
        speed_m_s=v_mean, wheel_speed_rad_s=w_mean, dc_torque_nm=t_dc, accel_m_s2=dv_dt,
        coa=coa,
        coa_se=coa_se, creepage=creepage, phase_deg=phase,
        phase_se_deg=fit.phase_stderr_deg, creep_coefficient=k, creep_coefficient_se=k_se,
        creepage_swing=r * fit.wheel_amplitude / v_ref,
        wheel_excess_accel_m_s2=r * dw_dt - dv_dt,
        dc_step_ratio=step / max(fit.torque_amplitude, 1e-12), torque_speed_ratio=ratio,
        torque_amplitude_nm=float(fit.torque_amplitude))


def _reference_speed(speed_m_s: float) -> float:
    """The speed [m/s] creepage and k are referred to: |V|, at least 0.5 m/s (standstill)."""
    return max(abs(speed_m_s), 0.5)


def _creep_coefficient(ratio: complex, e: float, v_ref: float, vehicle: Vehicle,
                       frequency_hz: float) -> tuple[float, float]:
    """k = D*V/(R^2*N) from the ratio T/w (:func:`damping_from_ratio`) and its standard
    error from k's change over one standard error ``e`` [rad] of the phase and of the (log)
    amplitude ratio."""
    scale = v_ref / (vehicle.wheel_radius_m ** 2 * vehicle.normal_load_n)

    def k_of(x: complex) -> float:
        return damping_from_ratio(x, vehicle, frequency_hz)[0] * scale

    k = k_of(ratio)
    k_se = math.hypot(k_of(ratio * complex(math.cos(e), math.sin(e))) - k,
                      k_of(ratio * (1 + e)) - k)
    return k, k_se


def with_delay(w: WindowResult, vehicle: Vehicle, frequency_hz: float,
               delay_s: float) -> WindowResult:
    """A window with a further net delay of the torque behind the speed divided out.

    Parameters
    ----------
    w : WindowResult
        The window as measured.
    vehicle : torquemod.io.run.Vehicle
        The vehicle (for k, :func:`damping_from_ratio`).
    frequency_hz : float
        Modulation frequency [Hz].
    delay_s : float
        Net delay of the torque behind the speed [s] (:mod:`torquemod.ontrain.delay`).

    Returns
    -------
    WindowResult
        ``w`` with ``torque_speed_ratio`` multiplied by ``exp(j*2*pi*f*delay_s)`` and phase,
        k and its standard error recomputed; ``w`` itself when ``delay_s`` is 0.
    """
    if delay_s == 0.0:
        return w
    ratio = w.torque_speed_ratio * cmath.exp(2j * math.pi * frequency_hz * delay_s)
    k, k_se = _creep_coefficient(ratio, math.radians(w.phase_se_deg),
                                 _reference_speed(w.speed_m_s), vehicle,
                                 frequency_hz)
    return replace(w, phase_deg=math.degrees(cmath.phase(ratio)), creep_coefficient=k,
                   creep_coefficient_se=k_se, torque_speed_ratio=ratio)
