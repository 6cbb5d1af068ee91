"""The twin's fixed-step RK4 integrator, run across lanes (numba).

Classical RK4 for every state but the platform speed, whose linear rate ``-K_p/J_p`` (the
platform's PI loop, by far the stiffest mode) is taken exactly by the exponential RK4 of
S. Krogstad, "Generalized integrating factor methods for stiff PDEs", J. Comput. Phys. 203
(2005) 72-88 (weights :func:`_etd_coefficients`); with that rate zero it is classical RK4.
The step is then bounded by the other modes (the torsional, ~200 1/s on the default rig),
so the settling runs at twice the recorded step (:mod:`torquemod.twins.vtrack.rig.steps`).

:func:`integrate_lanes` advances ``L`` independent integrations -- torque steps of one run or
of many sweep points, each with its own parameters, start state, time axis, modulation and
speed-reference wobble -- in one compiled loop over a structure of arrays: every round does
one RK4 step of every lane that is still running, stage by stage across the lanes (the
first stage of every lane, then the second, ...). One RK4 step is a chain of four contact
force evaluations (Polach 2005), each waiting for the one before; the lanes' chains are
independent, so the processor overlaps them instead of waiting out each evaluation's
latency.

:func:`integrate` is the same kernel with one lane. Each lane runs exactly the operations of
a single integration in the same order, so a lane's output does not depend on how many lanes
run beside it or which (tested bit for bit). The method (Hermite samples inside a step,
their contact forces from the cubic through the exact ones, the normal load from per-step
anchors, the wobble's phasors, the stop at the first slipping sample) is described in
:mod:`torquemod.twins.vtrack.rig.dynamics`.

numba caches the compiled kernel under this file's name and time stamp only: the helpers it
inlines from :mod:`~torquemod.twins.vtrack.rig.dynamics`, :mod:`~torquemod.twins.vtrack.rig.wobble`
and :mod:`~torquemod.twins.vtrack.rig.kernels` do not invalidate it, so a change to them must
come with an edit of this file (or a cleared ``__pycache__``) to take effect.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.twins.vtrack.rig.dynamics import (
    _ANCHOR_EXACT,
    _CUBIC_MISS,
    _FAST,
    _RESYNC,
    A_PHI,
    N_ANCHOR,
    N_CONST,
    N_STATES,
    OUT_COLUMNS,
    P_JOINT_A,
    P_JOINT_N,
    _constants,
    _creep_force_in,
    _ctuple,
    _cubic_weights,
    _hermite,
    _hermite_weights,
    _load_advance,
    _load_anchor,
    _load_near,
    _put,
    _ramp,
    _rhs_s,
)
from torquemod.twins.vtrack.rig.wobble import _wob_rev, _wob_set, _wob_step, _wobble

#: columns of the per-lane float settings ``sf`` of :func:`_integrate_lanes`: start time [s],
#: sample interval [s], DC ramp from/to [N*m], its start and duration [s], modulation
#: amplitude [N*m], angular frequency [rad/s], phase [rad], generator time origin [s], slip
#: creepage [-]
(S_T0, S_DT, S_DCF, S_DCT, S_TSTEP, S_RAMP, S_AMP, S_OMEGA, S_PHASE, S_TGEN,
 S_SLIP) = range(11)
N_SF = 11
#: columns of the per-lane integer settings ``si``: samples, RK4 steps per block, samples per
#: block, first output row
I_N, I_SUB, I_M, I_OFF = range(4)
N_SI = 4
#: columns of the per-lane step values kept between the stages of a round
(V_HB, V_TMH, V_TM1, V_ES, V_EC, V_S2, V_S5, V_U2, V_U5, V_V2, V_V5, V_WTH, V_WT1, V_TB,
 V_HPREV, V_RC, V_RS, V_MS, V_MC, V_DTH, V_E2, V_A1, V_B2, V_E, V_C1, V_C2, V_F1, V_F2,
 V_F3, V_NA, V_L) = range(31)
N_V = 31
#: points on the circle of the contour means of :func:`_etd_coefficients`
_ETD_POINTS = 32


@numba.njit(inline="always", **_FAST)
def _phis(z):
    """``phi_1(z) = (e^z - 1)/z``, ``phi_2 = (e^z - 1 - z)/z^2``,
    ``phi_3 = (e^z - 1 - z - z^2/2)/z^3`` as means over a circle of radius 1 around ``z``
    in the complex plane (A.-K. Kassam and L. N. Trefethen, SIAM J. Sci. Comput. 26 (2005)
    1214-1233): free of the plain formulas' cancellation as ``z -> 0`` (1, 1/2, 1/6 there)."""
    a1 = a2 = a3 = 0.0
    for k in range(_ETD_POINTS):
        ang = 2.0 * math.pi * (k + 0.5) / _ETD_POINTS
        r = complex(z + math.cos(ang), math.sin(ang))
        em = np.exp(r) - 1.0
        a1 += (em / r).real
        a2 += ((em - r) / (r * r)).real
        a3 += ((em - r - 0.5 * r * r) / (r * r * r)).real
    return a1 / _ETD_POINTS, a2 / _ETD_POINTS, a3 / _ETD_POINTS


