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
    J_p W_p'  = K_p*(W_ref(t) - W_p) + K_i*i_pi + R_p*F_x - T_rr
    W_ref(t)  = W_0 + wobble(t, th_p)       a speed loop's slow oscillation (wobble_table)
    xi_x      = (w_w*R_w - W_p*R_p)/(W_p*R_p)              V-Track paper Eq. (3)
    F_x, F_y  = Polach(xi_x, xi_y, N(th_p), V = W_p*R_p)

The motor torque is ``T_m = T_dc(t) + A*sin(2*pi*f*(t - t_gen) + phi)`` with a DC ramp.

Integration (:func:`integrate`): classical RK4 at a fixed step of ``samples_per_step`` output
samples (default 4, configured in ``[procedure]``); samples inside a step are the cubic
Hermite interpolant of the step's end states and slopes, with the contact forces evaluated
at that state -- exactly at the step's middle sample, and for the other inner samples of an
even block of >= 4 by the cubic through the exact forces half a step before, at the ends and
the middle (to ~1e-6 N; exact at rail joints and in fast transients; see :func:`_integrate`).
The dynamics (and so the phase) never read these recorded forces. The work per step is trimmed
without changing the equations: the modulation sine is rotated from step to step, the normal
load's sines from a per-step anchor (above :func:`_load_near`), the speed reference's wobble
from per-step phasors (:func:`_wob_step`), and the states are kept in registers
(:func:`_rhs_s`).
"""

from __future__ import annotations

import math
import types

import numba
import numpy as np

from torquemod.analysis.contact.polach import creep_force_scalar
from torquemod.twins.vtrack.params import DisturbanceParams, RigParams
from torquemod.twins.vtrack.rig.kernels import FLAGS
from torquemod.twins.vtrack.rig.kernels import cos_small as _cos_small
from torquemod.twins.vtrack.rig.kernels import exp_small as _exp_small
from torquemod.twins.vtrack.rig.kernels import sin_small as _sin_small
from torquemod.twins.vtrack.rig.wobble import (  # noqa: F401 - the wobble's names, re-exported from their old home
    _wob_rev,
    _wob_set,
    _wob_step,
    _wobble,
    wobble_basis,
    wobble_reference,
    wobble_table,
)

N_STATES = 7

_FLAGS = FLAGS


def _renamed(fn, name: str):
    """``fn`` as a new function object called ``name`` (same code and globals)."""
    out = types.FunctionType(fn.__code__, fn.__globals__, name, fn.__defaults__,
                             fn.__closure__)
    out.__qualname__ = name
    out.__doc__ = fn.__doc__
    return out


# the Polach kernel compiled for this integrator (fast-math), under its own name: numba's
# cache tells compiled functions apart by source file, name and argument types, not by the
# compile options, so with polach.creep_force_kernel (no fast-math) both loaded whichever
# had been compiled first into the cache directory -- the twin's values moved by ~1e-13
# with the cache's history
_creep_force = numba.njit(cache=True, fastmath=_FLAGS)(
    _renamed(creep_force_scalar, "creep_force_scalar_fastmath"))
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
    """Flatten the rig and load-disturbance parameters into the vector the kernel reads.

    Parameters
    ----------
    rig : RigParams
        The rig.
    dist : DisturbanceParams
        The disturbances.

    Returns
    -------
    ndarray
        The parameter vector (SI units).
    """
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
    (``sleeper_count`` per revolution) and the decaying response after each rail joint.

    Parameters
    ----------
    th_p : float
        Platform angle [rad].
    p : ndarray
        The parameter vector (:func:`pack_parameters`).

    Returns
    -------
    float
        N [N].
    """
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


