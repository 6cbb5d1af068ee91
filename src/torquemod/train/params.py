"""Parameters of the train twin (issue 10): a powered wheelset on a running train.

Thin frozen containers, SI units in the names; :func:`load_train_config` reads them from a
TOML configuration (``torquemod simulate --config train.toml``, the default in
``data/train_default.toml``). Values marked *assumed* in the default configuration are
plausible for a four-axle electric locomotive or motor coach, not measured on one.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from ..checks import positive_number
from ..contact.hertz import hertz_ellipse
from ..contact.kalker import kalker_coefficients
from ..contact.presets import POLACH_PRESETS, PolachParameters
from ..errors import InputError
from ..io.manifest import check_keys

#: Friction conditions of the track map. ``dry`` and ``wet`` are Polach's published sets
#: (contact.presets); the others are assumed, with the reason in ``source``.
CONDITIONS: dict[str, PolachParameters] = {
    "dry": POLACH_PRESETS["dry"],
    "wet": POLACH_PRESETS["wet"],
    "leaves": PolachParameters(
        mu0=0.12, a_ratio=0.40, b_s_m=0.20, k_a=0.30, k_s=0.10,
        source="assumed: leaf-film friction of about 0.05-0.2 is the range reported for "
               "autumn rail (e.g. RSSB T354; Cann, Wear 2006); reduction factors as wet"),
    "friction_modifier": PolachParameters(
        mu0=0.34, a_ratio=0.90, b_s_m=0.30, k_a=0.50, k_s=0.20,
        source="assumed: top-of-rail friction modifiers aim at an intermediate friction of "
               "about 0.3-0.35 with a nearly flat (positive) characteristic (Eadie et al., "
               "Wear 2008); reduction factors between dry and wet"),
}


@dataclass(frozen=True)
class VehicleParams:
    """One powered axle and its share of the vehicle.

    Rotations are referred to the axle: ``motor_inertia_kg_m2`` is the rotor (and pinion)
    inertia times the gear ratio squared; the compliant coupling (``coupling_*``) joins it
    to the wheelset (``wheelset_inertia_kg_m2``, with the gear wheel). ``normal_load_n`` [N]
    is the axle's (both wheels). ``mass_share_kg`` [kg] is the vehicle mass this axle moves
    alone; ``davis_*`` the running resistance ``a + b*V + c*V^2`` [N] of that share.
    ``motor_time_constant_s`` [s]: the motor torque follows its command with this lag.
    """

    wheel_radius_m: float = 0.46
    normal_load_n: float = 200e3
    wheelset_inertia_kg_m2: float = 160.0
    motor_inertia_kg_m2: float = 110.0
    coupling_stiffness_nm_rad: float = 2.0e6
    coupling_damping_nm_s_rad: float = 400.0
    gear_ratio: float = 4.5
    mass_share_kg: float = 21_000.0
    davis_a_n: float = 700.0
    davis_b_n_s_m: float = 12.0
    davis_c_n_s2_m2: float = 1.6
    motor_time_constant_s: float = 0.004
    wheel_profile_radius_m: float = 0.30
    rail_head_radius_m: float = 0.30
    youngs_modulus_pa: float = 210e9
    poisson_ratio: float = 0.28
    shear_modulus_pa: float = 8.1e10

    @property
    def inertia_kg_m2(self) -> float:
        """Wheelset, gears and motor rotor referred to the axle [kg*m^2]."""
        return self.wheelset_inertia_kg_m2 + self.motor_inertia_kg_m2

    def stiffness_x_n(self) -> float:
        """Lumped longitudinal contact stiffness of the axle [N]: ``2*pi*G*a*b*c11/4`` of
        one wheel's Hertz ellipse (Polach 2005 Eq. 4 with Kalker's c11, FACTS §3)."""
        el = hertz_ellipse(self.normal_load_n / 2, curvature_x_1_m=1 / self.wheel_radius_m,
                           curvature_y_1_m=1 / self.wheel_profile_radius_m
                           + 1 / self.rail_head_radius_m,
                           youngs_modulus_pa=self.youngs_modulus_pa,
                           poisson_ratio=self.poisson_ratio)
        c11 = kalker_coefficients(el.a_m / el.b_m, self.poisson_ratio).c11
        return 2.0 * math.pi * self.shear_modulus_pa * el.a_m * el.b_m * c11 / 4.0


@dataclass(frozen=True)
class Segment:
    """Friction from ``start_m`` [m] on: a named condition or explicit Polach parameters."""

    start_m: float
    condition: str
    polach: PolachParameters


@dataclass(frozen=True)
class TrackParams:
    """The friction map (segments, linear transitions of ``transition_m`` [m]) and the
    vertical irregularity that makes the axle load vary: sines of the wavelengths
    ``irregularity_wavelengths_m`` [m] with a total relative RMS ``load_variation_rms``."""

    segments: tuple[Segment, ...]
    length_m: float
    transition_m: float = 20.0
    load_variation_rms: float = 0.03
    irregularity_wavelengths_m: tuple[float, ...] = (3.1, 7.3, 13.7, 26.0)


@dataclass(frozen=True)
class Leg:
    """One part of the driver's demand up to ``until_m`` [m]: ``mode`` ``torque`` (this
    axle's DC torque ``torque_nm`` [N*m], negative brakes), ``speed`` (hold ``speed_m_s``
    with this axle), ``coast`` or ``probe`` (DC torque steps to ``levels`` of the available
    adhesion, each for ``step_m`` [m], while the other axles hold the speed: the tractive
    effort is unchanged). ``others_force_n`` [N]: the other axles' force outside probes."""

    until_m: float
    mode: str
    torque_nm: float = 0.0
    speed_m_s: float = 0.0
    levels: tuple[float, ...] = ()
    step_m: float = 100.0
    others_force_n: float = 0.0


