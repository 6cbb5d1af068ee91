"""Ground truth of the twin's simulated steps: what ``truth.json`` records per step.

Per step the steady state and the theory phases at its DC torque, and what was simulated over
the recorded samples: means, CoA, the phase of the wheel speed behind the shaft torque with
the speed loop's wobble fitted out
(:func:`~torquemod.twins.vtrack.rig.truthphase.wobble_free_phase_deg`), the variation of the
creepage and of the platform speed, also per platform revolution. Moved out of
:mod:`torquemod.twins.vtrack.simulate` (which re-exports the public names) to keep modules small.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np

from torquemod.twins.vtrack.params import SimConfig
from torquemod.twins.vtrack.rig.dynamics import OUT_COLUMNS
from torquemod.twins.vtrack.rig.kernels import SMALL, cos_small, sin_small
from torquemod.twins.vtrack.rig.truthphase import WOBBLE_FIT_STRIDE, sine_fit_phase_deg
from torquemod.twins.vtrack.smallsignal import predicted_phase_deg, rigid_wheel_phase_deg
from torquemod.twins.vtrack.theory import large_signal_phase_deg, operating_point

_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}
#: columns of the output the truth fit reads: platform angle, torque, wheel speed
_FIT_COLS = np.array([_COL["platform_angle_rad"], _COL["torque_nm"], _COL["wheel_speed_rad_s"]])


def _cycle_bounds(theta: np.ndarray, start: int, cycles: int) -> list[int]:
    """Sample indices where the platform angle has advanced by whole revolutions from
    ``theta[start]``: ``[start, i1, ..., i_cycles]``."""
    th0 = theta[start]
    targets = th0 + 2.0 * np.pi * np.arange(1, cycles + 1)
    idx = start + np.searchsorted(theta[start:], targets)
    if idx[-1] >= theta.size:
        raise RuntimeError("simulated segment too short for the requested revolutions")
    return [start, *(int(i) for i in idx)]


def wobble_truth(config: SimConfig, wobble: np.ndarray) -> dict:
    """truth.json's record of the wobble drawn for this run: configuration and realised
    terms; ``reference_rms_pct`` is the RMS of the realised reference over a long run
    (``sqrt(sum amp^2/2)/W0``) [%].

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.
    wobble : ndarray
        The wobble rows.

    Returns
    -------
    dict
        The record.
    """
    d, w0 = config.disturbances, config.rig.platform_speed_rad_s
    f_rev = w0 / (2.0 * np.pi)
    terms = []
    for amp, rate, ph, kind in wobble.tolist():
        band = kind < 0.5
        terms.append({"kind": "band" if band else "revolution",
                      "frequency_hz": rate / (2.0 * np.pi) if band else rate * f_rev,
                      "order": None if band else int(rate),
                      "amplitude_rel": amp / w0, "amplitude_rad_s": amp, "phase_rad": ph})
    return {"enabled": bool(wobble.shape[0]), "rms": d.speed_wobble_rms,
            "band_hz": list(d.speed_wobble_band_hz), "components": d.speed_wobble_components,
            "rev1": d.speed_wobble_rev1, "rev2": d.speed_wobble_rev2,
            "revolution_hz": f_rev, "terms": terms,
            "reference_rms_pct": float(100.0 * np.sqrt(0.5 * np.sum(wobble[:, 0] ** 2)) / w0)}


#: truth.json's columns averaged over a recorded span
_MEANS = ("creepage", "torque_nm", "fx_n", "fy_n", "fz_n", "platform_speed_rad_s")


@numba.njit(cache=True, nogil=True)
def _span_moments(raw, a, b, cols, mean, std_cols, std):
    """Means over rows ``a:b`` of ``raw`` of the columns ``cols`` into ``mean``, and the
    standard deviations (two passes, as ``numpy.std``) of the columns ``std_cols`` (indices
    into ``cols``) into ``std``: one pass over the rows instead of a copy per column."""
    mean[:] = 0.0
    for k in range(a, b):
        for j in range(cols.size):
            mean[j] += raw[k, cols[j]]
    mean /= b - a
    std[:] = 0.0
    for k in range(a, b):
        for j in range(std_cols.size):
            d = raw[k, cols[std_cols[j]]] - mean[std_cols[j]]
            std[j] += d * d
    for j in range(std_cols.size):
        std[j] = math.sqrt(std[j] / (b - a))


@numba.njit(cache=True, nogil=True)
def _partition_moments(raw, edges, cols, mean, std_cols, std):
    """:func:`_span_moments` of the whole ``edges[0]:edges[-1]`` (row 0 of ``mean`` and
    ``std``) and of each part ``edges[j]:edges[j+1]`` (row ``j + 1``) in two passes over the
    rows instead of two per span: the parts' sums give the whole's mean, and the second pass
    gathers the squared deviations from both means. The truth's layout (6 means, 2 standard
    deviations) sums in local variables (:func:`_partition_sums_6_2`: a third of the time
    of sums kept in the output arrays, the same additions in the same order)."""
    m = edges.size - 1
    nc, ns = cols.size, std_cols.size
    mean[:] = 0.0
    std[:] = 0.0
    if nc == 6 and ns == 2:
        _partition_sums_6_2(raw, edges, cols, mean, std_cols, std)
    else:
        for j in range(m):
            for k in range(edges[j], edges[j + 1]):
                for c in range(nc):
                    mean[j + 1, c] += raw[k, cols[c]]
        _means_from_sums(edges, mean)
        for j in range(m):
            for k in range(edges[j], edges[j + 1]):
                for c in range(ns):
                    x = raw[k, cols[std_cols[c]]]
                    d = x - mean[j + 1, std_cols[c]]
                    e = x - mean[0, std_cols[c]]
                    std[j + 1, c] += d * d
                    std[0, c] += e * e
    for j in range(m):
        for c in range(ns):
            std[j + 1, c] = math.sqrt(std[j + 1, c] / (edges[j + 1] - edges[j]))
    for c in range(ns):
        std[0, c] = math.sqrt(std[0, c] / (edges[m] - edges[0]))


@numba.njit(cache=True, nogil=True)
def _means_from_sums(edges, mean):
    """Rows ``1..m`` of ``mean`` hold the parts' sums: make them means and row 0 the
    whole's (the sum of the parts' sums over all rows)."""
    m = edges.size - 1
    for j in range(m):
        for c in range(mean.shape[1]):
            mean[0, c] += mean[j + 1, c]
            mean[j + 1, c] /= edges[j + 1] - edges[j]
    for c in range(mean.shape[1]):
        mean[0, c] /= edges[m] - edges[0]


@numba.njit(cache=True, nogil=True)
def _partition_sums_6_2(raw, edges, cols, mean, std_cols, std):
    """:func:`_partition_moments`' two passes for 6 mean and 2 deviation columns with the
    running sums in local variables (registers) instead of the output arrays; leaves the
    means and the sums of squared deviations (rows as there) in ``mean`` and ``std``."""
    m = edges.size - 1
    c0, c1, c2, c3, c4, c5 = cols[0], cols[1], cols[2], cols[3], cols[4], cols[5]
    for j in range(m):
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        for k in range(edges[j], edges[j + 1]):
            s0 += raw[k, c0]
            s1 += raw[k, c1]
            s2 += raw[k, c2]
            s3 += raw[k, c3]
            s4 += raw[k, c4]
            s5 += raw[k, c5]
        mean[j + 1, 0], mean[j + 1, 1], mean[j + 1, 2] = s0, s1, s2
        mean[j + 1, 3], mean[j + 1, 4], mean[j + 1, 5] = s3, s4, s5
    _means_from_sums(edges, mean)
    a0, a1 = std_cols[0], std_cols[1]
    k0, k1 = cols[a0], cols[a1]
    w0 = w1 = 0.0  # the whole's
    for j in range(m):
        p0 = p1 = 0.0  # the part's
        mj0, mj1, mw0, mw1 = mean[j + 1, a0], mean[j + 1, a1], mean[0, a0], mean[0, a1]
        for k in range(edges[j], edges[j + 1]):
            x = raw[k, k0]
            d = x - mj0
            e = x - mw0
            p0 += d * d
            w0 += e * e
            x = raw[k, k1]
            d = x - mj1
            e = x - mw1
            p1 += d * d
            w1 += e * e
        std[j + 1, 0], std[j + 1, 1] = p0, p1
    std[0, 0], std[0, 1] = w0, w1


#: fit samples between exact evaluations of the basis's sines (rotated in between)
_BASIS_EXACT = 256


@numba.njit(cache=True, nogil=True)
def _fit_basis(t, w, wob, theta, x):
    """The truth fit's basis at times ``t`` [s] (equally spaced) and platform angles
    ``theta`` [rad] into ``x``: ``cos(w*t)``, ``sin(w*t)``, 1, then per wobble row
    (:func:`~torquemod.twins.vtrack.rig.dynamics.wobble_table`) cos and sin of ``rate*t`` (band
    rows) or
    ``order*theta`` (revolution rows) -- :func:`~torquemod.twins.vtrack.rig.dynamics.wobble_basis`
    and the
    modulation's columns, each sine rotated from sample to sample (through ``rate*dt``, whose
    small-angle sin and cos are computed once per column, or the angle's small increment,
    :mod:`torquemod.twins.vtrack.rig.kernels`) and exact every ``_BASIS_EXACT`` samples."""
    n = t.size
    nw = wob.shape[0]
    dt = t[1] - t[0] if n > 1 else 0.0
    m1 = nw + 1
    rates = np.empty(m1)
    rev = np.zeros(m1, dtype=np.bool_)
    rates[0] = w
    for j in range(nw):
        rates[j + 1] = wob[j, 1]
        rev[j + 1] = wob[j, 3] > 0.5
    # time columns turn by the same rates[j]*dt every sample
    c_dt, s_dt = np.empty(m1), np.empty(m1)
    small = np.zeros(m1, dtype=np.bool_)
    for j in range(m1):
        d = rates[j] * dt
        small[j] = abs(d) <= SMALL
        c_dt[j], s_dt[j] = cos_small(d), sin_small(d)
    c, s = np.empty(m1), np.empty(m1)
    for k in range(n):
        exact = k % _BASIS_EXACT == 0
        for j in range(m1):
            if rev[j]:
                d = rates[j] * (theta[k] - theta[k - 1]) if k > 0 else 0.0
                if exact or not abs(d) <= SMALL:
                    arg = rates[j] * theta[k]
                    c[j], s[j] = math.cos(arg), math.sin(arg)
                else:
                    cd, sd = cos_small(d), sin_small(d)
                    c[j], s[j] = c[j] * cd - s[j] * sd, s[j] * cd + c[j] * sd
            elif exact or not small[j]:
                arg = rates[j] * t[k]
                c[j], s[j] = math.cos(arg), math.sin(arg)
            else:
                cd, sd = c_dt[j], s_dt[j]
                c[j], s[j] = c[j] * cd - s[j] * sd, s[j] * cd + c[j] * sd
        x[k, 0], x[k, 1], x[k, 2] = c[0], s[0], 1.0
        for j in range(nw):
            x[k, 3 + 2 * j], x[k, 4 + 2 * j] = c[j + 1], s[j + 1]


_MEAN_COLS = np.array([_COL[c] for c in _MEANS])
_STD_COLS = np.array([_MEANS.index("creepage"), _MEANS.index("platform_speed_rad_s")])


#: rows of the fit taken per load and store of each sum (:func:`_add_rows8`)
_ROWS = 8


@numba.njit(cache=True, nogil=True)
def _add_rows8(x, i, sg):
    """Add rows ``i..i+7`` of ``x`` (the fit's basis, then torque and speed, padded with
    zeros) to ``sg[p, q] = sum x[:, p]*x[:, q]`` for every basis column ``p``: each sum is
    loaded and stored once for the eight rows and takes their products one row after the
    other, as eight single-row updates would (the same additions in the same order). The
    loop over ``q`` runs over whole rows of ``sg`` (the lower triangle is computed too and
    never read), so that it compiles to vector instructions across the sums."""
    r0, r1, r2, r3 = x[i], x[i + 1], x[i + 2], x[i + 3]
    r4, r5, r6, r7 = x[i + 4], x[i + 5], x[i + 6], x[i + 7]
    w = x.shape[1]
    for p in range(sg.shape[0]):
        b0, b1, b2, b3 = r0[p], r1[p], r2[p], r3[p]
        b4, b5, b6, b7 = r4[p], r5[p], r6[p], r7[p]
        row = sg[p]
        for q in range(w):
            row[q] = (((((((row[q] + b0 * r0[q]) + b1 * r1[q]) + b2 * r2[q]) + b3 * r3[q])
                        + b4 * r4[q]) + b5 * r5[q]) + b6 * r6[q]) + b7 * r7[q]


@numba.njit(cache=True, nogil=True)
def _fit_sums(raw, t0_s, fs, stride, w, wob, coef, cols, win_lo, win_hi, gram, rhs, ref):
    """The truth fit's normal equations over windows of one step, without the GIL.

    The fit's samples are the rows ``i*stride`` of ``raw`` (sample ``k`` at
    ``t0_s + k/fs`` [s]); their basis is :func:`_fit_basis` (modulation cos, sin, DC, then the
    wobble rows of ``wob``; ``cols = (platform angle, torque, wheel speed)`` columns of
    ``raw``). For each window ``j`` (fit samples ``win_lo[j] <= i < win_hi[j]``):
    ``gram[j] = X^T X`` and ``rhs[j] = X^T [torque, speed]``. ``ref[i]``: the speed
    reference's wobble at fit sample ``i``, ``X[i, 3:] @ coef``. The windows overlap (the
    whole step and its revolutions), so the sums are taken over the pieces between
    consecutive window edges (each sample once, row after row) and added up per window.
    Torque and speed ride as two more columns of the basis (``X^T [torque, speed]`` are
    then columns of the same sums: ``x_p*u`` is the product ``u*x_p`` bit for bit), the
    rows padded to a multiple of 8 columns for :func:`_add_rows8`."""
    n = (raw.shape[0] + stride - 1) // stride
    m = 3 + 2 * wob.shape[0]
    width = (m + 2 + 7) // 8 * 8
    t, theta = np.empty(n), np.empty(n)
    for i in range(n):
        t[i] = t0_s + (i * stride) / fs
        theta[i] = raw[i * stride, cols[0]]
    x = np.zeros((n, width))
    _fit_basis(t, w, wob, theta, x)
    for i in range(n):
        x[i, m] = raw[i * stride, cols[1]]
        x[i, m + 1] = raw[i * stride, cols[2]]
        r = 0.0
        for q in range(m - 3):
            r += x[i, 3 + q] * coef[q]
        ref[i] = r
    edges = np.unique(np.concatenate((win_lo, win_hi)))
    nseg = edges.size - 1
    sg = np.zeros((max(nseg, 1), m, width))
    nw = win_lo.size
    gram[:] = 0.0
    rhs[:] = 0.0
    for g in range(nseg):
        i, hi = edges[g], edges[g + 1]
        sgg = sg[g]
        while i + _ROWS <= hi:  # eight rows per load and store of each sum, row by row
            _add_rows8(x, i, sgg)
            i += _ROWS
        while i < hi:
            for p in range(m):
                bp = x[i, p]
                for q in range(width):
                    sgg[p, q] += bp * x[i, q]
            i += 1
        for j in range(nw):
            if win_lo[j] <= edges[g] and edges[g + 1] <= win_hi[j]:
                for p in range(m):
                    for q in range(m):
                        gram[j, p, q] += sgg[p, q]
                    rhs[j, p, 0] += sgg[p, m]
                    rhs[j, p, 1] += sgg[p, m + 1]
    for j in range(nw):
        for p in range(m):
            for q in range(p):
                gram[j, p, q] = gram[j, q, p]


def _phase_from_sums(gram: np.ndarray, rhs: np.ndarray) -> float:
    """:func:`~.truthphase._phase_from_basis` from its normal equations (``gram = X^T X``,
    ``rhs = X^T [torque, speed]``)."""
    coef = np.linalg.lstsq(gram, rhs, rcond=1e-12)[0]
    ang = np.angle(coef[0] - 1j * coef[1])
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


def _spans_truth(raw: np.ndarray, t0_s: float, config: SimConfig, wobble: np.ndarray,
                 spans: list[tuple[int, int]]) -> list[dict]:
    """What was simulated over each span ``(a, b)`` of sample indices into ``raw`` (sample 0
    at ``t0_s`` [s]): means, CoA of the mean forces, the phase with the wobble fitted out
    (:func:`~.truthphase.wobble_free_phase_deg`: least squares on every
    ``WOBBLE_FIT_STRIDE``-th sample of the span's whole modulation periods), the creepage's
    and the platform speed's variation (``std``; the latter ``/mean`` [%]) and that of the
    speed reference over the same samples
    (``amp*sin(arg + ph) = amp*(sin(arg)*cos(ph) + cos(arg)*sin(ph))`` from the fit's basis).
    The sums run in compiled kernels that release the GIL (:func:`_fit_sums`,
    :func:`_partition_moments`), so that steps finish side by side."""
    f, fs = config.modulation.actual_frequency_hz, config.sensors.sample_rate_hz
    w0 = config.rig.platform_speed_rad_s
    stride = WOBBLE_FIT_STRIDE
    n_fit = (raw.shape[0] + stride - 1) // stride
    nw = wobble.shape[0]
    ref = np.zeros(n_fit)
    if nw:
        windows = []
        for a, b in spans:
            n = int(np.floor((b - a) / fs * f) * fs / f)  # whole modulation periods
            windows.append((-(-a // stride), -(-(a + n) // stride)))
        lo, hi = (np.array(v, dtype=np.int64) for v in zip(*windows, strict=True))
        m = 3 + 2 * nw
        gram, rhs = np.empty((len(spans), m, m)), np.empty((len(spans), m, 2))
        wob = np.ascontiguousarray(wobble, dtype=np.float64)
        coef = np.column_stack([wob[:, 0] * np.sin(wob[:, 2]),
                                wob[:, 0] * np.cos(wob[:, 2])]).ravel()
        _fit_sums(raw, t0_s, fs, stride, 2.0 * np.pi * f, wob, coef, _FIT_COLS, lo, hi,
                  gram, rhs, ref)
    edges = [a for a, _ in spans[1:]] + [spans[-1][1]] if len(spans) > 1 else []
    partition = (len(spans) > 1 and spans[0] == (edges[0], edges[-1])
                 and all(spans[j][1] == spans[j + 1][0] for j in range(1, len(spans) - 1)))
    if partition:  # the whole and its revolutions: two passes in all
        means = np.empty((len(spans), _MEAN_COLS.size))
        stds = np.empty((len(spans), _STD_COLS.size))
        _partition_moments(raw, np.array(edges, dtype=np.int64), _MEAN_COLS, means,
                           _STD_COLS, stds)
    out = []
    for i, (a, b) in enumerate(spans):
        if partition:
            mean, std = means[i], stds[i]
        else:
            mean, std = np.empty(_MEAN_COLS.size), np.empty(_STD_COLS.size)
            _span_moments(raw, a, b, _MEAN_COLS, mean, _STD_COLS, std)
        m = dict(zip(_MEANS, mean.tolist(), strict=True))
        if nw:
            phase = _phase_from_sums(gram[i], rhs[i])
        else:
            seg = raw[a:b]
            phase = sine_fit_phase_deg(seg[:, _COL["torque_nm"]],
                                       seg[:, _COL["wheel_speed_rad_s"]], fs, f)
        r = ref[-(-a // stride):-(-b // stride)]
        out.append({"creepage_mean": m["creepage"],
                    "creepage_std": float(std[0]),
                    "coa_mean": float(np.hypot(m["fx_n"], m["fy_n"]) / m["fz_n"]),
                    "torque_mean_nm": m["torque_nm"], "fx_mean_n": m["fx_n"],
                    "fy_mean_n": m["fy_n"], "fz_mean_n": m["fz_n"], "phase_deg": phase,
                    "platform_speed_rms_pct": float(100.0 * std[1]
                                                    / m["platform_speed_rad_s"]),
                    "reference_rms_pct": float(100.0 * r.std() / w0) if r.size else 0.0})
    return out


def _large_signal(dc: float, config: SimConfig) -> float | None:
    """Phase [deg] at the actual modulation amplitude (periodic steady state of the same
    model, driven by the motor as in the simulation; :func:`large_signal_phase_deg`)."""
    res = large_signal_phase_deg(dc, config.rig, config.modulation.actual_frequency_hz,
                                 config.modulation.amplitude_nm, drive="motor")
    return None if res.slipped else float(res.phase_deg)


def step_truth(i_step: int, dc: float, config: SimConfig, raw: np.ndarray | None,
                slipped: bool, t0_s: float = 0.0, wobble: np.ndarray | None = None,
                bounds: list[int] = (0, 0), large_signal: bool = True) -> dict:
    """Ground truth of one step: the steady state and theory at ``dc`` and, when not
    ``slipped``, what was simulated over the recorded samples ``raw`` (from ``t0_s`` [s]) and
    per platform revolution (``bounds``, indices into the step's output, ``raw`` starting
    at ``bounds[0]``); see :func:`_spans_truth`. ``large_signal = False`` leaves the
    large-signal theory phase out (None; its periodic-state solve is most of the theory's
    cost).

    Parameters
    ----------
    i_step : int
        The step.
    dc : float
        DC torque [N*m].
    config : SimConfig
        The twin's configuration.
    raw : ndarray or None
        The recorded true samples.
    slipped : bool
        The step slipped.
    t0_s : float
        Time of ``raw``'s first sample [s]. Default 0.
    wobble : ndarray or None
        The wobble rows.
    bounds : list of int
        Revolution bounds (indices into the step's output).
    large_signal : bool
        Include the large-signal phase. Default True.

    Returns
    -------
    dict
        The step's truth entry.
    """
    rig, f = config.rig, config.modulation.actual_frequency_hz
    op = operating_point(dc, rig)
    k = op.creep_coefficient
    entry = {"step": i_step, "dc_torque_nm": dc, "slipped": bool(slipped),
             "slipped_steady_state": op.slipped}
    if op.slipped:
        entry.update(creepage=None, coa=None, creep_coefficient=None, dcoa_dxi=None,
                     phase_theory_deg=None, phase_rigid_deg=None,
                     phase_large_signal_deg=None)
    else:
        entry.update(
            creepage=op.creepage, coa=op.coa, creep_coefficient=k, dcoa_dxi=op.dcoa_dxi,
            fx_n=op.fx_n, fy_n=op.fy_n,
            phase_theory_deg=float(predicted_phase_deg(k, rig, f, creepage=op.creepage)),
            phase_large_signal_deg=_large_signal(dc, config) if large_signal else None,
            phase_rigid_deg=float(rigid_wheel_phase_deg(
                k, inertia_kg_m2=rig.wheel_inertia_kg_m2, speed_m_s=rig.speed_m_s,
                wheel_radius_m=rig.wheel_radius_m, normal_load_n=rig.normal_load_n,
                frequency_hz=f)))
    if raw is not None and not slipped:
        wob = np.zeros((0, 4)) if wobble is None else wobble
        rel = [(a - bounds[0], b - bounds[0]) for a, b in itertools.pairwise(bounds)]
        spans = [(0, raw.shape[0])] + (rel if len(rel) > 1 else [])
        whole, *cycles = _spans_truth(raw, t0_s, config, wob, spans)
        entry["simulated"] = whole
        if cycles:
            whole["cycles"] = [{"cycle": j, **c} for j, c in enumerate(cycles, start=1)]
    return entry


def recorded_step_truth(i_step: int, dc: float, config: SimConfig, out: np.ndarray,
                        n_done: int, t_step: float, wobble: np.ndarray, n_settle: int,
                        large_signal: bool = True) -> tuple[dict, list[int]]:
    """Truth entry (:func:`step_truth`) of a step that did not slip, integrated into ``out``
    (``n_done`` samples from ``t_step`` [s]) and recorded from sample ``n_settle`` over the
    procedure's platform revolutions; also the revolutions' sample bounds in ``out``.

    Parameters
    ----------
    i_step : int
        The step.
    dc : float
        DC torque [N*m].
    config : SimConfig
        The twin's configuration.
    out : ndarray
        The step's output.
    n_done : int
        Samples integrated [-].
    t_step : float
        Start time [s].
    wobble : ndarray
        The wobble rows.
    n_settle : int
        First recorded sample [-].
    large_signal : bool
        Include the large-signal phase. Default True.

    Returns
    -------
    entry : dict
        The truth entry.
    bounds : list of int
        The revolutions' sample bounds in ``out``.
    """
    bounds = _cycle_bounds(out[:n_done, _COL["platform_angle_rad"]], n_settle,
                           config.procedure.cycles_per_step)
    raw = out[bounds[0]:bounds[-1]]
    t0 = t_step + bounds[0] * (1.0 / config.sensors.sample_rate_hz)
    return step_truth(i_step, dc, config, raw, False, t0, wobble, bounds,
                       large_signal), bounds