# ---- normal load near an anchor angle ---------------------------------------------------
# Within one RK4 step the platform turns by ~1e-4 rad, so every evaluation of the normal load
# in the step is written as its sines and decay at the step's start angle (the "anchor")
# rotated/decayed by the small increment, whose sin, cos and exp are Taylor polynomials
# accurate to rounding for |u| <= _SMALL (:mod:`torquemod.twins.vtrack.rig.kernels`). The anchor
# itself is
# advanced the same way from step to step and evaluated exactly every _ANCHOR_EXACT steps.
# Larger increments, and a rail joint between anchor and angle, fall back to the exact
# :func:`normal_load`.
_SMALL = 0.05
# anchor vector: angle, sin/cos of the sleeper argument, joint phase, joint decay, sin/cos
A_TH, A_SS, A_SC, A_PHI, A_JE, A_JS, A_JC = range(7)
N_ANCHOR = 7


@numba.njit(**_FAST)
def _load_anchor(th_p: float, p: np.ndarray, a: np.ndarray) -> float:
    """Set the anchor ``a`` at ``th_p`` and return the normal load there (= normal_load)."""
    a[A_TH] = th_p
    n = p[P_N0]
    if p[P_SLEEP_A] != 0.0:
        u = p[P_SLEEP_N] * th_p
        a[A_SS] = math.sin(u)
        a[A_SC] = math.cos(u)
        n += p[P_SLEEP_A] * a[A_SS]
    if p[P_JOINT_A] != 0.0:
        pitch = 2.0 * math.pi / p[P_JOINT_N]
        phi = (th_p - 0.5 * pitch) % pitch
        t = phi / p[P_WREF]
        a[A_PHI] = phi
        a[A_JE] = math.exp(-p[P_JOINT_Z] * t)
        a[A_JS] = math.sin(p[P_JOINT_W] * t)
        a[A_JC] = math.cos(p[P_JOINT_W] * t)
        n += p[P_JOINT_A] * a[A_JE] * a[A_JS]
    return n


@numba.njit(**_FAST)
def _load_near(th_p: float, p: np.ndarray, a: np.ndarray) -> float:
    """:func:`normal_load` at ``th_p`` from the anchor ``a`` set nearby (see above)."""
    d = th_p - a[A_TH]
    n = p[P_N0]
    if p[P_SLEEP_A] != 0.0:
        u = p[P_SLEEP_N] * d
        if abs(u) <= _SMALL:
            n += p[P_SLEEP_A] * (a[A_SS] * _cos_small(u) + a[A_SC] * _sin_small(u))
        else:
            n += p[P_SLEEP_A] * math.sin(p[P_SLEEP_N] * th_p)
    if p[P_JOINT_A] != 0.0:
        pitch = 2.0 * math.pi / p[P_JOINT_N]
        phi = a[A_PHI] + d
        tau = d / p[P_WREF]
        x = p[P_JOINT_Z] * tau
        u = p[P_JOINT_W] * tau
        if 0.0 <= phi < pitch and abs(u) <= _SMALL and abs(x) <= _SMALL:
            n += p[P_JOINT_A] * a[A_JE] * _exp_small(-x) * (
                a[A_JS] * _cos_small(u) + a[A_JC] * _sin_small(u))
        else:
            phi = (th_p - 0.5 * pitch) % pitch
            t = phi / p[P_WREF]
            n += p[P_JOINT_A] * math.exp(-p[P_JOINT_Z] * t) * math.sin(p[P_JOINT_W] * t)
    return n


