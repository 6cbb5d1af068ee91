"""``torquemod simulate``: run the V-Track digital twin and write an experiment folder.

Public entry points (the CLI in :mod:`torquemod.cli` only parses arguments and calls these):

* :func:`default_config_text` -- the commented default TOML (package data
  ``torquemod/data/vtrack_default.toml``),
* :func:`load_config` -- default config, optionally overridden by a user TOML file,
* :func:`run_simulation` -- simulate the procedure and write ``experiment.toml``, one file per
  recording and ``truth.json`` (the simulated ground truth per step).

``truth.json`` holds the run's speed-loop wobble (``speed_wobble``: configuration, realised
terms, reference RMS) and per step the steady state, the theory phases and what was simulated
(``simulated``: means, CoA, the phase with the wobble fitted out, the platform speed's RMS
variation), also per platform revolution (``simulated.cycles``).

Recordings of a step in which the wheel slips are *not* written; the step appears in
``truth.json`` with ``slipped = true`` and the procedure stops there (as the paper's test did).
"""

from __future__ import annotations

import copy
import itertools
import math
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from importlib import resources
from pathlib import Path

import numba
import numpy as np

from . import __version__
from .checks import positive_number
from .contact.hertz import hertz_ellipse
from .contact.kalker import kalker_coefficients
from .contact.presets import polach_preset
from .data import Recording
from .errors import InputError
from .fsutil import atomic_dir
from .io import write_manifest, write_recording
from .jsonutil import dump_json
from .rig.dynamics import (
    OUT_COLUMNS,
    initial_state,
    integrate,
    pack_parameters,
    wobble_basis,
    wobble_reference,
    wobble_table,
)
from .rig.params import (
    ContactParams,
    DisturbanceParams,
    ModulationParams,
    ProcedureParams,
    RigParams,
    SensorParams,
    SimConfig,
)
from .rig.sensors import measure
from .theory import (
    creep_curve_peak,
    large_signal_phase_deg,
    operating_point,
    predicted_phase_deg,
    rigid_wheel_phase_deg,
)

_POLACH_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")
_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}
_SUFFIX = {"csv": ".csv", "hdf5": ".h5"}


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

def default_config_text() -> str:
    """The default configuration (V-Track) as commented TOML text."""
    return (resources.files("torquemod") / "data" / "vtrack_default.toml").read_text("utf-8")


