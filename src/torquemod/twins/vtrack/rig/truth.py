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

import numpy as np

from torquemod.twins.vtrack.params import SimConfig
from torquemod.twins.vtrack.rig.dynamics import OUT_COLUMNS
from torquemod.twins.vtrack.rig.truthphase import WOBBLE_FIT_STRIDE, sine_fit_phase_deg
from torquemod.twins.vtrack.rig.truthsums import (
    _fit_basis,  # noqa: F401 - tests read it here
    _fit_sums,
    _partition_moments,
    _span_moments,
    step_sums,
)
from torquemod.twins.vtrack.smallsignal import predicted_phase_deg, rigid_wheel_phase_deg
from torquemod.twins.vtrack.theory import (
    LargeSignalResult,
    large_signal_phase_deg,
    operating_point,
)

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


_MEAN_COLS = np.array([_COL[c] for c in _MEANS])
_STD_COLS = np.array([_MEANS.index("creepage"), _MEANS.index("platform_speed_rad_s")])


def _phase_from_sums(gram: np.ndarray, rhs: np.ndarray) -> float:
    """:func:`~.truthphase._phase_from_basis` from its normal equations (``gram = X^T X``,
    ``rhs = X^T [torque, speed]``)."""
    coef = np.linalg.lstsq(gram, rhs, rcond=1e-12)[0]
    ang = np.angle(coef[0] - 1j * coef[1])
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