@numba.njit(**_FAST)
def _load_advance(th_p: float, p: np.ndarray, a: np.ndarray, b: np.ndarray, exact: bool
                  ) -> float:
    """Set the anchor ``b`` at ``th_p`` by advancing the anchor ``a`` set nearby (the sines
    rotated, the decay multiplied, as in :func:`_load_near`), or exactly (:func:`_load_anchor`)
    if ``exact``, across a rail joint or for a large increment; return the normal load."""
    if exact:
        return _load_anchor(th_p, p, b)
    d = th_p - a[A_TH]
    sa = p[P_SLEEP_A] != 0.0
    u = p[P_SLEEP_N] * d
    if sa and not abs(u) <= _SMALL:
        return _load_anchor(th_p, p, b)
    ja = p[P_JOINT_A] != 0.0
    phi = a[A_PHI] + d
    tau = d / p[P_WREF]
    x = p[P_JOINT_Z] * tau
    v = p[P_JOINT_W] * tau
    if ja and not (0.0 <= phi < 2.0 * math.pi / p[P_JOINT_N] and abs(v) <= _SMALL
                   and abs(x) <= _SMALL):
        return _load_anchor(th_p, p, b)
    b[A_TH] = th_p
    n = p[P_N0]
    if sa:
        cu, su = _cos_small(u), _sin_small(u)
        b[A_SS] = a[A_SS] * cu + a[A_SC] * su
        b[A_SC] = a[A_SC] * cu - a[A_SS] * su
        n += p[P_SLEEP_A] * b[A_SS]
    if ja:
        cv, sv = _cos_small(v), _sin_small(v)
        b[A_PHI] = phi
        b[A_JE] = a[A_JE] * _exp_small(-x)
        b[A_JS] = a[A_JS] * cv + a[A_JC] * sv
        b[A_JC] = a[A_JC] * cv - a[A_JS] * sv
        n += p[P_JOINT_A] * b[A_JE] * b[A_JS]
    return n


#: RK4 steps between exact evaluations of the load anchor (advanced by rotation in between)
_ANCHOR_EXACT = 64


@numba.njit(**_FAST)
def _rhs(y: np.ndarray, t_m: float, n: float, p: np.ndarray, dy: np.ndarray):
    """Right-hand side at state ``y``, motor torque ``t_m`` and normal load ``n`` into ``dy``;
    returns the contact values (Fx, Fy, xi_x) so that the caller can record them."""
    v = y[5] * p[P_RP]
    xi = (y[2] * p[P_RW] - v) / v
    fx, fy = _creep_force(xi, p[P_XIY], n, v, p[P_SX], p[P_SY], p[P_MU0], p[P_A], p[P_B],
                          p[P_KA], p[P_KS])
    t_sh = p[P_KT] * y[0] + p[P_CT] * (y[1] - y[2])
    err = p[P_WREF] - y[5]
    dy[0] = y[1] - y[2]
    dy[1] = (t_m - t_sh) / p[P_JM]
    dy[2] = (t_sh - p[P_RW] * fx) / p[P_JW]
    dy[3] = y[2]
    dy[4] = y[5]
    dy[5] = (p[P_KP] * err + p[P_KI] * y[6] + p[P_RP] * fx - p[P_TRR]) / p[P_JP]
    dy[6] = err
    return fx, fy, xi


@numba.njit(**_FAST)
def _deriv(y: np.ndarray, t_m: float, p: np.ndarray, dy: np.ndarray, f: np.ndarray) -> None:
    """Right-hand side at state ``y`` and motor torque ``t_m`` into ``dy``, contact values
    (Fx, Fy, N, xi_x) into ``f`` -- the plain form of what :func:`integrate` evaluates."""
    n = normal_load(y[4], p)
    fx, fy, xi = _rhs(y, t_m, n, p, dy)
    f[0], f[1], f[2], f[3] = fx, fy, n, xi


@numba.njit(**_FAST)
def _ramp(t, dc_from, dc_to, t_step, ramp_s):
    r = 1.0 if ramp_s <= 0.0 else min(max((t - t_step) / ramp_s, 0.0), 1.0)
    return dc_from + (dc_to - dc_from) * r


