"""The V-Track twin's configuration: the default TOML (``data/vtrack_default.toml``), a
user's file merged over it key by key, and the typed :class:`SimConfig` built from the result.

Kept apart from the simulator so that checking a configuration needs neither the compiled
kernels nor the large-signal theory (a bad file is refused before any stage starts).
"""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import replace
from importlib import resources
from pathlib import Path

from torquemod._util.tomlcheck import below_nyquist, between, checked_value, unknown_keys
from torquemod.analysis.contact.hertz import hertz_ellipse
from torquemod.analysis.contact.kalker import kalker_coefficients
from torquemod.analysis.contact.presets import polach_preset
from torquemod.errors import InputError
from torquemod.io.checks import positive_number
from torquemod.twins.vtrack.params import (
    MAX_LAMBDA_H,
    ContactParams,
    DisturbanceParams,
    ModulationParams,
    ProcedureParams,
    RigParams,
    SensorParams,
    SimConfig,
    stiffest_rate,
)

__all__ = ["config_from_dict", "default_config_text", "load_config"]

_POLACH_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")


def default_config_text() -> str:
    """The default configuration (V-Track) as commented TOML text.

    Returns
    -------
    str
        ``torquemod/data/vtrack_default.toml``.
    """
    return (resources.files("torquemod") / "data" / "vtrack_default.toml").read_text("utf-8")


def _parse(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # the message names line and column
        raise InputError(f"TOML syntax error: {exc}", path=where,
                         hint="fix the line named") from None


def _check_and_merge(default: dict, user: dict, where: str) -> dict:
    merged = copy.deepcopy(default)
    unknown_keys(user, default, "the configuration", where, takes="known sections:")
    for section, table in user.items():
        if not isinstance(table, dict):
            raise InputError(f"'{section}' must be a table", path=where)
        unknown_keys(table, default[section], "", where, prefix=f"{section}.",
                     takes=f"[{section}] takes")
        for key, value in table.items():
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
            if any(isinstance(v, float) and not math.isfinite(v)
                   for v in (value if isinstance(value, list) else [value])):
                raise InputError(f"'{section}.{key}' must be finite, got {value!r}",
                                 path=where, hint=f"the default is {ref!r}")
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
    nu = checked_value(c["poisson_ratio"], float, "contact.poisson_ratio", where,
                       between(0.0, 0.5, lo_open=True, hi_open=True))
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
    """Build a :class:`SimConfig` from a complete (merged) configuration dict.

    Parameters
    ----------
    doc : dict
        The configuration, every section and key.
    where : str
        The source, named in messages. Default "<config>".

    Returns
    -------
    SimConfig
        The configuration.

    Raises
    ------
    InputError
        A bad value: the wobble band, negative wobble amplitudes, no DC torques, or
        step counts below 1.
    """
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
    modulation = ModulationParams(
        amplitude_nm=_positive(doc, "modulation", "amplitude_nm", where, allow_zero=True),
        frequency_hz=_positive(doc, "modulation", "frequency_hz", where),
        frequency_offset=checked_value(m["frequency_offset"], float,
                                       "modulation.frequency_offset", where,
                                       between(-0.5, 0.5, lo_open=True, hi_open=True)),
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
    below_nyquist(modulation.actual_frequency_hz, sensors.sample_rate_hz,
                  "modulation.frequency_hz", "sensors.sample_rate_hz", where)
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
    procedure = _check_step(rig, sensors, procedure, where)
    return SimConfig(rig=rig, modulation=modulation, disturbances=dist, sensors=sensors,
                     procedure=procedure)


def _check_step(rig: RigParams, sensors: SensorParams, proc: ProcedureParams,
                where: str) -> ProcedureParams:
    """``proc`` with an RK4 step the rig's fastest mode allows (lambda*h <= MAX_LAMBDA_H):
    ``samples_per_step`` is halved (8, 4, 2, 1) while the step is too long -- a shorter step
    is only more accurate, so a stiffer rig or a lower sample rate just runs slower; refused
    when even one sample per step is too long (raise ``substeps``)."""
    lam = stiffest_rate(rig)
    sps = proc.samples_per_step
    while sps > 1 and lam * sps / (proc.substeps * sensors.sample_rate_hz) > MAX_LAMBDA_H:
        sps //= 2
    h = sps / (proc.substeps * sensors.sample_rate_hz)
    if lam * h > MAX_LAMBDA_H:
        raise InputError(f"integrator step {h:.3g} s too long for the rig's fastest mode "
                         f"(lambda*h = {lam * h:.2f} > {MAX_LAMBDA_H} with one sample per "
                         "step)", path=where, hint="raise procedure.substeps")
    return proc if sps == proc.samples_per_step else replace(proc, samples_per_step=sps)


def load_config(path: str | Path | None = None, *, overrides: dict | None = None) -> SimConfig:
    """The default configuration, overridden by the TOML file ``path`` (any subset of keys)
    and then by ``overrides`` (a dict of the same layout, for programs and tests).

    Unknown sections or keys and TOML syntax errors raise :class:`InputError` naming the key
    or the line.

    Parameters
    ----------
    path : str or pathlib.Path or None
        A TOML file with any subset of the keys; None: the defaults alone.
    overrides : dict or None
        Further values, in the same layout. Default None.

    Returns
    -------
    SimConfig
        The configuration.

    Raises
    ------
    InputError
        An unreadable file, TOML syntax, an unknown section or key, or a bad value.
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