def _parse(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # the message names line and column
        raise InputError(f"TOML syntax error: {exc}", path=where,
                         hint="fix the line named") from None


def _check_and_merge(default: dict, user: dict, where: str) -> dict:
    merged = copy.deepcopy(default)
    for section, table in user.items():
        if section not in default:
            raise InputError(f"unknown section [{section}]", path=where,
                             hint=f"known sections: {', '.join(default)}")
        if not isinstance(table, dict):
            raise InputError(f"'{section}' must be a table", path=where)
        for key, value in table.items():
            if key not in default[section]:
                raise InputError(f"unknown key '{section}.{key}'", path=where,
                                 hint=f"known keys in [{section}]: "
                                      f"{', '.join(default[section])}")
            ref = default[section][key]
            ok = (isinstance(value, bool) if isinstance(ref, bool)
                  else isinstance(value, str) if isinstance(ref, str)
                  else isinstance(value, list) if isinstance(ref, list)
                  else isinstance(value, int | float) and not isinstance(value, bool))
            if isinstance(ref, int) and not isinstance(ref, bool) and ok:
                ok = isinstance(value, int)
            if not ok:
                raise InputError(f"'{section}.{key}' has the wrong type ({value!r}); the "
                                 f"default is {ref!r}", path=where)
            merged[section][key] = value
    # a preset chosen by the user fills the Polach values it does not give itself
    if "preset" in user.get("contact", {}):
        vals = polach_preset(user["contact"]["preset"]).as_dict()
        for k in _POLACH_KEYS:
            merged["contact"][k] = user["contact"].get(k, vals[k])
    return merged


def _positive(doc: dict, section: str, key: str, where: str, *, allow_zero=False) -> float:
    return positive_number(doc[section][key], f"{section}.{key}", path=where,
                           allow_zero=allow_zero)


def _contact(doc: dict, rig: dict, where: str) -> ContactParams:
    c = doc["contact"]
    e_mod = _positive(doc, "contact", "youngs_modulus_pa", where)
    nu = float(c["poisson_ratio"])
    a, b = float(c["semi_axis_a_m"]), float(c["semi_axis_b_m"])
    if a > 0 and b > 0:
        pass
    elif a == 0 and b == 0:
        rw_t = _positive(doc, "contact", "wheel_transverse_radius_m", where, allow_zero=True)
        rr_t = _positive(doc, "contact", "rail_transverse_radius_m", where, allow_zero=True)
        ky = (1.0 / rw_t if rw_t > 0 else 0.0) + (1.0 / rr_t if rr_t > 0 else 0.0)
        if ky <= 0:
            raise InputError("the contact needs a lateral curvature: give "
                             "rail_transverse_radius_m or wheel_transverse_radius_m > 0",
                             path=where)
        el = hertz_ellipse(float(rig["normal_load_n"]),
                           curvature_x_1_m=1.0 / float(rig["wheel_radius_m"]),
                           curvature_y_1_m=ky, youngs_modulus_pa=e_mod, poisson_ratio=nu)
        a, b = el.a_m, el.b_m
    else:
        raise InputError("give both contact.semi_axis_a_m and semi_axis_b_m (> 0) or neither",
                         path=where)
    kc = kalker_coefficients(a / b, nu)
    for k in _POLACH_KEYS:
        _positive(doc, "contact", k, where, allow_zero=(k == "b_s_m"))
    return ContactParams(mu0=float(c["mu0"]), a_ratio=float(c["a_ratio"]),
                         b_s_m=float(c["b_s_m"]), k_a=float(c["k_a"]), k_s=float(c["k_s"]),
                         shear_modulus_pa=e_mod / (2.0 * (1.0 + nu)), a_m=a, b_m=b,
                         c11=kc.c11, c22=kc.c22, lateral_creepage=float(c["lateral_creepage"]),
                         preset=str(c["preset"]))


def config_from_dict(doc: dict, *, where: str = "<config>") -> SimConfig:
    """Build a :class:`SimConfig` from a complete (merged) configuration dict."""
    r = doc["rig"]
    for key in r:
        _positive(doc, "rig", key, where)
    rig = RigParams(
        wheel_radius_m=float(r["wheel_radius_m"]), platform_radius_m=float(r["platform_radius_m"]),
        speed_m_s=float(r["speed_km_h"]) / 3.6, normal_load_n=float(r["normal_load_n"]),
        wheel_inertia_kg_m2=float(r["wheel_inertia_kg_m2"]),
        drive_inertia_kg_m2=float(r["drive_inertia_kg_m2"]),
        shaft_stiffness_nm_rad=float(r["shaft_stiffness_nm_rad"]),
        shaft_damping_nm_s_rad=float(r["shaft_damping_nm_s_rad"]),
        platform_inertia_kg_m2=float(r["platform_inertia_kg_m2"]),
        platform_kp_nm_s_rad=float(r["platform_kp_nm_s_rad"]),
        platform_ki_nm_rad=float(r["platform_ki_nm_rad"]),
        rolling_resistance_nm=float(r["rolling_resistance_nm"]),
        contact=_contact(doc, r, where))
    m = doc["modulation"]
    modulation = ModulationParams(amplitude_nm=float(m["amplitude_nm"]),
                                  frequency_hz=_positive(doc, "modulation", "frequency_hz", where),
                                  frequency_offset=float(m["frequency_offset"]),
                                  random_phase=bool(m["random_phase"]))
    d = dict(doc["disturbances"])
    dist = DisturbanceParams(**{k: (v if isinstance(v, bool | int) else
                                    tuple(float(x) for x in v) if isinstance(v, list)
                                    else float(v)) for k, v in d.items()})
    band = dist.speed_wobble_band_hz
    if len(band) != 2 or not 0 < band[0] <= band[1]:
        raise InputError(f"disturbances.speed_wobble_band_hz must be [low, high] with "
                         f"0 < low <= high, got {list(band)}", path=where)
    if (min(dist.speed_wobble_rms, dist.speed_wobble_rev1, dist.speed_wobble_rev2) < 0
            or dist.speed_wobble_components < 0):
        raise InputError("disturbances.speed_wobble_* amplitudes and components must be zero "
                         "or positive", path=where)
    for key in doc["sensors"]:
        _positive(doc, "sensors", key, where, allow_zero=(key != "sample_rate_hz"))
    sensors = SensorParams(**{k: float(v) for k, v in doc["sensors"].items()})
    p = doc["procedure"]
    torques = p["dc_torques_nm"]
    if not torques or not all(isinstance(x, int | float) and not isinstance(x, bool)
                              and math.isfinite(x) for x in torques):
        raise InputError("'procedure.dc_torques_nm' must be a non-empty list of numbers",
                         path=where)
    if p["cycles_per_step"] < 1 or p["substeps"] < 1 or p["samples_per_step"] < 1:
        raise InputError("'procedure.cycles_per_step', 'substeps' and 'samples_per_step' must "
                         "be >= 1", path=where)
    procedure = ProcedureParams(dc_torques_nm=tuple(float(x) for x in torques),
                                cycles_per_step=int(p["cycles_per_step"]),
                                settle_s=_positive(doc, "procedure", "settle_s", where,
                                                   allow_zero=True),
                                ramp_s=_positive(doc, "procedure", "ramp_s", where,
                                                 allow_zero=True),
                                slip_creepage=_positive(doc, "procedure", "slip_creepage", where),
                                substeps=int(p["substeps"]),
                                samples_per_step=int(p["samples_per_step"]))
    _check_step(rig, sensors, procedure, where)
    return SimConfig(rig=rig, modulation=modulation, disturbances=dist, sensors=sensors,
                     procedure=procedure)


#: largest |lambda*h| accepted for the integrator (RK4 is stable to 2.78 on the real axis)
MAX_LAMBDA_H = 2.0


def stiffest_rate(rig: RigParams) -> float:
    """Estimate [1/s] of the fastest eigenvalue of the twin's equations: the platform's PI
    loop ``Kp/Jp``, the torsional mode ``sqrt(k/J) + c/J`` (``1/J = 1/Jm + 1/Jw``) or the
    creep-force damping ``(Rw^2/Jw + Rp^2/Jp)*dFx/dxi/V`` at zero creepage."""
    c = rig.contact
    inv_j = 1.0 / rig.drive_inertia_kg_m2 + 1.0 / rig.wheel_inertia_kg_m2
    torsion = math.sqrt(rig.shaft_stiffness_nm_rad * inv_j) + rig.shaft_damping_nm_s_rad * inv_j
    kx = 2.0 * (c.k_a + c.k_s) * c.stiffness_x_n / math.pi  # dFx/dxi at 0, P05 Eq. (8)
    contact = (rig.wheel_radius_m ** 2 / rig.wheel_inertia_kg_m2
               + rig.platform_radius_m ** 2 / rig.platform_inertia_kg_m2) * kx / rig.speed_m_s
    return max(rig.platform_kp_nm_s_rad / rig.platform_inertia_kg_m2, torsion, contact)


def _check_step(rig: RigParams, sensors: SensorParams, proc: ProcedureParams,
                where: str) -> None:
    h = proc.samples_per_step / (proc.substeps * sensors.sample_rate_hz)
    lam_h = stiffest_rate(rig) * h
    if lam_h > MAX_LAMBDA_H:
        raise InputError(f"integrator step {h:.3g} s too long for the rig's fastest mode "
                         f"(lambda*h = {lam_h:.2f} > {MAX_LAMBDA_H})", path=where,
                         hint="lower procedure.samples_per_step or raise procedure.substeps")


def load_config(path: str | Path | None = None, *, overrides: dict | None = None) -> SimConfig:
    """The default configuration, overridden by the TOML file ``path`` (any subset of keys)
    and then by ``overrides`` (a dict of the same layout, for programs and tests).

    Unknown sections or keys and TOML syntax errors raise :class:`InputError` naming the key
    or the line.
    """
    default = _parse(default_config_text(), "vtrack_default.toml")
    merged = default
    where = "<default>"
    if path is not None:
        path = Path(path)
        where = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read the configuration ({exc})", path=path) from None
        merged = _check_and_merge(default, _parse(text, where), where)
    if overrides:
        merged = _check_and_merge(merged, overrides, "<overrides>")
    return config_from_dict(merged, where=where)


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------

def _cycle_bounds(theta: np.ndarray, start: int, cycles: int) -> list[int]:
    """Sample indices where the platform angle has advanced by whole revolutions from
    ``theta[start]``: ``[start, i1, ..., i_cycles]``."""
    th0 = theta[start]
    targets = th0 + 2.0 * np.pi * np.arange(1, cycles + 1)
    idx = start + np.searchsorted(theta[start:], targets)
    if idx[-1] >= theta.size:
        raise RuntimeError("simulated segment too short for the requested revolutions")
    return [start, *(int(i) for i in idx)]


@numba.njit(cache=True)
def _sine_fit_sums(x, y, n, dw, gram, rhs):
    """Normal equations of the fit of ``cos(k*dw)``, ``sin(k*dw)``, 1 to ``x[:n]`` and
    ``y[:n]``: ``gram`` (3, 3) and ``rhs`` (3, 2). The basis is rotated sample by sample
    (exact sin/cos every 1024 samples); each signal is taken relative to its first sample
    (absorbed by the DC term) to keep the sums well conditioned."""
    cr, sr = math.cos(dw), math.sin(dw)
    gram[:] = 0.0
    rhs[:] = 0.0
    c, s = 1.0, 0.0
    x0, y0 = x[0], y[0]
    for k in range(n):
        if k % 1024 == 0:
            c, s = math.cos(k * dw), math.sin(k * dw)
        gram[0, 0] += c * c
        gram[0, 1] += c * s
        gram[0, 2] += c
        gram[1, 1] += s * s
        gram[1, 2] += s
        u, v = x[k] - x0, y[k] - y0
        rhs[0, 0] += u * c
        rhs[1, 0] += u * s
        rhs[2, 0] += u
        rhs[0, 1] += v * c
        rhs[1, 1] += v * s
        rhs[2, 1] += v
        c, s = c * cr - s * sr, s * cr + c * sr
    gram[1, 0] = gram[0, 1]
    gram[2, 0] = gram[0, 2]
    gram[2, 1] = gram[1, 2]
    gram[2, 2] = n


def sine_fit_phase_deg(torque: np.ndarray, speed: np.ndarray, fs_hz: float,
                       frequency_hz: float) -> float:
    """Phase [deg] of ``speed`` behind ``torque`` at ``frequency_hz`` by a least-squares fit
    of cos, sin and DC to each signal over the largest whole number of periods (IEEE Std 1057
    three-parameter fit, FACTS.md §5; solved by its 3x3 normal equations). Positive when the
    speed lags."""
    n = int(np.floor(torque.size / fs_hz * frequency_hz) * fs_hz / frequency_hz)
    if n < 3 or speed.size < n:
        raise ValueError("sine fit needs one whole period of both signals")
    gram, rhs = np.empty((3, 3)), np.empty((3, 2))
    _sine_fit_sums(np.asarray(torque, dtype=np.float64), np.asarray(speed, dtype=np.float64),
                   n, 2.0 * np.pi * frequency_hz / fs_hz, gram, rhs)
    coef = np.linalg.solve(gram, rhs)
    ang = np.angle(coef[0] - 1j * coef[1])  # x = A cos(w + phi) -> a = A cos phi, b = -A sin phi
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


#: the wobble-aware truth fit uses every 8th sample (2 kHz at 16 670 Hz): every simulated line
#: (modulation, its harmonics, the 15-100 Hz load and torsional lines) lies far below the
#: decimated Nyquist frequency, so no alias lands on the modulation frequency
_WOBBLE_FIT_STRIDE = 8


def _phase_from_basis(x: np.ndarray, torque: np.ndarray, speed: np.ndarray) -> float:
    """Phase [deg] of ``speed`` behind ``torque`` from a least-squares fit of the basis ``x``
    whose first two columns are cos and sin at the modulation frequency."""
    # normal equations solved by SVD: two wobble lines closer than the window resolves are
    # near-collinear, which leaves the modulation's coefficients (orthogonal to them) intact
    coef = np.linalg.lstsq(x.T @ x, x.T @ np.column_stack([torque, speed]), rcond=1e-12)[0]
    ang = np.angle(coef[0] - 1j * coef[1])  # x = A cos(w + phi) -> a = A cos phi, b = -A sin phi
    return float((np.degrees(ang[0] - ang[1]) + 180.0) % 360.0 - 180.0)


def wobble_free_phase_deg(torque: np.ndarray, speed: np.ndarray, theta_rad: np.ndarray,
                          fs_hz: float, frequency_hz: float, wobble: np.ndarray, *,
                          t0_s: float = 0.0) -> float:
    """:func:`sine_fit_phase_deg` with the speed loop's wobble (rows of
    :func:`~torquemod.rig.dynamics.wobble_table`) fitted alongside: cos, sin and DC at
    ``frequency_hz`` plus cos and sin at every wobble line (band rows at their rate in time
    from ``t0_s`` [s], revolution rows at their order of the platform angle ``theta_rad``), so
    that the wobble's leakage into the modulation line (up to 0.5 deg over three revolutions at
    the default 0.2 % RMS, measured) stays out of the truth. Linear least squares on every
    ``_WOBBLE_FIT_STRIDE``-th sample of the same whole modulation periods; without wobble rows
    it is :func:`sine_fit_phase_deg`."""
    if wobble.shape[0] == 0:
        return sine_fit_phase_deg(torque, speed, fs_hz, frequency_hz)
    n = int(np.floor(torque.size / fs_hz * frequency_hz) * fs_hz / frequency_hz)
    idx = np.arange(0, n, _WOBBLE_FIT_STRIDE)
    t = t0_s + idx / fs_hz
    w = 2.0 * np.pi * frequency_hz
    x = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones(idx.size),
                         wobble_basis(wobble, t, theta_rad[idx])])
    return _phase_from_basis(x, torque[idx], speed[idx])


