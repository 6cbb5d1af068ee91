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

Integration (:mod:`torquemod.twins.vtrack.rig.lanes`): classical RK4 at a fixed step of
``samples_per_step`` output samples (default 12, configured in ``[procedure]``), the platform
speed ``W_p`` by the exponential RK4 of Krogstad (2005) with its linear rate ``-K_p/J_p``
taken exactly (the PI loop's stiff mode, ~3300 1/s on the default rig, bounds no step);
samples inside
a step are the cubic Hermite interpolant of the step's end states and slopes, with the contact
forces evaluated at that state -- exactly at the step's middle sample, and for the other inner
samples of an even block of >= 4 by the cubic through the exact forces half a step before, at
the ends and the middle (to ~1e-6 N at 4 samples, ~1e-3 N at the default 12 -- the error grows
as h^4 through a rail joint's ringing; exact at rail joints and in fast transients; see
:func:`torquemod.twins.vtrack.rig.lanes.integrate`).
The dynamics (and so the phase) never read these recorded forces. The work per step is trimmed
without changing the equations: the modulation sine is rotated from step to step, the normal
load's sines from a per-step anchor (above :func:`_load_near`), the speed reference's wobble
from per-step phasors (:func:`_wob_step`), and the right-hand side reads the states as
scalars (:func:`_rhs_s`). The helpers below take a lane index ``l`` into arrays of lanes
(one row per integration), as the integrator runs several side by side.
"""

from __future__ import annotations

import math
import types

import numba
import numpy as np

from torquemod.analysis.contact.polach import creep_force_scalar
from torquemod.twins.vtrack.params import DisturbanceParams, RigParams
from torquemod.twins.vtrack.rig.kernels import FLAGS, cos_small, exp_small, sin_small
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
#: the same functions inlined into the integrator (numba's ``inline="always"``: compiled only
#: as part of their callers, with the callers' flags; no cache entries of their own)
_INLINE = {"fastmath": _FLAGS, "inline": "always"}
_creep_force_in = numba.njit(**_INLINE)(
    _renamed(creep_force_scalar, "creep_force_scalar_inline"))
_cos_small = numba.njit(**_INLINE)(_renamed(cos_small.py_func, "cos_small_inline"))
_sin_small = numba.njit(**_INLINE)(_renamed(sin_small.py_func, "sin_small_inline"))
_exp_small = numba.njit(**_INLINE)(_renamed(exp_small.py_func, "exp_small_inline"))
#: Columns of the per-sample output of the integrator
#: (:func:`torquemod.twins.vtrack.rig.lanes.integrate`).
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
# Within one RK4 step the platform turns by ~5e-4 rad, so every evaluation of the normal load
# in the step is written as its sines and decay at the step's start angle (the "anchor")
# rotated/decayed by the small increment: the rotations' sin and cos by Taylor polynomials
# accurate to rounding for |u| <= _ROT (a joint's ringing turns by ~0.18 rad in a step of
# 12 samples, the sleepers' argument by ~0.07 rad), the decay's exp for |x| <= _SMALL
# (:mod:`torquemod.twins.vtrack.rig.kernels`). The anchor itself is advanced the same way
# from step to step and evaluated exactly every _ANCHOR_EXACT steps. Larger increments, and
# a rail joint between anchor and angle, fall back to the exact :func:`normal_load`.
_SMALL = 0.05
_ROT = 0.25


def _cos_rot_py(u):
    """``cos(u)`` for ``|u| <= 0.25``: the first omitted term u**14/14! < 4.3e-20."""
    v = u * u
    return 1.0 - v / 2.0 * (1.0 - v / 12.0 * (1.0 - v / 30.0 * (1.0 - v / 56.0 * (
        1.0 - v / 90.0 * (1.0 - v / 132.0)))))


#: ``sin(u)`` for ``|u| <= 0.25``: :func:`~torquemod.twins.vtrack.rig.kernels.sin_small`'s
#: polynomial, whose first omitted term there is u**13/13! < 9.7e-18 relative
_sin_rot = _sin_small
_cos_rot = numba.njit(**_INLINE)(_cos_rot_py)
# anchor vector: angle, sin/cos of the sleeper argument, joint phase, joint decay, sin/cos
A_TH, A_SS, A_SC, A_PHI, A_JE, A_JS, A_JC = range(7)
N_ANCHOR = 7


@numba.njit(inline="always", **_FAST)
def _load_anchor(th_p: float, p: np.ndarray, l: int, a: np.ndarray) -> float:
    """Set lane ``l``'s anchor ``a[l]`` at ``th_p`` and return the normal load there
    (= :func:`normal_load` with the parameters ``p[l]``)."""
    a[l, A_TH] = th_p
    n = p[l, P_N0]
    if p[l, P_SLEEP_A] != 0.0:
        u = p[l, P_SLEEP_N] * th_p
        a[l, A_SS] = math.sin(u)
        a[l, A_SC] = math.cos(u)
        n += p[l, P_SLEEP_A] * a[l, A_SS]
    if p[l, P_JOINT_A] != 0.0:
        pitch = 2.0 * math.pi / p[l, P_JOINT_N]
        phi = (th_p - 0.5 * pitch) % pitch
        t = phi / p[l, P_WREF]
        a[l, A_PHI] = phi
        a[l, A_JE] = math.exp(-p[l, P_JOINT_Z] * t)
        a[l, A_JS] = math.sin(p[l, P_JOINT_W] * t)
        a[l, A_JC] = math.cos(p[l, P_JOINT_W] * t)
        n += p[l, P_JOINT_A] * a[l, A_JE] * a[l, A_JS]
    return n


@numba.njit(inline="always", **_FAST)
def _load_near(th_p: float, p: np.ndarray, l: int, a: np.ndarray) -> float:
    """:func:`normal_load` at ``th_p`` from lane ``l``'s anchor ``a[l]`` set nearby (see
    above; parameters ``p[l]``)."""
    d = th_p - a[l, A_TH]
    n = p[l, P_N0]
    if p[l, P_SLEEP_A] != 0.0:
        u = p[l, P_SLEEP_N] * d
        if abs(u) <= _ROT:
            n += p[l, P_SLEEP_A] * (a[l, A_SS] * _cos_rot(u) + a[l, A_SC] * _sin_rot(u))
        else:
            n += p[l, P_SLEEP_A] * math.sin(p[l, P_SLEEP_N] * th_p)
    if p[l, P_JOINT_A] != 0.0:
        pitch = 2.0 * math.pi / p[l, P_JOINT_N]
        phi = a[l, A_PHI] + d
        tau = d / p[l, P_WREF]
        x = p[l, P_JOINT_Z] * tau
        u = p[l, P_JOINT_W] * tau
        if 0.0 <= phi < pitch and abs(u) <= _ROT and abs(x) <= _SMALL:
            n += p[l, P_JOINT_A] * a[l, A_JE] * _exp_small(-x) * (
                a[l, A_JS] * _cos_rot(u) + a[l, A_JC] * _sin_rot(u))
        else:
            phi = (th_p - 0.5 * pitch) % pitch
            t = phi / p[l, P_WREF]
            n += p[l, P_JOINT_A] * math.exp(-p[l, P_JOINT_Z] * t) * math.sin(p[l, P_JOINT_W] * t)
    return n


@numba.njit(inline="always", **_FAST)
def _load_advance(th_p: float, p: np.ndarray, l: int, a: np.ndarray, b: np.ndarray,
                  exact: bool) -> float:
    """Set lane ``l``'s anchor ``b[l]`` at ``th_p`` by advancing its anchor ``a[l]`` set
    nearby (the sines rotated, the decay multiplied, as in :func:`_load_near`), or exactly
    (:func:`_load_anchor`) if ``exact``, across a rail joint or for a large increment;
    return the normal load."""
    if exact:
        return _load_anchor(th_p, p, l, b)
    d = th_p - a[l, A_TH]
    sa = p[l, P_SLEEP_A] != 0.0
    u = p[l, P_SLEEP_N] * d
    if sa and not abs(u) <= _ROT:
        return _load_anchor(th_p, p, l, b)
    ja = p[l, P_JOINT_A] != 0.0
    phi = a[l, A_PHI] + d
    tau = d / p[l, P_WREF]
    x = p[l, P_JOINT_Z] * tau
    v = p[l, P_JOINT_W] * tau
    if ja and not (0.0 <= phi < 2.0 * math.pi / p[l, P_JOINT_N] and abs(v) <= _ROT
                   and abs(x) <= _SMALL):
        return _load_anchor(th_p, p, l, b)
    b[l, A_TH] = th_p
    n = p[l, P_N0]
    if sa:
        cu, su = _cos_rot(u), _sin_rot(u)
        b[l, A_SS] = a[l, A_SS] * cu + a[l, A_SC] * su
        b[l, A_SC] = a[l, A_SC] * cu - a[l, A_SS] * su
        n += p[l, P_SLEEP_A] * b[l, A_SS]
    if ja:
        cv, sv = _cos_rot(v), _sin_rot(v)
        b[l, A_PHI] = phi
        b[l, A_JE] = a[l, A_JE] * _exp_small(-x)
        b[l, A_JS] = a[l, A_JS] * cv + a[l, A_JC] * sv
        b[l, A_JC] = a[l, A_JC] * cv - a[l, A_JS] * sv
        n += p[l, P_JOINT_A] * b[l, A_JE] * b[l, A_JS]
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
    (Fx, Fy, N, xi_x) into ``f`` -- the plain form of what the integrator evaluates."""
    n = normal_load(y[4], p)
    fx, fy, xi = _rhs(y, t_m, n, p, dy)
    f[0], f[1], f[2], f[3] = fx, fy, n, xi