@numba.njit(inline="always", **_FAST)
def _etd_coefficients(lam, h):
    """The weights of the exponential RK4 of S. Krogstad (J. Comput. Phys. 203 (2005)
    72-88) for the linear rate ``lam`` [1/s] over a step ``h`` [s], ``z = lam*h``:
    ``e^(z/2)``, ``h/2*phi_1(z/2)``, ``h*phi_2(z/2)`` (stages 2 and 3), ``e^z``,
    ``h*phi_1(z)``, ``2*h*phi_2(z)`` (stage 4), and of the end ``h*(phi_1 - 3*phi_2 +
    4*phi_3)``, ``h*(phi_2 - 2*phi_3)`` (taken twice) and ``h*(4*phi_3 - phi_2)``
    (:func:`_phis`); with ``lam = 0`` they are classical RK4's."""
    z = lam * h
    p1h, p2h, _ = _phis(0.5 * z)
    p1, p2, p3 = _phis(z)
    return (math.exp(0.5 * z), 0.5 * h * p1h, h * p2h, math.exp(z), h * p1, 2.0 * h * p2,
            h * (p1 - 3.0 * p2 + 4.0 * p3), h * (p2 - 2.0 * p3), h * (4.0 * p3 - p2))


@numba.njit(nogil=True, _nrt=False, **_FAST)
def _integrate_lanes(y, sf, si, p, wob, nw, out, res, wf, wi):
    """Advance the states ``y`` (L, 7) (modified in place) lane by lane as
    :func:`integrate` does one, with the settings ``sf`` (L, :data:`N_SF`), ``si``
    (L, :data:`N_SI`), parameters ``p`` (L, 26), wobble tables ``wob`` (L, rows, 4) of
    ``nw[l]`` rows each; lane ``l`` writes its samples to ``out[l]`` from row
    ``si[l, I_OFF]``. ``res[l] = (n_written, slipped)``."""
    nl = y.shape[0]
    cst, anc, anc_n, ws, wc, wrc, wrs, wsum, ya, f0, kb, kc, kd, ke, fe, z, v, pm, hw = wf
    have_pm, ib, jj, mbl, n_steps, act = wi
    n_act = nl
    for l in range(nl):
        _constants(p, l, cst)
        t0 = sf[l, S_T0]
        ang0 = sf[l, S_OMEGA] * (t0 - sf[l, S_TGEN]) + sf[l, S_PHASE]
        v[l, V_MS], v[l, V_MC] = math.sin(ang0), math.cos(ang0)
        _wob_set(t0, y[l, 4], wob, l, nw, ws, wc)
        n0 = _load_anchor(y[l, 4], p, l, anc)
        tm = _ramp(t0, sf[l, S_DCF], sf[l, S_DCT], sf[l, S_TSTEP], sf[l, S_RAMP]) \
            + sf[l, S_AMP] * v[l, V_MS]
        a0, a1, a2, a5, a6, fx0, fy0, xi0 = _rhs_s(y[l, 0], y[l, 1], y[l, 2], y[l, 5],
                                                   y[l, 6], tm, n0, _ctuple(cst, l),
                                                   _wobble(t0, y[l, 4], wob[l, :nw[l]]))
        ya[l, 0], ya[l, 1], ya[l, 2], ya[l, 3], ya[l, 4] = a0, a1, a2, a5, a6
        f0[l, 0], f0[l, 1], f0[l, 2], f0[l, 3] = fx0, fy0, n0, xi0
        v[l, V_HPREV] = -1.0
        v[l, V_RC] = v[l, V_RS] = 1.0
        v[l, V_L] = -cst[l, 8] * cst[l, 5]  # the platform loop's -K_p/J_p [1/s]
    while n_act > 0:
        # ---- the step's set-up, its start sample and the first stage ----------------------
        for l in range(nl):
            if not act[l]:
                continue
            n, s_n, m = si[l, I_N], si[l, I_SUB], si[l, I_M]
            dt, omega = sf[l, S_DT], sf[l, S_OMEGA]
            c = _ctuple(cst, l)
            if jj[l] == 0:
                if ib[l] >= n:
                    res[l, 0], res[l, 1] = n, 0
                    act[l] = False
                    n_act -= 1
                    continue
                mb = min(m, n - ib[l])
                mbl[l] = mb
                hb = mb * dt / s_n
                if hb != v[l, V_HPREV]:  # rotation of the modulation phase by half a step
                    v[l, V_HPREV] = hb
                    v[l, V_RC], v[l, V_RS] = math.cos(0.5 * omega * hb), math.sin(0.5 * omega * hb)
                    (v[l, V_E2], v[l, V_A1], v[l, V_B2], v[l, V_E], v[l, V_C1], v[l, V_C2],
                     v[l, V_F1], v[l, V_F2], v[l, V_F3]) = _etd_coefficients(v[l, V_L], hb)
                    for j in range(nw[l]):
                        wrc[l, j] = math.cos(0.5 * wob[l, j, 1] * hb)
                        wrs[l, j] = math.sin(0.5 * wob[l, j, 1] * hb)
                    # the weights of the samples inside a step, at th = q/mb
                    for q in range(1, mb):
                        th = q / mb
                        w00, w10, w01, w11 = _hermite_weights(th, hb)
                        l0, l1, l2, l3 = _cubic_weights(th)
                        hw[l, q, 0], hw[l, q, 1], hw[l, q, 2], hw[l, q, 3] = w00, w10, w01, w11
                        hw[l, q, 4], hw[l, q, 5], hw[l, q, 6], hw[l, q, 7] = l0, l1, l2, l3
                v[l, V_HB] = hb
                v[l, V_TB] = sf[l, S_T0] + ib[l] * dt
            mb, hb = mbl[l], v[l, V_HB]
            hh = 0.5 * hb
            ta = v[l, V_TB] + jj[l] * hb
            y0, y1, y2, y3, y4, y5, y6 = y[l, 0], y[l, 1], y[l, 2], y[l, 3], y[l, 4], y[l, 5], \
                y[l, 6]
            if (jj[l] * mb) % s_n == 0:  # the sample at the start of this RK4 step
                k = ib[l] + (jj[l] * mb) // s_n
                xi0 = f0[l, 3]
                _put(out, l, si[l, I_OFF] + k, c[6], c[7], y0, y1, y2, y3, y4, y5, f0[l, 0],
                     f0[l, 1], f0[l, 2], xi0)
                if not (xi0 < sf[l, S_SLIP]) or not math.isfinite(xi0):
                    res[l, 0], res[l, 1] = k + 1, 1
                    act[l] = False
                    n_act -= 1
                    continue
            amp = sf[l, S_AMP]
            if amp != 0.0:  # modulation at ta + h/2 and ta + h
                ms, mc, rc, rs = v[l, V_MS], v[l, V_MC], v[l, V_RC], v[l, V_RS]
                hs = ms * rc + mc * rs
                hc = mc * rc - ms * rs
                es = hs * rc + hc * rs
                ec = hc * rc - hs * rs
                if n_steps[l] % _RESYNC == 0:
                    ang = omega * (ta + hb - sf[l, S_TGEN]) + sf[l, S_PHASE]
                    es, ec = math.sin(ang), math.cos(ang)
                else:
                    g = 1.5 - 0.5 * (es * es + ec * ec)  # keep on the unit circle
                    es *= g
                    ec *= g
            else:
                hs = es = 0.0
                ec = 1.0
            v[l, V_ES], v[l, V_EC] = es, ec
            use_wob = nw[l] > 0
            if use_wob:
                if n_steps[l] % _RESYNC == 0:
                    _wob_set(ta, y4, wob, l, nw, ws, wc)
                    v[l, V_DTH] = 0.0
                _wob_step(wob, l, nw, ws, wc, wrc, wrs, v[l, V_DTH], wsum)
            wth = wsum[l, 0]
            v[l, V_WTH], v[l, V_WT1] = wth, wsum[l, 1]
            n_steps[l] += 1
            dcf, dct, tst, rmp = sf[l, S_DCF], sf[l, S_DCT], sf[l, S_TSTEP], sf[l, S_RAMP]
            tmh = _ramp(ta + hh, dcf, dct, tst, rmp) + amp * hs
            v[l, V_TMH] = tmh
            v[l, V_TM1] = _ramp(ta + hb, dcf, dct, tst, rmp) + amp * es
            a0, a1, a2, a5, a6 = ya[l, 0], ya[l, 1], ya[l, 2], ya[l, 3], ya[l, 4]
            # the platform speed's stages and end by exponential RK4 (its linear rate
            # -K_p/J_p taken exactly, the rest of its right-hand side "n" as RK4 takes all):
            # its stiff mode no longer bounds the step; the other states by classical RK4
            lam = v[l, V_L]
            na = a5 - lam * y5
            v[l, V_NA] = na
            s2, s5 = y2 + hh * a2, v[l, V_E2] * y5 + v[l, V_A1] * na
            s4 = y4 + hh * y5
            dw = (wth + _wob_rev(wsum, l, hh * y5)) if use_wob else 0.0
            b0, b1, b2, b5, b6, _, _, _ = _rhs_s(y0 + hh * a0, y1 + hh * a1, s2, s5,
                                                 y6 + hh * a6, tmh, _load_near(s4, p, l, anc),
                                                 c, dw)
            v[l, V_S2], v[l, V_S5] = s2, s5
            kb[l, 0], kb[l, 1], kb[l, 2], kb[l, 3], kb[l, 4] = b0, b1, b2, b5, b6
        # ---- second stage ----------------------------------------------------------------
        for l in range(nl):
            if not act[l]:
                continue
            hh = 0.5 * v[l, V_HB]
            y0, y1, y2, y4, y5, y6 = y[l, 0], y[l, 1], y[l, 2], y[l, 4], y[l, 5], y[l, 6]
            b0, b1, b2, b5, b6 = kb[l, 0], kb[l, 1], kb[l, 2], kb[l, 3], kb[l, 4]
            s5 = v[l, V_S5]
            na = v[l, V_NA]
            u2 = y2 + hh * b2
            u5 = v[l, V_E2] * y5 + v[l, V_A1] * na + v[l, V_B2] * ((b5 - v[l, V_L] * s5) - na)
            u4 = y4 + hh * s5
            dw = (v[l, V_WTH] + _wob_rev(wsum, l, hh * s5)) if nw[l] > 0 else 0.0
            c0, c1, c2, c5, c6, _, _, _ = _rhs_s(y0 + hh * b0, y1 + hh * b1, u2, u5,
                                                 y6 + hh * b6, v[l, V_TMH],
                                                 _load_near(u4, p, l, anc),
                                                 _ctuple(cst, l), dw)
            v[l, V_U2], v[l, V_U5] = u2, u5
            kc[l, 0], kc[l, 1], kc[l, 2], kc[l, 3], kc[l, 4] = c0, c1, c2, c5, c6
        # ---- third stage -----------------------------------------------------------------
        for l in range(nl):
            if not act[l]:
                continue
            hb = v[l, V_HB]
            y0, y1, y2, y4, y5, y6 = y[l, 0], y[l, 1], y[l, 2], y[l, 4], y[l, 5], y[l, 6]
            c0, c1, c2, c5, c6 = kc[l, 0], kc[l, 1], kc[l, 2], kc[l, 3], kc[l, 4]
            u5 = v[l, V_U5]
            v2 = y2 + hb * c2
            na = v[l, V_NA]
            v5 = v[l, V_E] * y5 + v[l, V_C1] * na + v[l, V_C2] * ((c5 - v[l, V_L] * u5) - na)
            v4 = y4 + hb * u5
            dw = (v[l, V_WT1] + _wob_rev(wsum, l, hb * u5)) if nw[l] > 0 else 0.0
            d0, d1, d2, d5, d6, _, _, _ = _rhs_s(y0 + hb * c0, y1 + hb * c1, v2, v5,
                                                 y6 + hb * c6, v[l, V_TM1],
                                                 _load_near(v4, p, l, anc),
                                                 _ctuple(cst, l), dw)
            v[l, V_V2], v[l, V_V5] = v2, v5
            kd[l, 0], kd[l, 1], kd[l, 2], kd[l, 3], kd[l, 4] = d0, d1, d2, d5, d6
        # ---- the step's end state and the derivative there -------------------------------
        for l in range(nl):
            if not act[l]:
                continue
            hb = v[l, V_HB]
            y0, y1, y2, y3, y4, y5, y6 = y[l, 0], y[l, 1], y[l, 2], y[l, 3], y[l, 4], y[l, 5], \
                y[l, 6]
            h6 = hb / 6.0
            z0 = y0 + h6 * (ya[l, 0] + 2.0 * (kb[l, 0] + kc[l, 0]) + kd[l, 0])
            z1 = y1 + h6 * (ya[l, 1] + 2.0 * (kb[l, 1] + kc[l, 1]) + kd[l, 1])
            z2 = y2 + h6 * (ya[l, 2] + 2.0 * (kb[l, 2] + kc[l, 2]) + kd[l, 2])
            z3 = y3 + h6 * (y2 + 2.0 * (v[l, V_S2] + v[l, V_U2]) + v[l, V_V2])
            z4 = y4 + h6 * (y5 + 2.0 * (v[l, V_S5] + v[l, V_U5]) + v[l, V_V5])
            lam = v[l, V_L]
            nb, nc = kb[l, 3] - lam * v[l, V_S5], kc[l, 3] - lam * v[l, V_U5]
            z5 = v[l, V_E] * y5 + v[l, V_F1] * v[l, V_NA] + 2.0 * v[l, V_F2] * (nb + nc) \
                + v[l, V_F3] * (kd[l, 3] - lam * v[l, V_V5])
            z6 = y6 + h6 * (ya[l, 4] + 2.0 * (kb[l, 4] + kc[l, 4]) + kd[l, 4])
            nn = _load_advance(z4, p, l, anc, anc_n, n_steps[l] % _ANCHOR_EXACT == 0)
            dth = z4 - y4
            v[l, V_DTH] = dth
            dw = (v[l, V_WT1] + _wob_rev(wsum, l, dth)) if nw[l] > 0 else 0.0
            e0, e1, e2, e5, e6, fxn, fyn, xin = _rhs_s(z0, z1, z2, z5, z6, v[l, V_TM1], nn,
                                                       _ctuple(cst, l), dw)
            z[l, 0], z[l, 1], z[l, 2], z[l, 3], z[l, 4], z[l, 5], z[l, 6] = \
                z0, z1, z2, z3, z4, z5, z6
            ke[l, 0], ke[l, 1], ke[l, 2], ke[l, 3], ke[l, 4] = e0, e1, e2, e5, e6
            fe[l, 0], fe[l, 1], fe[l, 2], fe[l, 3] = fxn, fyn, nn, xin
        # ---- samples inside the step, then on to the next step ---------------------------
        for l in range(nl):
            if not act[l]:
                continue
            if not _inner_samples(l, y, ya, z, ke, f0, fe, v, pm, have_pm, anc, p, cst, si,
                                  sf, mbl[l], jj[l], ib[l], out, res, hw):
                act[l] = False
                n_act -= 1
                continue
            for j in range(N_STATES):
                y[l, j] = z[l, j]
            for j in range(5):
                ya[l, j] = ke[l, j]
            for j in range(N_ANCHOR):
                anc[l, j] = anc_n[l, j]
            for j in range(4):
                f0[l, j] = fe[l, j]
            v[l, V_MS], v[l, V_MC] = v[l, V_ES], v[l, V_EC]
            jj[l] += 1
            if jj[l] == si[l, I_SUB]:
                jj[l] = 0
                ib[l] += mbl[l]
    return res