@dataclass(frozen=True)
class ControllerParams:
    """Traction control: speed-holding gains, the anti-slip control that cuts the torque
    when the creepage exceeds ``antislip_creepage`` [-] (at ``antislip_cut_per_s`` [1/s],
    down to ``antislip_floor``, restored at ``antislip_restore_per_s`` below half of it)."""

    legs: tuple[Leg, ...]
    speed_gain_n_s_m: float = 40_000.0
    antislip_creepage: float = 0.04
    antislip_cut_per_s: float = 4.0
    antislip_floor: float = 0.2
    antislip_restore_per_s: float = 0.4


@dataclass(frozen=True)
class TrainSensorParams:
    """What the logger records. Torque: estimated from the motor current with a gain error,
    a bias [N*m], white noise [N*m RMS] and a first-order lag [s]. Wheel speed: an axle
    encoder with tooth spacing errors (RMS share of a pitch, as revolution harmonics 2-8),
    once-per-revolution eccentricity (share of the speed), white noise [rad/s RMS] and
    quantization [rad/s]. Reference speed (radar): its own rate [Hz], noise [m/s RMS] and
    scale error. Position: the reference speed integrated."""

    sample_rate_hz: float = 1000.0
    torque_gain_error: float = 0.01
    torque_bias_nm: float = 60.0
    torque_noise_nm: float = 40.0
    torque_lag_s: float = 0.0
    tooth_error_rms: float = 2e-4
    eccentricity: float = 3e-4
    speed_noise_rad_s: float = 1e-3
    speed_quantum_rad_s: float = 1e-4
    reference_rate_hz: float = 20.0
    reference_noise_m_s: float = 0.02
    reference_scale_error: float = 0.003


@dataclass(frozen=True)
class TrainConfig:
    """Everything the train twin needs (see :func:`load_train_config`)."""

    vehicle: VehicleParams
    track: TrackParams
    controller: ControllerParams
    sensors: TrainSensorParams
    modulation_frequency_hz: float = 5.0
    modulation_amplitude_nm: float = 2000.0
    initial_speed_m_s: float = 20.0
    substeps: int = 8
    raw: dict = field(default_factory=dict, compare=False)