def _wobble_truth(config: SimConfig, wobble: np.ndarray) -> dict:
    """truth.json's record of the wobble drawn for this run: configuration and realised
    terms; ``reference_rms_pct`` is the RMS of the realised reference over a long run
    (``sqrt(sum amp^2/2)/W0``) [%]."""
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


def _spans_truth(raw: np.ndarray, t0_s: float, config: SimConfig, wobble: np.ndarray,
                 spans: list[tuple[int, int]]) -> list[dict]:
    """What was simulated over each span ``(a, b)`` of sample indices into ``raw`` (sample 0
    at ``t0_s`` [s]): means, CoA of the mean forces, the phase with the wobble fitted out
    (:func:`wobble_free_phase_deg`), the creepage's and the platform speed's variation
    (``std``; the latter ``/mean`` [%]) and that of the speed reference over the same
    samples. One basis at the fit's stride serves every span."""
    f, fs = config.modulation.actual_frequency_hz, config.sensors.sample_rate_hz
    w0 = config.rig.platform_speed_rad_s
    th = raw[:, _COL["platform_angle_rad"]]
    idx = np.arange(0, raw.shape[0], _WOBBLE_FIT_STRIDE)
    t = t0_s + idx / fs
    ref = wobble_reference(wobble, t, th[idx])
    if wobble.shape[0]:
        w = 2.0 * np.pi * f
        x = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones(idx.size),
                             wobble_basis(wobble, t, th[idx])])
    # the averaged columns as contiguous rows: one strided pass over raw, not one per span
    cols = np.ascontiguousarray(raw[:, [_COL[c] for c in _MEANS]].T)
    out = []
    for a, b in spans:
        seg = raw[a:b]
        m = dict(zip(_MEANS, cols[:, a:b].mean(axis=1).tolist(), strict=True))
        if wobble.shape[0]:
            n = int(np.floor((b - a) / fs * f) * fs / f)  # whole modulation periods
            k = slice(np.searchsorted(idx, a), np.searchsorted(idx, a + n))
            phase = _phase_from_basis(x[k], raw[idx[k], _COL["torque_nm"]],
                                      raw[idx[k], _COL["wheel_speed_rad_s"]])
        else:
            phase = sine_fit_phase_deg(seg[:, _COL["torque_nm"]],
                                       seg[:, _COL["wheel_speed_rad_s"]], fs, f)
        r = ref[np.searchsorted(idx, a):np.searchsorted(idx, b)]
        out.append({"creepage_mean": m["creepage"],
                    "creepage_std": float(cols[0, a:b].std()),
                    "coa_mean": float(np.hypot(m["fx_n"], m["fy_n"]) / m["fz_n"]),
                    "torque_mean_nm": m["torque_nm"], "fx_mean_n": m["fx_n"],
                    "fy_mean_n": m["fy_n"], "fz_mean_n": m["fz_n"], "phase_deg": phase,
                    "platform_speed_rms_pct": float(
                        100.0 * cols[5, a:b].std()
                        / m["platform_speed_rad_s"]),
                    "reference_rms_pct": float(100.0 * r.std() / w0) if r.size else 0.0})
    return out