@numba.njit(inline="always", **_FAST)
def _inner_samples(l, y, ya, z, ke, f0, fe, v, pm, have_pm, anc, p, cst, si, sf, mb, jj, i,
                   out, res, hw):
    """Lane ``l``'s samples strictly inside its RK4 step: the states by cubic Hermite
    interpolation (:func:`~torquemod.twins.vtrack.rig.dynamics._hermite`). Whole blocks of
    an even number m >= 4 of samples per RK4 step evaluate the contact exactly at the middle
    sample only; the others take Fx, Fy and N from the cubic through the exact values half a
    step before the step, at its ends and at its middle
    (:func:`~torquemod.twins.vtrack.rig.dynamics._cubic_weights`) unless a rail joint (a kink
    in N) lies in that span or the force varies fast on the step's scale. Sets the middle
    contact for the next step (``pm``, ``have_pm``); returns False (``res`` set, ``y`` the
    sample's state) at the first sample that slips."""
    c = _ctuple(cst, l)
    s_n, m, off = si[l, I_SUB], si[l, I_M], si[l, I_OFF]
    slip = sf[l, S_SLIP]
    y0, y1, y2, y3, y4, y5, y6 = y[l, 0], y[l, 1], y[l, 2], y[l, 3], y[l, 4], y[l, 5], y[l, 6]
    a0, a1, a2, a5, a6 = ya[l, 0], ya[l, 1], ya[l, 2], ya[l, 3], ya[l, 4]
    z0, z1, z2, z3, z4, z5, z6 = z[l, 0], z[l, 1], z[l, 2], z[l, 3], z[l, 4], z[l, 5], z[l, 6]
    e0, e1, e2, e5, e6 = ke[l, 0], ke[l, 1], ke[l, 2], ke[l, 3], ke[l, 4]
    fx0, fy0, n0 = f0[l, 0], f0[l, 1], f0[l, 2]
    fxn, fyn, nn = fe[l, 0], fe[l, 1], fe[l, 2]
    fx_pm, fy_pm, n_pm, th_pm = pm[l, 0], pm[l, 1], pm[l, 2], pm[l, 3]
    cub_step = s_n == 1 and mb == m and m >= 4 and m % 2 == 0
    mid = 0
    use_cub = False
    p0 = p1 = p2 = p3 = p4 = p5 = p6 = 0.0
    n_mid = xi_mid = fx_mid = fy_mid = 0.0
    if cub_step:
        mid = mb // 2
        p0, p1, p2, p3, p4, p5, p6 = _hermite(hw[l, mid, 0], hw[l, mid, 1], hw[l, mid, 2],
                                              hw[l, mid, 3], y0, y1, y2, y3, y4, y5, y6, a0,
                                              a1, a2, a5, a6, z0, z1, z2, z3, z4, z5, z6, e0,
                                              e1, e2, e5, e6)
        n_mid = _load_near(p4, p, l, anc)
        vv = p5 * c[1]
        xi_mid = (p2 * c[0] - vv) / vv
        fx_mid, fy_mid = _creep_force_in(xi_mid, c[11], n_mid, vv, c[12], c[13], c[14], c[15],
                                      c[16], c[17], c[18])
        # the quadratic through the other three nodes misses the middle by ~h^3/16 times
        # the third derivative of Fx, which a fast transient drives far above its steady
        # ~1e-4 N
        miss = fx_mid - (fx0 + (fxn - fx_pm) / 3.0)
        use_cub = have_pm[l] and abs(miss) <= _CUBIC_MISS * abs(n_mid)
        if use_cub and p[l, P_JOINT_A] != 0.0:
            # no joint between half a step before and the step's end
            ph = anc[l, A_PHI]
            use_cub = (ph - (y4 - th_pm) >= 0.0
                       and ph + (z4 - y4) < 2.0 * math.pi / p[l, P_JOINT_N])
    for k in range(mb):
        q = k * s_n - jj * mb
        if 0 < q < mb:
            if cub_step and q == mid:
                q0, q1, q2, q3, q4, q5, q6 = p0, p1, p2, p3, p4, p5, p6
                ni, xi, fx, fy = n_mid, xi_mid, fx_mid, fy_mid
            else:
                q0, q1, q2, q3, q4, q5, q6 = _hermite(hw[l, q, 0], hw[l, q, 1], hw[l, q, 2],
                                                      hw[l, q, 3], y0, y1, y2, y3, y4, y5, y6,
                                                      a0, a1, a2, a5, a6, z0, z1, z2, z3, z4,
                                                      z5, z6, e0, e1, e2, e5, e6)
                vv = q5 * c[1]
                xi = (q2 * c[0] - vv) / vv
                if cub_step and use_cub:
                    l0, l1, l2, l3 = hw[l, q, 4], hw[l, q, 5], hw[l, q, 6], hw[l, q, 7]
                    fx = l0 * fx_pm + l1 * fx0 + l2 * fx_mid + l3 * fxn
                    fy = l0 * fy_pm + l1 * fy0 + l2 * fy_mid + l3 * fyn
                    ni = l0 * n_pm + l1 * n0 + l2 * n_mid + l3 * nn
                else:
                    ni = _load_near(q4, p, l, anc)
                    fx, fy = _creep_force_in(xi, c[11], ni, vv, c[12], c[13], c[14], c[15], c[16],
                                          c[17], c[18])
            _put(out, l, off + i + k, c[6], c[7], q0, q1, q2, q3, q4, q5, fx, fy, ni, xi)
            if not (xi < slip) or not math.isfinite(xi):
                y[l, 0], y[l, 1], y[l, 2], y[l, 3], y[l, 4], y[l, 5], y[l, 6] = \
                    q0, q1, q2, q3, q4, q5, q6
                res[l, 0], res[l, 1] = i + k + 1, 1
                return False
    have_pm[l] = cub_step
    if cub_step:
        pm[l, 0], pm[l, 1], pm[l, 2], pm[l, 3] = fx_mid, fy_mid, n_mid, p4
    return True