@numba.njit(inline="always", **_FAST)
def _ramp(t, dc_from, dc_to, t_step, ramp_s):
    r = 1.0 if ramp_s <= 0.0 else min(max((t - t_step) / ramp_s, 0.0), 1.0)
    return dc_from + (dc_to - dc_from) * r


@numba.njit(inline="always", **_FAST)
def _rhs_s(y0, y1, y2, y5, y6, t_m, n, c, dw=0.0):
    """:func:`_rhs` on scalars (the states the right-hand side reads; ``th_w' = w_w`` and
    ``th_p' = W_p`` need no evaluation) with the constants ``c`` of :func:`_constants` and the
    speed reference's wobble ``dw`` [rad/s] (:func:`_wobble`).
    Returns the derivatives of ``twist, w_m, w_w, W_p, i_pi`` and ``(Fx, Fy, xi_x)``."""
    rw, rp, wref, ijm, ijw, ijp, kt, ct, kp, ki, trr, xiy, sx, sy, mu0, a, b, ka, ks = c
    v = y5 * rp
    xi = (y2 * rw - v) / v
    fx, fy = _creep_force_in(xi, xiy, n, v, sx, sy, mu0, a, b, ka, ks)
    t_sh = kt * y0 + ct * (y1 - y2)
    err = wref + dw - y5
    return (y1 - y2, (t_m - t_sh) * ijm, (t_sh - rw * fx) * ijw,
            (kp * err + ki * y6 + rp * fx - trr) * ijp, err, fx, fy, xi)