@numba.njit(**_FAST)
def _rhs_s(y0, y1, y2, y5, y6, t_m, n, c, dw=0.0):
    """:func:`_rhs` on scalars (the states the right-hand side reads; ``th_w' = w_w`` and
    ``th_p' = W_p`` need no evaluation) with the constants ``c`` of :func:`_constants` and the
    speed reference's wobble ``dw`` [rad/s] (:func:`_wobble`).
    Returns the derivatives of ``twist, w_m, w_w, W_p, i_pi`` and ``(Fx, Fy, xi_x)``."""
    rw, rp, wref, ijm, ijw, ijp, kt, ct, kp, ki, trr, xiy, sx, sy, mu0, a, b, ka, ks = c
    v = y5 * rp
    xi = (y2 * rw - v) / v
    fx, fy = _creep_force(xi, xiy, n, v, sx, sy, mu0, a, b, ka, ks)
    t_sh = kt * y0 + ct * (y1 - y2)
    err = wref + dw - y5
    return (y1 - y2, (t_m - t_sh) * ijm, (t_sh - rw * fx) * ijw,
            (kp * err + ki * y6 + rp * fx - trr) * ijp, err, fx, fy, xi)


@numba.njit(**_FAST)
def _constants(p):
    return (p[P_RW], p[P_RP], p[P_WREF], 1.0 / p[P_JM], 1.0 / p[P_JW], 1.0 / p[P_JP], p[P_KT],
            p[P_CT], p[P_KP], p[P_KI], p[P_TRR], p[P_XIY], p[P_SX], p[P_SY], p[P_MU0], p[P_A],
            p[P_B], p[P_KA], p[P_KS])


@numba.njit(**_FAST)
def _put(out, i, kt, ct, y0, y1, y2, y3, y4, y5, fx, fy, n, xi):
    out[i, 0] = kt * y0 + ct * (y1 - y2)
    out[i, 1] = y2
    out[i, 2] = y5
    out[i, 3] = fx
    out[i, 4] = fy
    out[i, 5] = n
    out[i, 6] = y3
    out[i, 7] = y4
    out[i, 8] = xi


@numba.njit(**_FAST)
def _hermite(th, h, y0, y1, y2, y3, y4, y5, y6, a0, a1, a2, a5, a6, z0, z1, z2, z3, z4, z5, z6,
             e0, e1, e2, e5, e6):
    """Cubic Hermite interpolant at ``th`` (fraction of the step ``h``) of the states ``y``
    (slopes ``a``; ``th_w' = w_w``, ``th_p' = W_p``) at the step's start and ``z`` (slopes
    ``e``) at its end."""
    r = 1.0 - th
    w00 = (1.0 + 2.0 * th) * r * r
    w10 = th * r * r * h
    w01 = th * th * (3.0 - 2.0 * th)
    w11 = -th * th * r * h
    return (w00 * y0 + w10 * a0 + w01 * z0 + w11 * e0,
            w00 * y1 + w10 * a1 + w01 * z1 + w11 * e1,
            w00 * y2 + w10 * a2 + w01 * z2 + w11 * e2,
            w00 * y3 + w10 * y2 + w01 * z3 + w11 * z2,
            w00 * y4 + w10 * y5 + w01 * z4 + w11 * z5,
            w00 * y5 + w10 * a5 + w01 * z5 + w11 * e5,
            w00 * y6 + w10 * a6 + w01 * z6 + w11 * e6)


#: largest miss of the quadratic at the step's middle, relative to the normal load, for which
#: the inner samples take the contact from the cubic (1e-3 N at 4200 N: 99.9 % of the steps
#: of the default experiment, whose misses stay below 2e-4 N; 0.6 N after a start off
#: equilibrium)
_CUBIC_MISS = 2.5e-7


@numba.njit(**_FAST)
def _cubic_weights(th):
    """Lagrange weights at ``th`` of the nodes -1/2, 0, 1/2, 1 (fractions of a step)."""
    a, b, c, d = th + 0.5, th, th - 0.5, th - 1.0
    return b * c * d / -0.75, a * c * d / 0.25, a * b * d / -0.25, a * b * c / 0.75