def _large_signal(dc: float, config: SimConfig) -> float | None:
    """Phase [deg] at the actual modulation amplitude (periodic steady state of the same
    model, driven by the motor as in the simulation; :func:`large_signal_phase_deg`)."""
    res = large_signal_phase_deg(dc, config.rig, config.modulation.actual_frequency_hz,
                                 config.modulation.amplitude_nm, drive="motor")
    return None if res.slipped else float(res.phase_deg)


def _step_truth(i_step: int, dc: float, config: SimConfig, raw: np.ndarray | None,
                slipped: bool, t0_s: float = 0.0, wobble: np.ndarray | None = None,
                bounds: list[int] = (0, 0)) -> dict:
    """Ground truth of one step: the steady state and theory at ``dc`` and, when not
    ``slipped``, what was simulated over the recorded samples ``raw`` (from ``t0_s`` [s]) and
    per platform revolution (``bounds``, indices into the step's output, ``raw`` starting
    at ``bounds[0]``); see :func:`_spans_truth`."""
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
            phase_large_signal_deg=_large_signal(dc, config),
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


def _simulate(config: SimConfig, folder: Path, *, seed: int, fmt: str, progress: bool,
              files_per_cycle: bool) -> dict:
    from tqdm import tqdm

    rig, mod, proc = config.rig, config.modulation, config.procedure
    fs = config.sensors.sample_rate_hz
    dt = 1.0 / fs
    rng = np.random.default_rng(seed)
    params = pack_parameters(rig, config.disturbances)
    torques = proc.dc_torques_nm
    op0 = operating_point(torques[0], rig)
    if op0.slipped:
        op0 = operating_point(0.0, rig)
        t_start = 0.0
    else:
        t_start = torques[0]
    y = initial_state(rig, creepage=op0.creepage, dc_torque_nm=t_start, contact_fx_n=op0.fx_n)
    omega_mod = 2.0 * np.pi * mod.actual_frequency_hz
    n_settle = round(proc.settle_s * fs)
    n_rec = math.ceil((proc.cycles_per_step * rig.revolution_s * 1.01 + 0.1) * fs)
    t, dc_prev = 0.0, t_start
    steps, recordings = [], []
    slip_step = None
    bar = tqdm(total=len(torques), desc="simulate", unit="step", file=sys.stderr,
               disable=not progress)
    # one wobble for the whole run: the rig's speed loop runs on across the steps (redrawn
    # per step, the reference would jump by up to ~1 % of the speed at every step change)
    wobble = wobble_table(config.disturbances, rig.platform_speed_rad_s, rng)
    # the sensor noise has its own stream (a child of the seed's), so that it can be drawn
    # for one step while the next is integrated and the run stays deterministic
    noise_rng = rng.spawn(1)[0]

    def finish(i_step, dc, out, n_done, t_step):
        """Truth, sensor channels and files of a step that did not slip (worker thread)."""
        bounds = _cycle_bounds(out[:n_done, _COL["platform_angle_rad"]], n_settle,
                               proc.cycles_per_step)
        raw = out[bounds[0]:bounds[-1]]
        entry = _step_truth(i_step, dc, config, raw, False, t_step + bounds[0] * dt, wobble,
                            bounds)
        channels = measure(raw, disturbances=config.disturbances, sensors=config.sensors,
                           rng=noise_rng)
        spans = (list(itertools.pairwise(bounds)) if files_per_cycle
                 else [(bounds[0], bounds[-1])])
        recs = []
        for j, (a, b) in enumerate(spans, start=1):
            sl = slice(a - bounds[0], b - bounds[0])
            rec = Recording({k: v[sl] for k, v in channels.items()}, fs_hz=fs,
                            t0_s=t_step + a * dt, source="torquemod simulate")
            name = (f"step{i_step:02d}_cycle{j}" if files_per_cycle else f"step{i_step:02d}")
            file = name + _SUFFIX[fmt]
            if fmt == "hdf5":
                write_recording(folder / file, rec, fmt=fmt, write_time=True)
            else:
                write_recording(folder / file, rec, fmt=fmt)
            rec_entry = {"step": i_step, "dc_torque_nm": dc, "file": file}
            if files_per_cycle:
                rec_entry["cycle"] = j
            recs.append(rec_entry)
        return entry, recs

    # Two-stage pipeline: this thread integrates step after step (the state runs on from one
    # step to the next, so the steps stay sequential), one worker thread computes the truth,
    # draws the noise and writes the files of the step before. The compiled integrator and
    # numpy's noise and array work release the GIL, so the stages overlap on two cores.
    pending = []
    buffers = [np.empty((n_settle + n_rec, len(OUT_COLUMNS))) for _ in range(2)]
    with ThreadPoolExecutor(max_workers=1) as pool:
        try:
            for i_step, dc in enumerate(torques, start=1):
                phase = float(rng.uniform(0.0, 2.0 * np.pi)) if mod.random_phase else 0.0
                # two output buffers in turn: the one of the step before last is free again
                # once the worker has finished that step
                if len(pending) >= 2:
                    pending[-2].result()
                out = buffers[i_step % 2]
                n_done, slipped = integrate(y, t, n_settle + n_rec, dt, proc.substeps, params,
                                            dc_prev, dc, t, proc.ramp_s, mod.amplitude_nm,
                                            omega_mod, phase, t, proc.slip_creepage, out,
                                            proc.samples_per_step, wobble)
                t_step = t
                t += n_done * dt
                dc_prev = dc
                bar.update(1)
                if slipped:
                    slip_step = i_step
                    break
                pending.append(pool.submit(finish, i_step, dc, out, n_done, t_step))
            for fut in pending:  # in step order
                entry, recs = fut.result()
                steps.append(entry)
                recordings.extend(recs)
        finally:
            for fut in pending:
                fut.cancel()
    if slip_step is not None:
        steps.append(_step_truth(slip_step, torques[slip_step - 1], config, None, True))
        steps[-1]["slip_time_s"] = t
    bar.close()
    xi_peak, t_peak = creep_curve_peak(rig)
    truth = {
        "generator": "torquemod simulate", "version": __version__, "seed": seed,
        "format": fmt, "modulation_frequency_actual_hz": mod.actual_frequency_hz,
        "sample_rate_hz": fs, "slip_step": slip_step,
        "creep_curve_peak": {"creepage": xi_peak, "torque_nm": t_peak,
                             "coa": t_peak / (rig.wheel_radius_m * rig.normal_load_n)},
        "speed_wobble": _wobble_truth(config, wobble),
        "steps": steps, "parameters": asdict(config),
    }
    write_manifest(
        folder / "experiment.toml",
        rig={"wheel_radius_m": rig.wheel_radius_m, "platform_radius_m": rig.platform_radius_m,
             # inertia between the torque sensor and the contact: sets the theory constant
             "wheel_inertia_kg_m2": rig.wheel_inertia_kg_m2},
        test={"normal_load_n": rig.normal_load_n, "modulation_frequency_hz": mod.frequency_hz,
              "modulation_amplitude_nm": mod.amplitude_nm},
        recordings=recordings,
        extra={"simulation": {"generator": "torquemod simulate", "version": __version__,
                              "seed": seed, "slip_step": slip_step or 0,
                              "truth": "truth.json"}})
    (folder / "truth.json").write_text(dump_json(truth), encoding="utf-8")
    return truth


def run_simulation(config: SimConfig, out_dir: Path, *, seed: int = 0, fmt: str = "csv",
                   progress: bool = True, files_per_cycle: bool = True,
                   force: bool = False) -> dict:
    """Simulate ``config`` and write the experiment folder ``out_dir``; return the truth dict.

    The folder is written into a temporary sibling and renamed into place at the end, so an
    interrupted run leaves no half-written experiment. An existing non-empty ``out_dir``
    raises :class:`~torquemod.errors.OutputError` unless ``force`` (then it is replaced).
    Deterministic for a given ``seed``.
    """
    if fmt not in _SUFFIX:
        raise InputError(f"unknown output format '{fmt}'", hint="use csv or hdf5")
    out_dir = Path(out_dir)
    with atomic_dir(out_dir, force=force) as tmp:
        truth = _simulate(config, tmp, seed=seed, fmt=fmt, progress=progress,
                          files_per_cycle=files_per_cycle)
    return truth
