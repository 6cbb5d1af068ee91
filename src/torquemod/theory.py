"""Small-signal theory of torque modulation: phase lag <-> creep coefficient.

Sign convention of the project: ``phase_deg > 0`` when the measured wheel angular velocity
lags the measured torque.

Rigid wheel (FACTS.md §1; the V-Track paper's Eq. (1) with its constant). Linearising the
wheel ``J*w' = T - R*F_x`` with ``F_x = N*k*xi_x`` and ``xi_x = (w*R - V)/V`` gives::

    dw/dT = 1 / (j*Omega*J + R^2*N*k/V)   =>   tan(phi) = Omega*J*V / (R^2*N*k)

with ``Omega = 2*pi*f_mod`` and ``k = dCoA/dxi_x`` the creep coefficient.

Drive line (this module's :func:`drive_line_response`): motor inertia -- torque shaft
(stiffness, damping) -- torque sensor -- wheel -- contact -- platform on its PI speed
controller. The torque sensor sits in series with the shaft and its encoder turns with the
wheel, so the measured pair (shaft torque, wheel speed) brackets exactly the inertia
*downstream of the sensor* (``RigParams.wheel_inertia_kg_m2``): the motor side and the shaft
change amplitudes but cancel from the phase. What remains beyond the rigid formula is the
platform: the traction reaction ``F_x*R_p`` makes the platform speed, and hence the rolling
speed, respond a little, which is included here exactly as in the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .contact.polach import creep_force
from .errors import InputError
from .rig.params import RigParams


def rigid_wheel_phase_deg(creep_coefficient, *, inertia_kg_m2: float, speed_m_s: float,
                          wheel_radius_m: float, normal_load_n: float, frequency_hz: float):
    """Phase lag [deg] of wheel speed behind torque for a rigid wheel (FACTS.md §1):
    ``phi = arctan(Omega*J*V / (R^2*N*k))``, ``Omega = 2*pi*f``; 90 deg at k = 0.

    ``creep_coefficient`` k = dCoA/dxi_x [-] (scalar or array, k >= 0).
    """
    k = np.asarray(creep_coefficient, dtype=float)
    omega = 2.0 * np.pi * frequency_hz
    num = omega * inertia_kg_m2 * speed_m_s
    den = wheel_radius_m**2 * normal_load_n * k
    return np.degrees(np.arctan2(num, den))


def creep_coefficient_from_phase(phase_deg, *, inertia_kg_m2: float, speed_m_s: float,
                                 wheel_radius_m: float, normal_load_n: float,
                                 frequency_hz: float):
    """Inverse of :func:`rigid_wheel_phase_deg`:
    ``k = Omega*J*V / (R^2*N*tan(phi))`` [-]; phases outside (0, 90] deg raise InputError."""
    phi = np.asarray(phase_deg, dtype=float)
    if np.any(~np.isfinite(phi)) or np.any(phi <= 0.0) or np.any(phi > 90.0):
        raise InputError(f"phase {phase_deg} deg is outside (0, 90] deg",
                         hint="a wheel speed that leads the torque has no creep coefficient")
    omega = 2.0 * np.pi * frequency_hz
    return omega * inertia_kg_m2 * speed_m_s / (
        wheel_radius_m**2 * normal_load_n * np.tan(np.radians(phi)))


def drive_line_response(creep_coefficient, params: RigParams, frequency_hz, *,
                        creepage: float = 0.0):
    """Transfer functions from motor torque to measured shaft torque and to wheel speed.

    Linearisation of :mod:`torquemod.rig.dynamics` at ``s = j*2*pi*f``::

        J_m s w_m = T_m - Z_s (w_m - w_w),          Z_s = k_t/s + c_t
        J_w s w_w = Z_s (w_m - w_w) - R_w dF_x
        (J_p s + K_p + K_i/s) W_p = R_p dF_x
        dF_x = N k (R_w w_w - (1 + xi0) R_p W_p) / V

    Returns ``(h_torque, h_speed)``: complex [N*m/N*m] and [rad/s per N*m], broadcast over
    ``creep_coefficient`` k [-] and ``frequency_hz`` [Hz]. ``creepage`` xi0 is the operating
    creepage (its effect is of order xi0 and usually negligible).
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
    with ``J = wheel_inertia_kg_m2`` for an infinitely stiff platform drive."""
    h_t, h_w = drive_line_response(creep_coefficient, params, frequency_hz, creepage=creepage)
    return np.degrees(np.angle(h_t / h_w))


def creep_coefficient_from_predicted_phase(phase_deg: float, params: RigParams,
                                           frequency_hz: float) -> float:
    """Inverse of :func:`predicted_phase_deg` (scalar), by bracketing in log(k)."""
    def g(logk):
        return float(predicted_phase_deg(np.exp(logk), params, frequency_hz)) - phase_deg
    lo, hi = np.log(1e-6), np.log(1e5)
    if g(lo) * g(hi) > 0:
        raise InputError(f"phase {phase_deg} deg is not reachable by this rig model")
    return float(np.exp(brentq(g, lo, hi, xtol=1e-12)))


# --------------------------------------------------------------------------------------------
# Steady state of the Polach contact
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OperatingPoint:
    """Steady rolling under a DC torque. ``creepage`` xi_x [-]; ``coa`` sqrt(Fx²+Fy²)/Fz [-];
    ``creep_coefficient`` d(Fx/Fz)/dxi_x [-] (what the phase responds to; equals dCoA/dxi_x
    without lateral creepage); ``dcoa_dxi`` dCoA/dxi_x [-]; forces [N]; ``slipped`` True when
    the torque exceeds what the creep curve can carry (then the other fields are NaN)."""

    dc_torque_nm: float
    creepage: float
    coa: float
    creep_coefficient: float
    dcoa_dxi: float
    fx_n: float
    fy_n: float
    slipped: bool


def _fx(xi_x, params: RigParams):
    c = params.contact
    return creep_force(xi_x, c.lateral_creepage, normal_load_n=params.normal_load_n,
                       speed_m_s=params.speed_m_s, **c.polach_kwargs())


def creep_curve_peak(params: RigParams, *, max_creepage: float = 0.5) -> tuple[float, float]:
    """``(creepage, torque_nm)`` at the maximum of ``R_w*F_x(xi_x)``: the largest DC torque
    the wheel can carry in steady rolling (beyond it the wheel slips)."""
    grid = np.geomspace(1e-7, max_creepage, 4000)
    fx = _fx(grid, params)[0]
    i = int(np.argmax(fx))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(lambda x: -float(_fx(x, params)[0]), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-12})
    xi = float(res.x)
    return xi, float(_fx(xi, params)[0]) * params.wheel_radius_m


def operating_point(dc_torque_nm: float, params: RigParams) -> OperatingPoint:
    """Solve ``T_dc = R_w*F_x(xi_x, xi_y)`` for xi_x on the rising branch (scipy brentq) and
    return the steady-state creepage, CoA and creep coefficients (central differences)."""
    xi_peak, t_peak = creep_curve_peak(params)
    rw, n = params.wheel_radius_m, params.normal_load_n
    if dc_torque_nm >= t_peak:
        nan = float("nan")
        return OperatingPoint(dc_torque_nm, nan, nan, nan, nan, nan, nan, True)
    lo = -xi_peak
    xi = brentq(lambda x: float(_fx(x, params)[0]) * rw - dc_torque_nm, lo, xi_peak,
                xtol=1e-15, rtol=1e-13, maxiter=500)
    h = max(1e-9, 1e-4 * abs(xi))
    fxp, fyp = _fx(xi + h, params)
    fxm, fym = _fx(xi - h, params)
    fx, fy = _fx(xi, params)
    k = float(fxp - fxm) / (2 * h) / n
    coa_p, coa_m = np.hypot(fxp, fyp) / n, np.hypot(fxm, fym) / n
    return OperatingPoint(dc_torque_nm=float(dc_torque_nm), creepage=float(xi),
                          coa=float(np.hypot(fx, fy) / n), creep_coefficient=k,
                          dcoa_dxi=float(coa_p - coa_m) / (2 * h), fx_n=float(fx),
                          fy_n=float(fy), slipped=False)