#: RK4 steps between exact re-evaluations of the modulation's sine (rotated in between)
_RESYNC = 1024


_NO_WOBBLE = np.zeros((0, 4))


def integrate(y, t0, n_samples, dt, substeps, p, dc_from, dc_to, t_step, ramp_s, amp, omega,
              phase, t_gen, slip_creepage, out, samples_per_step=1, wobble=None):
    """:func:`_integrate` (compiled) with the platform speed reference's ``wobble`` table of
    :func:`wobble_table` (None: a steady reference).

    Parameters
    ----------
    y : ndarray
        The state at ``t0``.
    t0 : float
        Start time [s].
    n_samples : int
        Output samples [-].
    dt : float
        Sample interval [s].
    substeps : int
        RK4 steps per ``samples_per_step`` samples [-].
    p : ndarray
        The parameter vector (:func:`pack_parameters`).
    dc_from : float
        DC torque before the ramp [N*m].
    dc_to : float
        DC torque after the ramp [N*m].
    t_step : float
        Start of the ramp [s].
    ramp_s : float
        Ramp time [s].
    amp : float
        Modulation amplitude [N*m].
    omega : float
        Modulation angular frequency [rad/s].
    phase : float
        Generator phase [rad].
    t_gen : float
        Generator time origin [s].
    slip_creepage : float
        Creepage at which the integration stops as slipped [-].
    out : ndarray
        Output rows (:data:`OUT_COLUMNS`), written in place.
    samples_per_step : int
        Output samples per integration step [-]. Default 1.
    wobble : ndarray or None
        The wobble rows; None: a steady reference.

    Returns
    -------
    n_written : int
        Samples written; integration stops at the first sample whose creepage exceeds
        ``slip_creepage``.
    slipped : bool
        Whether it stopped so.
    """
    wob = _NO_WOBBLE if wobble is None else np.ascontiguousarray(wobble, dtype=np.float64)
    return _integrate(y, t0, n_samples, dt, substeps, p, dc_from, dc_to, t_step, ramp_s, amp,
                      omega, phase, t_gen, slip_creepage, out, samples_per_step, wob)