_NO_WOBBLE = np.zeros((0, 4))


def lane_settings(t0, n_samples, dt, substeps, dc_from, dc_to, t_step, ramp_s, amp, omega,
                  phase, t_gen, slip_creepage, samples_per_step=1, row0=0):
    """One lane's rows of ``sf`` and ``si`` (:func:`integrate_lanes`).

    Parameters
    ----------
    t0 : float
        Start time [s].
    n_samples : int
        Output samples [-].
    dt : float
        Sample interval [s].
    substeps : int
        RK4 steps per ``samples_per_step`` samples [-].
    dc_from, dc_to : float
        DC torque before and after the ramp [N*m].
    t_step, ramp_s : float
        Start and duration of the ramp [s].
    amp : float
        Modulation amplitude [N*m].
    omega : float
        Modulation angular frequency [rad/s].
    phase : float
        Generator phase [rad].
    t_gen : float
        Generator time origin [s].
    slip_creepage : float
        Creepage at which the lane stops as slipped [-].
    samples_per_step : int
        Output samples per RK4 block [-]. Default 1.
    row0 : int
        The lane's first output row [-]. Default 0.

    Returns
    -------
    sf : ndarray
        The float settings (:data:`N_SF`).
    si : ndarray
        The integer settings (:data:`N_SI`).
    """
    sf = np.array([t0, dt, dc_from, dc_to, t_step, ramp_s, amp, omega, phase, t_gen,
                   slip_creepage], dtype=np.float64)
    si = np.array([n_samples, substeps, samples_per_step, row0], dtype=np.int64)
    return sf, si


