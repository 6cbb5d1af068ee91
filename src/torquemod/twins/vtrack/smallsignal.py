"""Small-signal theory of torque modulation: phase lag <-> creep coefficient, for the rigid wheel
(the V-Track paper's Eq. (1)) and for the full drive line with the platform's speed controller
(see :mod:`torquemod.twins.vtrack.theory` for the derivation and the large-signal case).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from torquemod.analysis.creep import phase_from_constant_deg, theory_constant
from torquemod.errors import InputError
from torquemod.twins.vtrack.params import RigParams


def rigid_wheel_phase_deg(creep_coefficient, *, inertia_kg_m2: float, speed_m_s: float,
                          wheel_radius_m: float, normal_load_n: float, frequency_hz: float):
    """Phase lag of the wheel speed behind the torque for a rigid wheel (V-Track paper, Eq. 1).

    ``phi = arctan(Omega*J*V/(R^2*N*k))``, ``Omega = 2*pi*f``; 90 deg at k = 0. The
    measurement's own formula (:func:`torquemod.analysis.creep.theory_constant`,
    :func:`torquemod.analysis.creep.phase_from_constant_deg`) in the rig's terms.

    Parameters
    ----------
    creep_coefficient : float or array_like
        k = dCoA/dxi_x [-], k >= 0.
    inertia_kg_m2 : float
        Wheel inertia J [kg*m^2].
    speed_m_s : float
        Rolling speed V [m/s].
    wheel_radius_m : float
        Wheel radius R [m].
    normal_load_n : float
        Normal load N [N].
    frequency_hz : float
        Modulation frequency f [Hz].

    Returns
    -------
    float or ndarray
        phi [deg].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    c = theory_constant(inertia_kg_m2=inertia_kg_m2, speed_m_s=speed_m_s,
                        wheel_radius_m=wheel_radius_m, normal_load_n=normal_load_n,
                        frequency_hz=frequency_hz)
    return phase_from_constant_deg(c, creep_coefficient)


def creep_coefficient_from_phase(phase_deg, *, inertia_kg_m2: float, speed_m_s: float,
                                 wheel_radius_m: float, normal_load_n: float,
                                 frequency_hz: float):
    """Inverse of :func:`rigid_wheel_phase_deg`: ``k = Omega*J*V/(R^2*N*tan(phi))``.

    Parameters
    ----------
    phase_deg : float or array_like
        phi [deg], in (0, 90].
    inertia_kg_m2 : float
        Wheel inertia J [kg*m^2].
    speed_m_s : float
        Rolling speed V [m/s].
    wheel_radius_m : float
        Wheel radius R [m].
    normal_load_n : float
        Normal load N [N].
    frequency_hz : float
        Modulation frequency f [Hz].

    Returns
    -------
    float or ndarray
        k [-].

    Raises
    ------
    InputError
        A phase outside (0, 90] deg.
    """
    phi = np.asarray(phase_deg, dtype=float)
    if np.any(~np.isfinite(phi)) or np.any(phi <= 0.0) or np.any(phi > 90.0):
        raise InputError(f"phase {phase_deg} deg is outside (0, 90] deg",
                         hint="a wheel speed that leads the torque has no creep coefficient")
    c = theory_constant(inertia_kg_m2=inertia_kg_m2, speed_m_s=speed_m_s,
                        wheel_radius_m=wheel_radius_m, normal_load_n=normal_load_n,
                        frequency_hz=frequency_hz)
    return c / np.tan(np.radians(phi))