# nogil: simulate's pipeline integrates the next step while a worker thread finishes the last
@numba.njit(nogil=True, **_FAST)
def _integrate(y, t0, n_samples, dt, substeps, p, dc_from, dc_to, t_step, ramp_s, amp, omega,
               phase, t_gen, slip_creepage, out, samples_per_step, wob):
    """Advance state ``y`` (modified in place) by ``n_samples`` output samples of ``dt`` [s]
    and write :data:`OUT_COLUMNS` to ``out`` (sample ``i`` is the state at ``t0 + i*dt``).

    The time axis is cut into blocks of ``samples_per_step`` samples, each integrated by
    ``substeps`` classical RK4 steps (step ``h = samples_per_step*dt/substeps``; a shorter
    last block takes the remaining samples). A sample that falls inside an RK4 step is the
    cubic Hermite interpolant of the step's end states and derivatives (error O(h^4), as
    the method's), with the contact forces evaluated at that interpolated state.
    ``samples_per_step = substeps = 1`` is one RK4 step per sample.

    Returns ``(n_written, slipped)``: integration stops at the first sample whose creepage
    exceeds ``slip_creepage`` (or is not finite), which counts as wheel slip; ``y`` is then
    the state of that sample.
    """
    m = samples_per_step
    s_n = substeps
    c = _constants(p)
    kt, ct = p[P_KT], p[P_CT]
    anc = np.zeros(N_ANCHOR)
    anc_n = np.zeros(N_ANCHOR)
    # the modulation sin(omega*(t - t_gen) + phase) by rotation between exact re-evaluations
    use_mod = amp != 0.0
    ang0 = omega * (t0 - t_gen) + phase
    ms, mc = math.sin(ang0), math.cos(ang0)
    y0, y1, y2, y3, y4, y5, y6 = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
    # the speed reference's wobble: each row's phasor at the step start (rotated from step to
    # step, exact every _RESYNC steps), a cubic in the step's time and angle increments
    nw = wob.shape[0]
    use_wob = nw > 0
    ws, wc, wrc, wrs, wsum = np.zeros(nw), np.zeros(nw), np.ones(nw), np.zeros(nw), np.zeros(6)
    _wob_set(t0, y4, wob, ws, wc)
    dth = 0.0  # platform angle advanced in the last step [rad]
    # derivative and contact at the first sample
    n0 = _load_anchor(y4, p, anc)
    tm = _ramp(t0, dc_from, dc_to, t_step, ramp_s) + amp * ms
    a0, a1, a2, a5, a6, fx0, fy0, xi0 = _rhs_s(y0, y1, y2, y5, y6, tm, n0, c,
                                               _wobble(t0, y4, wob))
    i = 0
    h_prev = -1.0
    # the contact at the middle of the step before (the cubic of the inner samples)
    have_pm = False
    fx_pm = fy_pm = n_pm = th_pm = 0.0
    joint_pitch = 2.0 * math.pi / p[P_JOINT_N]
    rc = rs = 1.0
    n_steps = 0
    while i < n_samples:
        mb = min(m, n_samples - i)  # samples in this block
        hb = mb * dt / s_n
        if hb != h_prev:  # rotation of the modulation phase by half a step
            h_prev = hb
            rc, rs = math.cos(0.5 * omega * hb), math.sin(0.5 * omega * hb)
            for j in range(nw):
                wrc[j], wrs[j] = math.cos(0.5 * wob[j, 1] * hb), math.sin(0.5 * wob[j, 1] * hb)
        tb = t0 + i * dt
        hh = 0.5 * hb
        for jj in range(s_n):
            ta = tb + jj * hb
            # the sample at the start of this RK step, if any
            if (jj * mb) % s_n == 0:
                k = i + (jj * mb) // s_n
                _put(out, k, kt, ct, y0, y1, y2, y3, y4, y5, fx0, fy0, n0, xi0)
                if not (xi0 < slip_creepage) or not math.isfinite(xi0):
                    y[0], y[1], y[2], y[3], y[4], y[5], y[6] = y0, y1, y2, y3, y4, y5, y6
                    return k + 1, True
            # modulation at ta + h/2 and ta + h
            if use_mod:
                hs = ms * rc + mc * rs
                hc = mc * rc - ms * rs
                es = hs * rc + hc * rs
                ec = hc * rc - hs * rs
                if n_steps % _RESYNC == 0:
                    ang = omega * (ta + hb - t_gen) + phase
                    es, ec = math.sin(ang), math.cos(ang)
                else:
                    g = 1.5 - 0.5 * (es * es + ec * ec)  # keep on the unit circle
                    es *= g
                    ec *= g
            else:
                hs = es = 0.0
                ec = 1.0
            # wobble: time part at ta + h/2 and ta + h, angle part per stage (below)
            if use_wob:
                if n_steps % _RESYNC == 0:
                    _wob_set(ta, y4, wob, ws, wc)
                    dth = 0.0
                _wob_step(wob, ws, wc, wrc, wrs, dth, wsum)
            wth, wt1 = wsum[0], wsum[1]
            n_steps += 1
            tmh = _ramp(ta + hh, dc_from, dc_to, t_step, ramp_s) + amp * hs
            tm1 = _ramp(ta + hb, dc_from, dc_to, t_step, ramp_s) + amp * es
            # classical RK4; k_i = (b0, b1, b2, w_w, W_p, b5, b6) of stage i
            s2, s5 = y2 + hh * a2, y5 + hh * a5
            s4 = y4 + hh * y5
            dw = (wth + _wob_rev(wsum, hh * y5)) if use_wob else 0.0
            b0, b1, b2, b5, b6, _, _, _ = _rhs_s(y0 + hh * a0, y1 + hh * a1, s2, s5,
                                                 y6 + hh * a6, tmh, _load_near(s4, p, anc), c,
                                                 dw)
            u2, u5 = y2 + hh * b2, y5 + hh * b5
            u4 = y4 + hh * s5
            dw = (wth + _wob_rev(wsum, hh * s5)) if use_wob else 0.0
            c0, c1, c2, c5, c6, _, _, _ = _rhs_s(y0 + hh * b0, y1 + hh * b1, u2, u5,
                                                 y6 + hh * b6, tmh, _load_near(u4, p, anc), c,
                                                 dw)
            v2, v5 = y2 + hb * c2, y5 + hb * c5
            v4 = y4 + hb * u5
            dw = (wt1 + _wob_rev(wsum, hb * u5)) if use_wob else 0.0
            d0, d1, d2, d5, d6, _, _, _ = _rhs_s(y0 + hb * c0, y1 + hb * c1, v2, v5,
                                                 y6 + hb * c6, tm1, _load_near(v4, p, anc), c,
                                                 dw)
            h6 = hb / 6.0
            z0 = y0 + h6 * (a0 + 2.0 * (b0 + c0) + d0)
            z1 = y1 + h6 * (a1 + 2.0 * (b1 + c1) + d1)
            z2 = y2 + h6 * (a2 + 2.0 * (b2 + c2) + d2)
            z3 = y3 + h6 * (y2 + 2.0 * (s2 + u2) + v2)
            z4 = y4 + h6 * (y5 + 2.0 * (s5 + u5) + v5)
            z5 = y5 + h6 * (a5 + 2.0 * (b5 + c5) + d5)
            z6 = y6 + h6 * (a6 + 2.0 * (b6 + c6) + d6)
            # derivative at the step's end: the next step's k1 and the interpolation's slope
            nn = _load_advance(z4, p, anc, anc_n, n_steps % _ANCHOR_EXACT == 0)
            dth = z4 - y4
            dw = (wt1 + _wob_rev(wsum, dth)) if use_wob else 0.0
            e0, e1, e2, e5, e6, fxn, fyn, xin = _rhs_s(z0, z1, z2, z5, z6, tm1, nn, c, dw)
            # samples strictly inside this step: the states by cubic Hermite interpolation
            # (_hermite). Whole blocks of an even number m >= 4 of samples per RK4 step
            # evaluate the contact exactly at the middle sample only; the others take Fx,
            # Fy and N from the cubic through the exact values half a step before the
            # step, at its ends and at its middle (_cubic_weights) unless a rail joint (a
            # kink in N) lies in that span. Error ~ 2e-3*(w*h)^4 of a line at w: 3e-8 of
            # the 40 Hz joint bounce at h = 4/16670 s (measured: 4e-8 N median, 1e-6 N
            # at 99.9 %, up to 3e-6 N after a joint in the default experiment).
            cub_step = s_n == 1 and mb == m and m >= 4 and m % 2 == 0
            if cub_step:
                mid = mb // 2
                p0, p1, p2, p3, p4, p5, p6 = _hermite(0.5, hb, y0, y1, y2, y3, y4, y5, y6,
                                                      a0, a1, a2, a5, a6, z0, z1, z2, z3,
                                                      z4, z5, z6, e0, e1, e2, e5, e6)
                n_mid = _load_near(p4, p, anc)
                v = p5 * c[1]
                xi_mid = (p2 * c[0] - v) / v
                fx_mid, fy_mid = _creep_force(xi_mid, c[11], n_mid, v, c[12], c[13], c[14],
                                              c[15], c[16], c[17], c[18])
                # ... and while the force is smooth on the step's scale: the quadratic
                # through the other three nodes misses the middle by ~h^3/16 times the third
                # derivative of Fx, which a fast transient (the platform loop's 0.3 ms mode
                # after a start off equilibrium) drives far above its steady ~1e-4 N
                miss = fx_mid - (fx0 + (fxn - fx_pm) / 3.0)
                use_cub = have_pm and abs(miss) <= _CUBIC_MISS * abs(n_mid)
                if use_cub and p[P_JOINT_A] != 0.0:
                    # no joint between half a step before and the step's end
                    ph = anc[A_PHI]
                    use_cub = ph - (y4 - th_pm) >= 0.0 and ph + (z4 - y4) < joint_pitch
            for k in range(mb):
                q = k * s_n - jj * mb
                if 0 < q < mb:
                    if cub_step and q == mid:
                        q0, q1, q2, q3, q4, q5, q6 = p0, p1, p2, p3, p4, p5, p6
                        ni, xi, fx, fy = n_mid, xi_mid, fx_mid, fy_mid
                    else:
                        th = q / mb
                        q0, q1, q2, q3, q4, q5, q6 = _hermite(
                            th, hb, y0, y1, y2, y3, y4, y5, y6, a0, a1, a2, a5, a6, z0, z1,
                            z2, z3, z4, z5, z6, e0, e1, e2, e5, e6)
                        v = q5 * c[1]
                        xi = (q2 * c[0] - v) / v
                        if cub_step and use_cub:
                            l0, l1, l2, l3 = _cubic_weights(th)
                            fx = l0 * fx_pm + l1 * fx0 + l2 * fx_mid + l3 * fxn
                            fy = l0 * fy_pm + l1 * fy0 + l2 * fy_mid + l3 * fyn
                            ni = l0 * n_pm + l1 * n0 + l2 * n_mid + l3 * nn
                        else:
                            ni = _load_near(q4, p, anc)
                            fx, fy = _creep_force(xi, c[11], ni, v, c[12], c[13], c[14],
                                                  c[15], c[16], c[17], c[18])
                    _put(out, i + k, kt, ct, q0, q1, q2, q3, q4, q5, fx, fy, ni, xi)
                    if not (xi < slip_creepage) or not math.isfinite(xi):
                        y[0], y[1], y[2], y[3], y[4], y[5], y[6] = q0, q1, q2, q3, q4, q5, q6
                        return i + k + 1, True
            have_pm = cub_step
            if cub_step:
                fx_pm, fy_pm, n_pm, th_pm = fx_mid, fy_mid, n_mid, p4
            y0, y1, y2, y3, y4, y5, y6 = z0, z1, z2, z3, z4, z5, z6
            a0, a1, a2, a5, a6 = e0, e1, e2, e5, e6
            for j in range(N_ANCHOR):
                anc[j] = anc_n[j]
            fx0, fy0, n0, xi0 = fxn, fyn, nn, xin
            ms, mc = es, ec
        i += mb
    y[0], y[1], y[2], y[3], y[4], y[5], y[6] = y0, y1, y2, y3, y4, y5, y6
    return n_samples, False


def initial_state(rig: RigParams, *, creepage: float, dc_torque_nm: float,
                  contact_fx_n: float) -> np.ndarray:
    """State vector in steady rolling.

    Parameters
    ----------
    rig : RigParams
        The rig.
    creepage : float
        Creepage [-].
    dc_torque_nm : float
        DC torque [N*m].
    contact_fx_n : float
        Traction force acting on the platform [N].

    Returns
    -------
    ndarray
        The state.
    """
    y = np.zeros(N_STATES)
    w = rig.speed_m_s * (1.0 + creepage) / rig.wheel_radius_m
    y[0] = dc_torque_nm / rig.shaft_stiffness_nm_rad
    y[1] = y[2] = w
    y[5] = rig.platform_speed_rad_s
    y[6] = (rig.rolling_resistance_nm - rig.platform_radius_m * contact_fx_n) \
        / rig.platform_ki_nm_rad
    return y