@numba.njit(inline="always", **_FAST)
def _constants(p, l, c):
    """Lane ``l``'s constants of :func:`_rhs_s` (from the parameters ``p[l]``) into ``c[l]``."""
    c[l, 0], c[l, 1], c[l, 2] = p[l, P_RW], p[l, P_RP], p[l, P_WREF]
    c[l, 3], c[l, 4], c[l, 5] = 1.0 / p[l, P_JM], 1.0 / p[l, P_JW], 1.0 / p[l, P_JP]
    c[l, 6], c[l, 7], c[l, 8], c[l, 9] = p[l, P_KT], p[l, P_CT], p[l, P_KP], p[l, P_KI]
    c[l, 10], c[l, 11], c[l, 12], c[l, 13] = p[l, P_TRR], p[l, P_XIY], p[l, P_SX], p[l, P_SY]
    c[l, 14], c[l, 15], c[l, 16] = p[l, P_MU0], p[l, P_A], p[l, P_B]
    c[l, 17], c[l, 18] = p[l, P_KA], p[l, P_KS]


#: number of constants of :func:`_constants`
N_CONST = 19


@numba.njit(inline="always", **_FAST)
def _ctuple(c, l):
    """Lane ``l``'s constants (:func:`_constants`) as the tuple :func:`_rhs_s` reads."""
    return (c[l, 0], c[l, 1], c[l, 2], c[l, 3], c[l, 4], c[l, 5], c[l, 6], c[l, 7], c[l, 8],
            c[l, 9], c[l, 10], c[l, 11], c[l, 12], c[l, 13], c[l, 14], c[l, 15], c[l, 16],
            c[l, 17], c[l, 18])


