"""Equations of motion of the train twin and their fixed-step RK4 integrator (numba).

States (rotations referred to the axle):

==========  ==========================================================  =========
``twist``   torsion of the compliant coupling, motor side minus axle     [rad]
``w_m``     motor (rotor, pinion) speed                                  [rad/s]
``w_w``     wheelset speed                                               [rad/s]
``v``       vehicle speed                                                [m/s]
``x``       position along the track                                     [m]
``t_a``     motor (air-gap) torque                                       [N*m]
==========  ==========================================================  =========

Equations (derived for this model; quasi-static Polach contact, Polach 2005)::

    T_c      = k_c*twist + c_c*(w_m - w_w)                 coupling torque
    J_m w_m' = t_a - T_c                                    motor side
    J_w w_w' = T_c - R*F                                    wheelset
    M v'     = F + F_o - (a + b*v + c*v^2)                  vehicle share (Davis)
    x'       = v
    tau t_a' = g*T_dc + A*sin(2*pi*f*t) - t_a               current-loop lag
    xi       = (w_w*R - v)/max(v, V_MIN)
    F        = Polach(xi, N(x), v; mu0, A, B, kA, kS at x)  creep force of the axle

``N(x) = N0*(1 + sum_k a_k*sin(2*pi*x/lambda_k + p_k))`` (track irregularity). The friction
parameters blend linearly over a transition of ``transition_m`` centred on each segment start.
The driver's demand ``T_dc``, the other axles' force ``F_o`` and the anti-slip factor ``g``
are set once per output sample (the controller's cycle) by :func:`_control`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.analysis.contact.polach import creep_force_scalar

_creep = numba.njit(cache=True)(creep_force_scalar)
V_MIN = 0.5  # [m/s] creepage reference floor (standstill)

#: Columns of the per-sample output of :func:`integrate`.
OUT = ("time_s", "motor_torque_nm", "wheel_speed_rad_s", "motor_speed_rad_s", "speed_m_s",
       "position_m", "creep_force_n", "normal_load_n", "creepage", "friction", "antislip",
       "dc_torque_nm", "segment")
N_OUT = len(OUT)
MODES = {"torque": 0, "speed": 1, "coast": 2, "probe": 3}
(P_R, P_JM, P_JW, P_KC, P_CC, P_M, P_DA, P_DB, P_DC, P_TAU, P_N0, P_SX, P_AMP, P_OMEGA,
 P_TRANS, P_KP, P_AS_XI, P_AS_CUT, P_AS_FLOOR, P_AS_REST) = range(20)
N_PAR = 20


@numba.njit(cache=True)
def _segment(x, starts):
    j = 0
    while j + 1 < starts.size and x >= starts[j + 1]:
        j += 1
    return j


@numba.njit(cache=True)
def _blend(x, starts, table, trans, q):
    """Parameter ``q`` of ``table`` at ``x``, blended linearly across ``trans`` [m]."""
    j = _segment(x, starts)
    half = 0.5 * trans
    if half > 0.0:
        if j + 1 < starts.size and x > starts[j + 1] - half:  # entering the next segment
            w = (x - (starts[j + 1] - half)) / trans
            return (1.0 - w) * table[j, q] + w * table[j + 1, q]
        if j > 0 and x < starts[j] + half:  # still leaving the previous one
            w = (x - (starts[j] - half)) / trans
            return (1.0 - w) * table[j - 1, q] + w * table[j, q]
    return table[j, q]


def friction_params(x, starts, table, trans):
    """(mu0, A, B, kA, kS) [array of 5] and the segment index at position ``x`` [m]: each
    parameter blended linearly across ``trans`` [m] centred on a segment start.

    Parameters
    ----------
    x : float
        Position [m].
    starts : ndarray
        Segment starts [m].
    table : ndarray
        (segments, 5) Polach parameters (mu0 [-], A [-], B [s/m], kA [-], kS [-]).
    trans : float
        Transition length [m].

    Returns
    -------
    params : ndarray
        The five parameters at ``x``.
    segment : int
        The segment index.
    """
    return (np.array([_blend(x, starts, table, trans, q) for q in range(5)]),
            _segment(x, starts))


@numba.njit(cache=True)
def normal_load(x, p, irr):
    """Axle load [N] at ``x`` [m]: ``irr`` rows (amplitude [-], wavenumber [rad/m], phase).

    Parameters
    ----------
    x : float
        Position [m].
    p : ndarray
        The parameter vector.
    irr : ndarray
        Irregularity rows.

    Returns
    -------
    float
        Axle load [N].
    """
    s = 0.0
    for k in range(irr.shape[0]):
        s += irr[k, 0] * math.sin(irr[k, 1] * x + irr[k, 2])
    return p[P_N0] * (1.0 + s)


@numba.njit(cache=True)
def _rhs(y, t, tdc, f_o, p, starts, table, irr, dy):
    twist, wm, ww, v, x, ta = y[0], y[1], y[2], y[3], y[4], y[5]
    r = p[P_R]
    tc = p[P_KC] * twist + p[P_CC] * (wm - ww)
    vr = max(v, V_MIN)
    xi = (ww * r - v) / vr
    tr = p[P_TRANS]
    mu0, a_r, b_r = (_blend(x, starts, table, tr, 0), _blend(x, starts, table, tr, 1),
                     _blend(x, starts, table, tr, 2))
    n = normal_load(x, p, irr)
    f, _ = _creep(xi, 0.0, n, v, p[P_SX], p[P_SX], mu0, a_r, b_r,
                  _blend(x, starts, table, tr, 3), _blend(x, starts, table, tr, 4))
    dy[0] = wm - ww
    dy[1] = (ta - tc) / p[P_JM]
    dy[2] = (tc - r * f) / p[P_JW]
    dy[3] = (f + f_o - (p[P_DA] + p[P_DB] * v + p[P_DC] * v * v)) / p[P_M]
    dy[4] = v
    dy[5] = (tdc + p[P_AMP] * math.sin(p[P_OMEGA] * t) - ta) / p[P_TAU]
    return f, n, xi, mu0 * ((1.0 - a_r) * math.exp(-b_r * abs(xi) * v) + a_r)


@numba.njit(cache=True)
def _control(y, p, leg_until, leg_mode, leg_val, leg_others, leg_step, levels, n_levels,
             seg_peak, seg, v_hold):
    """DC torque demand [N*m] and the other axles' force [N] for the current leg."""
    x, v = y[4], y[3]
    r = p[P_R]
    j = 0
    while j + 1 < leg_until.size and x >= leg_until[j]:
        j += 1
    mode = leg_mode[j]
    res = p[P_DA] + p[P_DB] * v + p[P_DC] * v * v
    if mode == 0:
        return leg_val[j], leg_others[j], j
    if mode == 1:
        return r * (res + p[P_KP] * (leg_val[j] - v)), 0.0, j
    if mode == 2:
        return 0.0, 0.0, j
    start = leg_until[j - 1] if j > 0 else 0.0
    k = int((x - start) // leg_step[j]) % max(n_levels[j], 1)
    tdc = levels[j, k] * seg_peak[seg] * p[P_N0] * r
    return tdc, res - tdc / r + p[P_KP] * (v_hold - v), j


@numba.njit(cache=True)
def integrate(y, n_samples, dt, substeps, p, starts, table, irr, leg_until, leg_mode,
              leg_val, leg_others, leg_step, levels, n_levels, seg_peak, out, t0=0.0):
    """Advance ``y`` (in place) by ``n_samples`` samples of ``dt`` [s], ``substeps`` RK4
    steps each, writing :data:`OUT` per sample (the state at the sample's start).

    Parameters
    ----------
    y : ndarray
        The state, advanced in place.
    n_samples : int
        Samples [-].
    dt : float
        Sample interval [s].
    substeps : int
        RK4 steps per sample [-].
    p : ndarray
        The parameter vector.
    starts, table : ndarray
        The friction map (:func:`friction_params`).
    irr : ndarray
        Irregularity rows.
    leg_until, leg_mode, leg_val, leg_others, leg_step : ndarray
        The driver's legs: end [m], mode, value, the other axles' force [N], probe step [m].
    levels : ndarray
        Probe levels [-].
    n_levels : ndarray
        Levels per leg.
    seg_peak : ndarray
        Available adhesion per segment [-].
    out : ndarray
        Output rows (:data:`OUT`).
    t0 : float
        Time of the first sample [s]. Default 0.

    Returns
    -------
    int
        Samples written (fewer when the integration stopped).
    """
    dy = np.zeros(6)
    k1 = np.zeros(6)
    k2 = np.zeros(6)
    k3 = np.zeros(6)
    k4 = np.zeros(6)
    yt = np.zeros(6)
    h = dt / substeps
    g = 1.0
    last_leg = -1
    v_hold = y[3]
    for i in range(n_samples):
        t = t0 + i * dt
        seg = _segment(y[4], starts)
        tdc, f_o, leg = _control(y, p, leg_until, leg_mode, leg_val, leg_others, leg_step,
                                 levels, n_levels, seg_peak, seg, v_hold)
        if leg != last_leg:
            last_leg = leg
            v_hold = y[3]
        f, n, xi, mu = _rhs(y, t, g * tdc, f_o, p, starts, table, irr, dy)
        # anti-slip: cut the torque while the creepage exceeds the limit (either sign)
        if abs(xi) > p[P_AS_XI]:
            g = max(p[P_AS_FLOOR], g - p[P_AS_CUT] * dt)
        elif abs(xi) < 0.5 * p[P_AS_XI]:
            g = min(1.0, g + p[P_AS_REST] * dt)
        row = out[i]
        row[0], row[1], row[2], row[3], row[4], row[5] = t, y[5], y[2], y[1], y[3], y[4]
        row[6], row[7], row[8], row[9], row[10], row[11], row[12] = f, n, xi, mu, g, tdc, seg
        tdc_g = g * tdc
        for s in range(substeps):
            ts = t + s * h
            _rhs(y, ts, tdc_g, f_o, p, starts, table, irr, k1)
            for q in range(6):
                yt[q] = y[q] + 0.5 * h * k1[q]
            _rhs(yt, ts + 0.5 * h, tdc_g, f_o, p, starts, table, irr, k2)
            for q in range(6):
                yt[q] = y[q] + 0.5 * h * k2[q]
            _rhs(yt, ts + 0.5 * h, tdc_g, f_o, p, starts, table, irr, k3)
            for q in range(6):
                yt[q] = y[q] + h * k3[q]
            _rhs(yt, ts + h, tdc_g, f_o, p, starts, table, irr, k4)
            for q in range(6):
                y[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
        if not math.isfinite(y[2]):
            return i + 1
    return n_samples


def static_coa(xi, speed_m_s, normal_load_n, stiffness_x_n, mu0, a_ratio, b_s_m, k_a, k_s):
    """CoA [-] of the Polach curve (Polach 2005 Eqs. 1-9, longitudinal creepage only; the
    vectorised twin of :func:`~torquemod.analysis.contact.polach.creep_force_scalar`),
    broadcasting.

    Parameters
    ----------
    xi : float or array_like
        Longitudinal creepage [-].
    speed_m_s : float or array_like
        Rolling speed [m/s].
    normal_load_n : float or array_like
        Normal load Q [N].
    stiffness_x_n : float or array_like
        Lumped contact stiffness ``pi*G*a*b*c11/4`` [N].
    mu0 : float or array_like
        Friction at zero slip velocity [-].
    a_ratio : float or array_like
        A [-].
    b_s_m : float or array_like
        B [s/m].
    k_a, k_s : float or array_like
        Reduction factors [-].

    Returns
    -------
    ndarray
        CoA [-].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (1)-(9).
    """
    xi = np.asarray(xi, dtype=float)
    mu = mu0 * ((1.0 - a_ratio) * np.exp(-b_s_m * np.abs(xi) * speed_m_s) + a_ratio)
    eps = stiffness_x_n * np.abs(xi) / (normal_load_n * mu)
    ke = k_a * eps
    return np.sign(xi) * mu * (2.0 / np.pi) * (ke / (1.0 + ke * ke) + np.arctan(k_s * eps))


def adhesion_peak(speed_m_s, normal_load_n, stiffness_x_n, mu0, a_ratio, b_s_m, k_a, k_s,
                  *, n_grid: int = 400):
    """Peak CoA [-] of :func:`static_coa` over the creepage and the creepage at the peak,
    per element of the broadcast arguments (log grid 1e-5..0.3, parabolic refinement in
    log creepage: relative error < 1e-5 of the peak).

    Parameters
    ----------
    speed_m_s : float or array_like
        Rolling speed [m/s].
    normal_load_n : float or array_like
        Normal load [N].
    stiffness_x_n : float or array_like
        Lumped contact stiffness [N].
    mu0 : float or array_like
        Friction at zero slip velocity [-].
    a_ratio : float or array_like
        A [-].
    b_s_m : float or array_like
        B [s/m].
    k_a, k_s : float or array_like
        Reduction factors [-].
    n_grid : int
        Grid points [-]. Default 400.

    Returns
    -------
    peak : ndarray
        Peak CoA [-].
    xi_peak : ndarray
        Creepage at the peak [-].
    """
    args = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in
                                 (speed_m_s, normal_load_n, stiffness_x_n, mu0, a_ratio,
                                  b_s_m, k_a, k_s)))
    shape = args[0].shape
    flat = [a.reshape(-1, 1) for a in args]
    lx = np.linspace(np.log(1e-5), np.log(0.3), n_grid)
    coa = static_coa(np.exp(lx)[None, :], *flat)
    j = np.clip(np.argmax(coa, axis=1), 1, n_grid - 2)
    r = np.arange(coa.shape[0])
    a, b, c = coa[r, j - 1], coa[r, j], coa[r, j + 1]
    den = a - 2 * b + c
    ok = den < 0
    d = np.where(ok, 0.5 * (a - c) / np.where(ok, den, -1.0), 0.0)
    peak = np.where(ok, b - 0.25 * (a - c) * d, b)
    xi_peak = np.exp(lx[j] + d * (lx[1] - lx[0]))
    return peak.reshape(shape), xi_peak.reshape(shape)
