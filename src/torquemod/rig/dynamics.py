"""Equations of motion of the V-Track twin and their fixed-step RK4 integrator (numba).

States (all rotations referred to the wheel axle, except the platform):

==========  ===============================================================  =========
``twist``   torsion of the torque shaft, motor side minus wheel side          [rad]
``w_m``     angular speed of motor + gearboxes                               [rad/s]
``w_w``     angular speed of the wheel (and of the torque sensor's encoder)  [rad/s]
``th_w``    wheel angle                                                      [rad]
``th_p``    platform angle                                                   [rad]
``W_p``     platform angular speed                                           [rad/s]
``i_pi``    integral of the platform speed error (PI controller)             [rad]
==========  ===============================================================  =========

Equations (derived for this model; the contact force is quasi-static, Polach 2005)::

    T_sh      = k_t*twist + c_t*(w_m - w_w)               shaft (and sensor) torque
    J_m w_m'  = T_m(t) - T_sh                              motor side
    J_w w_w'  = T_sh - R_w*F_x                             wheel (creep-force moment)
    J_p W_p'  = K_p*(W_ref - W_p) + K_i*i_pi + R_p*F_x - T_rr
    xi_x      = (w_w*R_w - W_p*R_p)/(W_p*R_p)              V-Track paper Eq. (3)
    F_x, F_y  = Polach(xi_x, xi_y, N(th_p), V = W_p*R_p)

The motor torque is ``T_m = T_dc(t) + A*sin(2*pi*f*(t - t_gen) + phi)`` with a DC ramp.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..contact.polach import creep_force_scalar
from .params import DisturbanceParams, RigParams

N_STATES = 7

# fast-math without the no-NaN/no-inf assumptions, so that the slip check still sees NaN
_FLAGS = {"contract", "arcp", "afn", "reassoc", "nsz"}
# the Polach kernel compiled for this integrator
_creep_force = numba.njit(cache=True, fastmath=_FLAGS)(creep_force_scalar)
_FAST = {"fastmath": _FLAGS, "cache": True}
#: Columns of the per-sample output of :func:`integrate`.
OUT_COLUMNS = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n",
               "fz_n", "wheel_angle_rad", "platform_angle_rad", "creepage")

# indices into the packed parameter vector
(P_RW, P_RP, P_WREF, P_N0, P_JW, P_JM, P_KT, P_CT, P_JP, P_KP, P_KI, P_TRR, P_SX, P_SY, P_MU0,
 P_A, P_B, P_KA, P_KS, P_XIY, P_SLEEP_N, P_SLEEP_A, P_JOINT_N, P_JOINT_A, P_JOINT_W,
 P_JOINT_Z) = range(26)
N_PARAMS = 26


def pack_parameters(rig: RigParams, dist: DisturbanceParams) -> np.ndarray:
    """Flatten the rig and load-disturbance parameters into the vector the kernel reads."""
    c = rig.contact
    on = dist.enabled
    p = np.zeros(N_PARAMS)
    p[P_RW], p[P_RP] = rig.wheel_radius_m, rig.platform_radius_m
    p[P_WREF], p[P_N0] = rig.platform_speed_rad_s, rig.normal_load_n
    p[P_JW], p[P_JM] = rig.wheel_inertia_kg_m2, rig.drive_inertia_kg_m2
    p[P_KT], p[P_CT] = rig.shaft_stiffness_nm_rad, rig.shaft_damping_nm_s_rad
    p[P_JP], p[P_KP], p[P_KI] = (rig.platform_inertia_kg_m2, rig.platform_kp_nm_s_rad,
                                 rig.platform_ki_nm_rad)
    p[P_TRR] = rig.rolling_resistance_nm
    p[P_SX], p[P_SY] = c.stiffness_x_n, c.stiffness_y_n
    p[P_MU0], p[P_A], p[P_B], p[P_KA], p[P_KS] = c.mu0, c.a_ratio, c.b_s_m, c.k_a, c.k_s
    p[P_XIY] = c.lateral_creepage
    p[P_SLEEP_N] = dist.sleeper_count
    p[P_SLEEP_A] = dist.sleeper_load_n if on else 0.0
    p[P_JOINT_N] = max(dist.joint_count, 1)
    p[P_JOINT_A] = dist.joint_load_n if on else 0.0
    wn, z = 2.0 * math.pi * dist.joint_frequency_hz, dist.joint_damping_ratio
    p[P_JOINT_W] = wn * math.sqrt(max(1.0 - z * z, 1e-12))  # damped frequency [rad/s]
    p[P_JOINT_Z] = z * wn  # decay rate [1/s]
    return p


@numba.njit(**_FAST)
def normal_load(th_p: float, p: np.ndarray) -> float:
    """Normal load N [N] at platform angle ``th_p``: spring preload, sleeper passing
    (``sleeper_count`` per revolution) and the decaying response after each rail joint."""
    n = p[P_N0]
    if p[P_SLEEP_A] != 0.0:
        n += p[P_SLEEP_A] * math.sin(p[P_SLEEP_N] * th_p)
    if p[P_JOINT_A] != 0.0:
        pitch = 2.0 * math.pi / p[P_JOINT_N]
        # joints sit half a pitch after angle 0, so a run starting at 0 begins between joints
        phi = (th_p - 0.5 * pitch) % pitch
        t = phi / p[P_WREF]
        n += p[P_JOINT_A] * math.exp(-p[P_JOINT_Z] * t) * math.sin(p[P_JOINT_W] * t)
    return n


@numba.njit(**_FAST)
def _forces(y: np.ndarray, p: np.ndarray):
    v = y[5] * p[P_RP]
    xi_x = (y[2] * p[P_RW] - v) / v
    n = normal_load(y[4], p)
    fx, fy = _creep_force(xi_x, p[P_XIY], n, v, p[P_SX], p[P_SY], p[P_MU0], p[P_A],
                                p[P_B], p[P_KA], p[P_KS])
    return fx, fy, n, xi_x


@numba.njit(**_FAST)
def _deriv(y: np.ndarray, t_m: float, p: np.ndarray, dy: np.ndarray, f: np.ndarray) -> None:
    """Right-hand side at state ``y`` and motor torque ``t_m``; contact values into ``f``
    (Fx, Fy, N, xi_x) so that the caller can record them without recomputing."""
    fx, fy, n, xi = _forces(y, p)
    f[0], f[1], f[2], f[3] = fx, fy, n, xi
    t_sh = p[P_KT] * y[0] + p[P_CT] * (y[1] - y[2])
    err = p[P_WREF] - y[5]
    dy[0] = y[1] - y[2]
    dy[1] = (t_m - t_sh) / p[P_JM]
    dy[2] = (t_sh - p[P_RW] * fx) / p[P_JW]
    dy[3] = y[2]
    dy[4] = y[5]
    dy[5] = (p[P_KP] * err + p[P_KI] * y[6] + p[P_RP] * fx - p[P_TRR]) / p[P_JP]
    dy[6] = err


@numba.njit(**_FAST)
def _motor_torque(t, dc_from, dc_to, t_step, ramp_s, amp, omega, phase, t_gen):
    r = 1.0 if ramp_s <= 0.0 else min(max((t - t_step) / ramp_s, 0.0), 1.0)
    return dc_from + (dc_to - dc_from) * r + amp * math.sin(omega * (t - t_gen) + phase)


@numba.njit(**_FAST)
def integrate(y, t0, n_samples, dt, substeps, p, dc_from, dc_to, t_step, ramp_s, amp, omega,
              phase, t_gen, slip_creepage, out):
    """Advance state ``y`` (modified in place) by ``n_samples`` output samples of ``dt`` [s],
    each split into ``substeps`` classical RK4 steps; write :data:`OUT_COLUMNS` to ``out``.

    Returns ``(n_written, slipped)``: integration stops at the first sample whose creepage
    exceeds ``slip_creepage`` (or is not finite), which counts as wheel slip.
    """
    h = dt / substeps
    k1 = np.empty(N_STATES)
    k2 = np.empty(N_STATES)
    k3 = np.empty(N_STATES)
    k4 = np.empty(N_STATES)
    yt = np.empty(N_STATES)
    f0 = np.empty(4)
    fs = np.empty(4)
    t = t0
    for i in range(n_samples):
        for sub in range(substeps):
            tm0 = _motor_torque(t, dc_from, dc_to, t_step, ramp_s, amp, omega, phase, t_gen)
            _deriv(y, tm0, p, k1, f0)
            if sub == 0:  # record the sample at the start of its interval
                xi = f0[3]
                out[i, 0] = p[P_KT] * y[0] + p[P_CT] * (y[1] - y[2])
                out[i, 1] = y[2]
                out[i, 2] = y[5]
                out[i, 3] = f0[0]
                out[i, 4] = f0[1]
                out[i, 5] = f0[2]
                out[i, 6] = y[3]
                out[i, 7] = y[4]
                out[i, 8] = xi
                if not (xi < slip_creepage) or not math.isfinite(xi):
                    return i + 1, True
            tmh = _motor_torque(t + 0.5 * h, dc_from, dc_to, t_step, ramp_s, amp, omega, phase,
                                t_gen)
            tm1 = _motor_torque(t + h, dc_from, dc_to, t_step, ramp_s, amp, omega, phase, t_gen)
            for j in range(N_STATES):
                yt[j] = y[j] + 0.5 * h * k1[j]
            _deriv(yt, tmh, p, k2, fs)
            for j in range(N_STATES):
                yt[j] = y[j] + 0.5 * h * k2[j]
            _deriv(yt, tmh, p, k3, fs)
            for j in range(N_STATES):
                yt[j] = y[j] + h * k3[j]
            _deriv(yt, tm1, p, k4, fs)
            for j in range(N_STATES):
                y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
            t += h
    return n_samples, False


def initial_state(rig: RigParams, *, creepage: float, dc_torque_nm: float,
                  contact_fx_n: float) -> np.ndarray:
    """State vector in steady rolling at ``creepage`` [-] under ``dc_torque_nm`` [N*m],
    with the traction force ``contact_fx_n`` [N] acting on the platform."""
    y = np.zeros(N_STATES)
    w = rig.speed_m_s * (1.0 + creepage) / rig.wheel_radius_m
    y[0] = dc_torque_nm / rig.shaft_stiffness_nm_rad
    y[1] = y[2] = w
    y[5] = rig.platform_speed_rad_s
    y[6] = (rig.rolling_resistance_nm - rig.platform_radius_m * contact_fx_n) \
        / rig.platform_ki_nm_rad
    return y