@numba.njit(inline="always", **_FAST)
def _put(out, l, i, kt, ct, y0, y1, y2, y3, y4, y5, fx, fy, n, xi):
    """Lane ``l``'s sample ``i``: the columns of :data:`OUT_COLUMNS` into ``out[l, i]``."""
    out[l, i, 0] = kt * y0 + ct * (y1 - y2)
    out[l, i, 1] = y2
    out[l, i, 2] = y5
    out[l, i, 3] = fx
    out[l, i, 4] = fy
    out[l, i, 5] = n
    out[l, i, 6] = y3
    out[l, i, 7] = y4
    out[l, i, 8] = xi


@numba.njit(inline="always", **_FAST)
def _hermite_weights(th, h):
    """Weights of the cubic Hermite interpolant (:func:`_hermite`) at ``th`` (fraction of
    the step ``h``): of the start value, start slope, end value and end slope."""
    r = 1.0 - th
    return (1.0 + 2.0 * th) * r * r, th * r * r * h, th * th * (3.0 - 2.0 * th), -th * th * r * h


@numba.njit(inline="always", **_FAST)
def _hermite(w00, w10, w01, w11, y0, y1, y2, y3, y4, y5, y6, a0, a1, a2, a5, a6, z0, z1, z2,
             z3, z4, z5, z6, e0, e1, e2, e5, e6):
    """Cubic Hermite interpolant with the weights of :func:`_hermite_weights` of the states
    ``y`` (slopes ``a``; ``th_w' = w_w``, ``th_p' = W_p``) at the step's start and ``z``
    (slopes ``e``) at its end."""
    return (w00 * y0 + w10 * a0 + w01 * z0 + w11 * e0,
            w00 * y1 + w10 * a1 + w01 * z1 + w11 * e1,
            w00 * y2 + w10 * a2 + w01 * z2 + w11 * e2,
            w00 * y3 + w10 * y2 + w01 * z3 + w11 * z2,
            w00 * y4 + w10 * y5 + w01 * z4 + w11 * z5,
            w00 * y5 + w10 * a5 + w01 * z5 + w11 * e5,
            w00 * y6 + w10 * a6 + w01 * z6 + w11 * e6)


#: largest miss of the quadratic at the step's middle, relative to the normal load, for which
#: the inner samples take the contact from the cubic (1e-3 N at 4200 N: 99.9 % of the steps
#: of the default experiment at 8 samples a step, whose misses stayed below 2e-4 N; 0.6 N
#: after a start off equilibrium; the miss grows as h^3)
_CUBIC_MISS = 2.5e-7


@numba.njit(inline="always", **_FAST)
def _cubic_weights(th):
    """Lagrange weights at ``th`` of the nodes -1/2, 0, 1/2, 1 (fractions of a step)."""
    a, b, c, d = th + 0.5, th, th - 0.5, th - 1.0
    return b * c * d / -0.75, a * c * d / 0.25, a * b * d / -0.25, a * b * c / 0.75


#: RK4 steps between exact re-evaluations of the modulation's sine (rotated in between)
_RESYNC = 1024


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