def stack_wobbles(wobbles) -> tuple[np.ndarray, np.ndarray]:
    """The lanes' wobble tables as one array.

    Parameters
    ----------
    wobbles : sequence of ndarray or None
        Each lane's table (rows, 4) of
        :func:`~torquemod.twins.vtrack.rig.wobble.wobble_table`; None: no wobble.

    Returns
    -------
    wob : ndarray
        The tables stacked (L, rows, 4), zero padded.
    nw : ndarray
        Each lane's row count.
    """
    tabs = [_NO_WOBBLE if w is None else np.asarray(w, dtype=np.float64) for w in wobbles]
    nw = np.array([t.shape[0] for t in tabs], dtype=np.int64)
    wob = np.zeros((len(tabs), max(1, int(nw.max(initial=0))), 4))
    for k, t in enumerate(tabs):
        wob[k, :t.shape[0]] = t
    return wob, nw


def integrate_lanes(y, sf, si, p, wob, nw, out) -> np.ndarray:
    """Run ``L`` integrations side by side (module docstring).

    Parameters
    ----------
    y : ndarray
        The lanes' states (L, 7), advanced in place.
    sf, si : ndarray
        The lanes' settings (L, :data:`N_SF`) and (L, :data:`N_SI`), rows of
        :func:`lane_settings`.
    p : ndarray
        The lanes' parameter vectors (L, 26) of
        :func:`~torquemod.twins.vtrack.rig.dynamics.pack_parameters`.
    wob, nw : ndarray
        The wobble tables and row counts of :func:`stack_wobbles`.
    out : ndarray
        The samples (L, rows, :data:`OUT_COLUMNS`), lane ``l`` from row ``si[l, I_OFF]``.

    Returns
    -------
    ndarray
        (L, 2) integers: the samples written and 1 where the lane stopped on wheel slip (as
        :func:`integrate`).
    """
    nl = y.shape[0]
    res = np.zeros((nl, 2), dtype=np.int64)
    if nl:
        nwm = wob.shape[1]
        wf = (np.empty((nl, N_CONST)), np.zeros((nl, N_ANCHOR)), np.zeros((nl, N_ANCHOR)),
              np.zeros((nl, nwm)), np.zeros((nl, nwm)), np.ones((nl, nwm)),
              np.zeros((nl, nwm)), np.zeros((nl, 6)), np.empty((nl, 5)), np.empty((nl, 4)),
              np.empty((nl, 5)), np.empty((nl, 5)), np.empty((nl, 5)), np.empty((nl, 5)),
              np.empty((nl, 4)), np.empty((nl, N_STATES)), np.zeros((nl, N_V)),
              np.zeros((nl, 4)), np.zeros((nl, max(1, int(si[:, I_M].max())), 8)))
        wi = (np.zeros(nl, dtype=np.bool_), np.zeros(nl, dtype=np.int64),
              np.zeros(nl, dtype=np.int64), np.zeros(nl, dtype=np.int64),
              np.zeros(nl, dtype=np.int64), np.ones(nl, dtype=np.bool_))
        _integrate_lanes(y, sf, si, p, wob, nw, out, res, wf, wi)
    return res