def _fit_windows(spans, fs: float, f: float, stride: int, wobble: np.ndarray):
    """The wobble fit's windows and buffers for :func:`_fit_sums`: per span, the first and
    past-the-last index of its ``stride``-th samples over its whole modulation periods
    (``lo``, ``hi``), empty normal equations (``gram`` (S, m, m), ``rhs`` (S, m, 2)), the
    wobble's rows as float64 and their sine/cosine amplitudes (``coef``)."""
    windows = []
    for a, b in spans:
        n = int(np.floor((b - a) / fs * f) * fs / f)  # whole modulation periods
        windows.append((-(-a // stride), -(-(a + n) // stride)))
    lo, hi = (np.array(v, dtype=np.int64) for v in zip(*windows, strict=True))
    m = 3 + 2 * wobble.shape[0]
    gram, rhs = np.empty((len(spans), m, m)), np.empty((len(spans), m, 2))
    wob = np.ascontiguousarray(wobble, dtype=np.float64)
    coef = np.column_stack([wob[:, 0] * np.sin(wob[:, 2]),
                            wob[:, 0] * np.cos(wob[:, 2])]).ravel()
    return lo, hi, gram, rhs, wob, coef


def _whole_phase(raw: np.ndarray, t0_s: float, config: SimConfig, wobble: np.ndarray,
                 spans: list[tuple[int, int]]) -> float:
    """``phase_deg`` of :func:`_spans_truth`'s first span (the whole step) alone, the same
    value bit for bit: the fit's sums over the same windows (the revolutions' edges cut the
    sums into the same pieces) by :func:`_fit_sums`, which gives :func:`step_sums`' sums
    exactly, without the moments and the revolutions' own solves."""
    f, fs = config.modulation.actual_frequency_hz, config.sensors.sample_rate_hz
    nw = wobble.shape[0]
    if not nw:
        a, b = spans[0]
        seg = raw[a:b]
        return sine_fit_phase_deg(seg[:, _COL["torque_nm"]], seg[:, _COL["wheel_speed_rad_s"]],
                                  fs, f)
    stride = WOBBLE_FIT_STRIDE
    lo, hi, gram, rhs, wob, coef = _fit_windows(spans, fs, f, stride, wobble)
    ref = np.zeros((raw.shape[0] + stride - 1) // stride)
    _fit_sums(raw, t0_s, fs, stride, 2.0 * np.pi * f, wob, coef, _FIT_COLS, lo, hi, gram, rhs,
              ref)
    return _phase_from_sums(gram[0], rhs[0])


def _spans_truth(raw: np.ndarray, t0_s: float, config: SimConfig, wobble: np.ndarray,
                 spans: list[tuple[int, int]]) -> list[dict]:
    """What was simulated over each span ``(a, b)`` of sample indices into ``raw`` (sample 0
    at ``t0_s`` [s]): means, CoA of the mean forces, the phase with the wobble fitted out
    (:func:`~.truthphase.wobble_free_phase_deg`: least squares on every
    ``WOBBLE_FIT_STRIDE``-th sample of the span's whole modulation periods), the creepage's
    and the platform speed's variation (``std``; the latter ``/mean`` [%]) and that of the
    speed reference over the same samples
    (``amp*sin(arg + ph) = amp*(sin(arg)*cos(ph) + cos(arg)*sin(ph))`` from the fit's basis).
    The sums run in compiled kernels that release the GIL
    (:mod:`torquemod.twins.vtrack.rig.truthsums`), so that steps finish side by side."""
    f, fs = config.modulation.actual_frequency_hz, config.sensors.sample_rate_hz
    w0 = config.rig.platform_speed_rad_s
    stride = WOBBLE_FIT_STRIDE
    n_fit = (raw.shape[0] + stride - 1) // stride
    nw = wobble.shape[0]
    ref = np.zeros(n_fit)
    edges = [a for a, _ in spans[1:]] + [spans[-1][1]] if len(spans) > 1 else []
    partition = (len(spans) > 1 and spans[0] == (edges[0], edges[-1])
                 and all(spans[j][1] == spans[j + 1][0] for j in range(1, len(spans) - 1)))
    if partition:  # the whole and its revolutions: two passes over the samples in all
        edges = np.array(edges, dtype=np.int64)
        means = np.empty((len(spans), _MEAN_COLS.size))
        stds = np.empty((len(spans), _STD_COLS.size))
    if nw:
        lo, hi, gram, rhs, wob, coef = _fit_windows(spans, fs, f, stride, wobble)
        args = (raw, t0_s, fs, stride, 2.0 * np.pi * f, wob, coef, _FIT_COLS, lo, hi, gram,
                rhs, ref)
        if partition:  # the fit's sums and the moments in one sweep
            step_sums(*args, edges, _MEAN_COLS, _STD_COLS, means, stds)
        else:
            _fit_sums(*args)
    if partition and not nw:
        _partition_moments(raw, edges, _MEAN_COLS, means, _STD_COLS, stds)
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


def _large_signal(dc: float, config: SimConfig) -> LargeSignalResult:
    """The periodic steady state at the actual modulation amplitude (the same model, driven
    by the motor as in the simulation; :func:`large_signal_phase_deg`)."""
    return large_signal_phase_deg(dc, config.rig, config.modulation.actual_frequency_hz,
                                  config.modulation.amplitude_nm, drive="motor")


def step_truth(i_step: int, dc: float, config: SimConfig, raw: np.ndarray | None,
                slipped: bool, t0_s: float = 0.0, wobble: np.ndarray | None = None,
                bounds: list[int] = (0, 0), large_signal: bool = True,
                statistics: bool = True) -> dict:
    """Ground truth of one step: the steady state and theory at ``dc`` and, when not
    ``slipped``, what was simulated over the recorded samples ``raw`` (from ``t0_s`` [s]) and
    per platform revolution (``bounds``, indices into the step's output, ``raw`` starting
    at ``bounds[0]``); see :func:`_spans_truth`. ``large_signal = False`` leaves the
    large-signal theory phase out (None; its periodic-state solve is most of the theory's
    cost); ``statistics = False`` keeps of what was simulated the phase alone
    (``simulated = {"phase_deg": ...}``, the same value; no means, variations or
    revolutions).

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
    statistics : bool
        Include the simulated means, variations and revolutions besides the phase.
        Default True.

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
        # the large-signal solve carries the small-signal phase (the same computation)
        ls = _large_signal(dc, config) if large_signal else None
        entry.update(
            creepage=op.creepage, coa=op.coa, creep_coefficient=k, dcoa_dxi=op.dcoa_dxi,
            fx_n=op.fx_n, fy_n=op.fy_n,
            phase_theory_deg=(ls.small_signal_phase_deg if ls is not None else
                              float(predicted_phase_deg(k, rig, f, creepage=op.creepage))),
            phase_large_signal_deg=(None if ls is None or ls.slipped
                                    else float(ls.phase_deg)),
            phase_rigid_deg=float(rigid_wheel_phase_deg(
                k, inertia_kg_m2=rig.wheel_inertia_kg_m2, speed_m_s=rig.speed_m_s,
                wheel_radius_m=rig.wheel_radius_m, normal_load_n=rig.normal_load_n,
                frequency_hz=f)))
    if raw is not None and not slipped:
        wob = np.zeros((0, 4)) if wobble is None else wobble
        rel = [(a - bounds[0], b - bounds[0]) for a, b in itertools.pairwise(bounds)]
        spans = [(0, raw.shape[0])] + (rel if len(rel) > 1 else [])
        if not statistics:
            entry["simulated"] = {"phase_deg": _whole_phase(raw, t0_s, config, wob, spans)}
            return entry
        whole, *cycles = _spans_truth(raw, t0_s, config, wob, spans)
        entry["simulated"] = whole
        if cycles:
            whole["cycles"] = [{"cycle": j, **c} for j, c in enumerate(cycles, start=1)]
    return entry


def recorded_step_truth(i_step: int, dc: float, config: SimConfig, out: np.ndarray,
                        n_done: int, t_step: float, wobble: np.ndarray, n_settle: int,
                        large_signal: bool = True,
                        statistics: bool = True) -> tuple[dict, list[int]]:
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
    statistics : bool
        Include the simulated statistics besides the phase (:func:`step_truth`). Default
        True.

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
                      large_signal, statistics), bounds