def default_train_config_text() -> str:
    """The default train configuration (TOML) as shipped with the package."""
    return (resources.files("torquemod") / "data" / "train_default.toml").read_text("utf-8")


def _polach(entry: dict, where: str) -> tuple[str, PolachParameters]:
    name = entry.get("condition")
    if name is not None:
        if name not in CONDITIONS:
            raise InputError(f"unknown friction condition '{name}'", path=where,
                             hint=f"use one of {', '.join(CONDITIONS)} or give mu0, a_ratio, "
                                  "b_s_m, k_a, k_s")
        return name, CONDITIONS[name]
    keys = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")
    missing = [k for k in keys if k not in entry]
    if missing:
        raise InputError(f"a [[track.segment]] needs 'condition' or all of {', '.join(keys)}"
                         f" (missing {', '.join(missing)})", path=where)
    vals = {k: positive_number(entry[k], k, path=where) for k in keys}
    return "custom", PolachParameters(**vals, source="given in the configuration")


def _known(table: dict, cls, section: str, where: str) -> dict:
    check_keys(table, sorted(cls.__dataclass_fields__), f"[{section}]", where,
               error=InputError)
    return table


def config_from_dict(doc: dict, *, where: str = "<train config>") -> TrainConfig:
    """A :class:`TrainConfig` from a parsed TOML document (``kind = "train"``)."""
    veh = VehicleParams(**_known(doc.get("vehicle", {}), VehicleParams, "vehicle", where))
    tr = dict(doc.get("track", {}))
    seg_list = tr.pop("segment", [])
    if not seg_list:
        raise InputError("the track needs at least one [[track.segment]]", path=where)
    segs = []
    for s in seg_list:
        name, pol = _polach(s, where)
        segs.append(Segment(float(s.get("start_m", 0.0)), name, pol))
    segs.sort(key=lambda s: s.start_m)
    if "irregularity_wavelengths_m" in tr:
        tr["irregularity_wavelengths_m"] = tuple(tr["irregularity_wavelengths_m"])
    track = TrackParams(tuple(segs), **_known(tr, TrackParams, "track", where))
    ctl = dict(doc.get("controller", {}))
    legs = []
    for leg in ctl.pop("leg", []):
        leg = dict(_known(leg, Leg, "controller.leg", where))
        if leg.get("mode") not in ("torque", "speed", "coast", "probe"):
            raise InputError(f"leg mode {leg.get('mode')!r} is not one of torque, speed, "
                             "coast, probe", path=where)
        leg["levels"] = tuple(leg.get("levels", ()))
        legs.append(Leg(**leg))
    if not legs:
        raise InputError("the driver needs at least one [[controller.leg]]", path=where)
    controller = ControllerParams(tuple(legs), **_known(ctl, ControllerParams, "controller",
                                                        where))
    sensors = TrainSensorParams(**_known(doc.get("sensors", {}), TrainSensorParams,
                                         "sensors", where))
    test = doc.get("test", {})
    run = doc.get("run", {})
    cfg = TrainConfig(veh, track, controller, sensors,
                      float(test.get("modulation_frequency_hz", 5.0)),
                      float(test.get("modulation_amplitude_nm", 2000.0)),
                      float(run.get("initial_speed_m_s", 20.0)),
                      int(run.get("substeps", 8)), raw=doc)
    for name in ("modulation_frequency_hz", "initial_speed_m_s"):
        positive_number(getattr(cfg, name), name, path=where)
    return cfg


def is_train_config(doc: dict) -> bool:
    """True when a simulation configuration describes a train run (``kind = "train"``)."""
    return doc.get("kind") == "train"


def load_train_config(path: str | Path | None = None) -> TrainConfig:
    """Read a train configuration (TOML); None: the packaged default."""
    if path is None:
        return config_from_dict(tomllib.loads(default_train_config_text()),
                                where="train_default.toml")
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the train configuration ({exc})", path=p) from None
    return config_from_dict(doc, where=str(p))