def drive_line_response(creep_coefficient, params: RigParams, frequency_hz, *,
                        creepage: float = 0.0):
    """Transfer functions from motor torque to measured shaft torque and to wheel speed.

    Linearisation of :mod:`torquemod.twins.vtrack.rig.dynamics` at ``s = j*2*pi*f``::

        J_m s w_m = T_m - Z_s (w_m - w_w),          Z_s = k_t/s + c_t
        J_w s w_w = Z_s (w_m - w_w) - R_w dF_x
        (J_p s + K_p + K_i/s) W_p = R_p dF_x
        dF_x = N k (R_w w_w - (1 + xi0) R_p W_p) / V

    Returns ``(h_torque, h_speed)``: complex [N*m/N*m] and [rad/s per N*m], broadcast over
    ``creep_coefficient`` k [-] and ``frequency_hz`` [Hz]. ``creepage`` xi0 is the operating
    creepage (its effect is of order xi0 and usually negligible).

    Parameters
    ----------
    creep_coefficient : float or array_like
        k [-].
    params : RigParams
        The rig.
    frequency_hz : float or array_like
        f [Hz].
    creepage : float
        Operating creepage xi0 [-]. Default 0.

    Returns
    -------
    h_torque : complex or ndarray
        Measured shaft torque per motor torque [N*m/N*m].
    h_speed : complex or ndarray
        Wheel speed per motor torque [rad/s per N*m].
    """
    k = np.asarray(creep_coefficient, dtype=float)
    f = np.asarray(frequency_hz, dtype=float)
    k, f = np.broadcast_arrays(k, f)
    s = 2j * np.pi * f
    p = params
    z_s = p.shaft_stiffness_nm_rad / s + p.shaft_damping_nm_s_rad
    z_p = p.platform_inertia_kg_m2 * s + p.platform_kp_nm_s_rad + p.platform_ki_nm_rad / s
    c = p.normal_load_n * k / p.speed_m_s  # dF_x per unit creepage-velocity [N*s/m]
    rw, rp = p.wheel_radius_m, p.platform_radius_m
    m = np.zeros((*k.shape, 3, 3), dtype=complex)
    # unknowns: w_m, w_w, W_p ; equations: motor, wheel, platform
    m[..., 0, 0] = p.drive_inertia_kg_m2 * s + z_s
    m[..., 0, 1] = -z_s
    m[..., 1, 0] = -z_s
    m[..., 1, 1] = p.wheel_inertia_kg_m2 * s + z_s + rw * c * rw
    m[..., 1, 2] = -rw * c * (1.0 + creepage) * rp
    m[..., 2, 1] = -rp * c * rw
    m[..., 2, 2] = z_p + rp * c * (1.0 + creepage) * rp
    rhs = np.zeros((*k.shape, 3, 1), dtype=complex)
    rhs[..., 0, 0] = 1.0
    x = np.linalg.solve(m, rhs)[..., 0]
    h_torque = z_s * (x[..., 0] - x[..., 1])
    h_speed = x[..., 1]
    return h_torque, h_speed


def predicted_phase_deg(creep_coefficient, params: RigParams, frequency_hz, *,
                        creepage: float = 0.0):
    """Phase [deg] of the measured wheel speed behind the measured shaft torque predicted by
    :func:`drive_line_response` (positive = lag). Reduces to :func:`rigid_wheel_phase_deg`
    with ``J = wheel_inertia_kg_m2`` for an infinitely stiff platform drive.

    Parameters
    ----------
    creep_coefficient : float or array_like
        k [-].
    params : RigParams
        The rig.
    frequency_hz : float or array_like
        f [Hz].
    creepage : float
        Operating creepage [-]. Default 0.

    Returns
    -------
    float or ndarray
        Phase [deg], positive = lag.
    """
    return response_phase_deg(*drive_line_response(creep_coefficient, params, frequency_hz,
                                                   creepage=creepage))


def response_phase_deg(h_torque, h_speed):
    """Phase [deg] of the wheel speed behind the shaft torque from the two responses of
    :func:`drive_line_response` (positive = lag): what :func:`predicted_phase_deg` returns,
    for a caller that already has them.

    Parameters
    ----------
    h_torque, h_speed : complex or ndarray
        The measured shaft torque's and the wheel speed's responses, as
        :func:`drive_line_response` returns them.

    Returns
    -------
    float or ndarray
        Phase [deg], positive = lag.
    """
    return np.degrees(np.angle(h_torque / h_speed))


def creep_coefficient_from_predicted_phase(phase_deg: float, params: RigParams,
                                           frequency_hz: float) -> float:
    """Inverse of :func:`predicted_phase_deg` (scalar), by bracketing in log(k).

    Parameters
    ----------
    phase_deg : float
        Phase [deg].
    params : RigParams
        The rig.
    frequency_hz : float
        f [Hz].

    Returns
    -------
    float
        k [-].

    Raises
    ------
    InputError
        The phase is not reachable by this rig model.
    """
    def g(logk):
        return float(predicted_phase_deg(np.exp(logk), params, frequency_hz)) - phase_deg
    lo, hi = np.log(1e-6), np.log(1e5)
    if g(lo) * g(hi) > 0:
        raise InputError(f"phase {phase_deg} deg is not reachable by this rig model")
    return float(np.exp(brentq(g, lo, hi, xtol=1e-12)))