def integrate(y, t0, n_samples, dt, substeps, p, dc_from, dc_to, t_step, ramp_s, amp, omega,
              phase, t_gen, slip_creepage, out, samples_per_step=1, wobble=None):
    """Advance state ``y`` (modified in place) by ``n_samples`` output samples of ``dt`` [s]
    and write :data:`~torquemod.twins.vtrack.rig.dynamics.OUT_COLUMNS` to ``out`` (sample
    ``i`` is the state at ``t0 + i*dt``): :func:`integrate_lanes` with one lane.

    The time axis is cut into blocks of ``samples_per_step`` samples, each integrated by
    ``substeps`` classical RK4 steps (step ``h = samples_per_step*dt/substeps``; a shorter
    last block takes the remaining samples). A sample that falls inside an RK4 step is the
    cubic Hermite interpolant of the step's end states and derivatives (error O(h^4), as
    the method's), with the contact forces evaluated at that interpolated state.
    ``samples_per_step = substeps = 1`` is one RK4 step per sample. The motor torque is the
    DC ramp ``dc_from`` -> ``dc_to`` from ``t_step`` over ``ramp_s`` plus
    ``amp*sin(omega*(t - t_gen) + phase)``.

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
        The parameter vector (:func:`~torquemod.twins.vtrack.rig.dynamics.pack_parameters`).
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
        Output rows (:data:`~torquemod.twins.vtrack.rig.dynamics.OUT_COLUMNS`), written in place.
    samples_per_step : int
        Output samples per integration step [-]. Default 1.
    wobble : ndarray or None
        The speed reference's wobble rows
        (:func:`~torquemod.twins.vtrack.rig.wobble.wobble_table`); None: a steady reference.

    Returns
    -------
    n_written : int
        Samples written; integration stops at the first sample whose creepage exceeds
        ``slip_creepage``.
    slipped : bool
        Whether it stopped so (``y`` is then the state of that sample).
        """
    sf, si = lane_settings(t0, n_samples, dt, substeps, dc_from, dc_to, t_step, ramp_s, amp,
                           omega, phase, t_gen, slip_creepage, samples_per_step)
    wob, nw = stack_wobbles([wobble])
    ys = np.array(y, dtype=np.float64).reshape(1, N_STATES)
    res = integrate_lanes(ys, sf[None], si[None], np.asarray(p, dtype=np.float64)[None], wob,
                          nw, out[None])
    y[:] = ys[0]
    return int(res[0, 0]), bool(res[0, 1])


__all__ = ["OUT_COLUMNS", "integrate", "integrate_lanes", "lane_settings", "stack_wobbles"]
