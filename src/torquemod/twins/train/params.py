"""Parameters of the train twin: a powered wheelset on a running train.

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

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    POSITIVE,
    below_nyquist,
    between,
    default_checks,
    one_of,
    read_table,
    unknown_keys,
)
from torquemod.analysis.contact.hertz import hertz_ellipse
from torquemod.analysis.contact.kalker import kalker_coefficients
from torquemod.analysis.contact.presets import POLACH_PRESETS, PolachParameters
from torquemod.errors import InputError

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

    Rotations are referred to the axle: the motor's inertia is the rotor (and pinion) inertia
    times the gear ratio squared; the compliant coupling joins it to the wheelset.

    Attributes
    ----------
    wheel_radius_m : float
        Rolling radius [m].
    normal_load_n : float
        Axle load, both wheels [N].
    wheelset_inertia_kg_m2 : float
        Wheelset with the gear wheel [kg*m^2].
    motor_inertia_kg_m2 : float
        Motor referred to the axle [kg*m^2].
    coupling_stiffness_nm_rad : float
        Coupling stiffness [N*m/rad].
    coupling_damping_nm_s_rad : float
        Coupling damping [N*m*s/rad].
    gear_ratio : float
        Motor turns per axle turn [-].
    mass_share_kg : float
        The vehicle mass this axle moves alone [kg].
    davis_a_n : float
        Running resistance ``a + b*V + c*V^2`` of that share: a [N].
    davis_b_n_s_m : float
        b [N*s/m].
    davis_c_n_s2_m2 : float
        c [N*s^2/m^2].
    motor_time_constant_s : float
        The motor torque follows its command with this lag [s].
    wheel_profile_radius_m : float
        Transverse radius of the wheel profile [m] (Hertz contact).
    rail_head_radius_m : float
        Transverse radius of the rail head [m].
    youngs_modulus_pa : float
        Young's modulus [Pa].
    poisson_ratio : float
        Poisson's ratio [-].
    shear_modulus_pa : float
        Shear modulus [Pa].
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
        one wheel's Hertz ellipse (Polach 2005 Eq. 4 with Kalker's c11, Kalker 1990 Table E.3)."""
        el = hertz_ellipse(self.normal_load_n / 2, curvature_x_1_m=1 / self.wheel_radius_m,
                           curvature_y_1_m=1 / self.wheel_profile_radius_m
                           + 1 / self.rail_head_radius_m,
                           youngs_modulus_pa=self.youngs_modulus_pa,
                           poisson_ratio=self.poisson_ratio)
        c11 = kalker_coefficients(el.a_m / el.b_m, self.poisson_ratio).c11
        return 2.0 * math.pi * self.shear_modulus_pa * el.a_m * el.b_m * c11 / 4.0


@dataclass(frozen=True)
class Segment:
    """Friction from a position on: a named condition or explicit Polach parameters.

    Attributes
    ----------
    start_m : float
        Where the segment starts [m].
    condition : str
        Its name.
    polach : PolachParameters
        Its Polach parameters [1]_.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """

    start_m: float
    condition: str
    polach: PolachParameters


@dataclass(frozen=True)
class TrackParams:
    """The friction map and the vertical irregularity that makes the axle load vary.

    Attributes
    ----------
    segments : tuple of Segment
        The friction segments, in order.
    length_m : float
        Track length [m].
    transition_m : float
        Length of the linear transitions between segments [m]. Default 20.
    load_variation_rms : float
        Total relative RMS of the load variation [-]. Default 0.03.
    irregularity_wavelengths_m : tuple of float
        Wavelengths of the irregularity's sines [m].
    """

    segments: tuple[Segment, ...]
    length_m: float
    transition_m: float = 20.0
    load_variation_rms: float = 0.03
    irregularity_wavelengths_m: tuple[float, ...] = (3.1, 7.3, 13.7, 26.0)


@dataclass(frozen=True)
class Leg:
    """One part of the driver's demand.

    Attributes
    ----------
    until_m : float
        Where the leg ends [m].
    mode : {"torque", "speed", "coast", "probe"}
        ``torque``: this axle's DC torque; ``speed``: hold the speed with this axle;
        ``coast``; ``probe``: DC torque steps to ``levels`` of the available adhesion while
        the other axles hold the speed (the tractive effort is unchanged).
    torque_nm : float
        DC torque of a ``torque`` leg [N*m], negative brakes. Default 0.
    speed_m_s : float
        Speed of a ``speed`` leg [m/s]. Default 0.
    levels : tuple of float
        The probe's levels, shares of the available adhesion [-].
    step_m : float
        Length of each probe level [m]. Default 100.
    others_force_n : float
        The other axles' force outside probes [N]. Default 0.
    """

    until_m: float
    mode: str
    torque_nm: float = 0.0
    speed_m_s: float = 0.0
    levels: tuple[float, ...] = ()
    step_m: float = 100.0
    others_force_n: float = 0.0


@dataclass(frozen=True)
class ControllerParams:
    """Traction control: the driver's legs, speed holding and anti-slip control.

    Attributes
    ----------
    legs : tuple of Leg
        The driver's demand, in order.
    speed_gain_n_s_m : float
        Speed-holding gain [N*s/m].
    antislip_creepage : float
        The anti-slip control cuts the torque above this creepage [-].
    antislip_cut_per_s : float
        At this rate [1/s].
    antislip_floor : float
        Down to this share of the demand [-].
    antislip_restore_per_s : float
        Restored at this rate below half the threshold [1/s].
    """

    legs: tuple[Leg, ...]
    speed_gain_n_s_m: float = 40_000.0
    antislip_creepage: float = 0.04
    antislip_cut_per_s: float = 4.0
    antislip_floor: float = 0.2
    antislip_restore_per_s: float = 0.4


@dataclass(frozen=True)
class TrainSensorParams:
    """What the logger records.

    Attributes
    ----------
    sample_rate_hz : float
        Logger rate [Hz].
    torque_gain_error : float
        Gain error of the torque estimated from the motor current [-].
    torque_bias_nm : float
        Its bias [N*m].
    torque_noise_nm : float
        Its white noise [N*m RMS].
    torque_lag_s : float
        Its first-order lag [s].
    tooth_error_rms : float
        The axle encoder's tooth spacing errors, RMS share of a pitch (revolution harmonics
        2-8) [-].
    eccentricity : float
        Once-per-revolution eccentricity, share of the speed [-].
    speed_noise_rad_s : float
        White noise of the wheel speed [rad/s RMS].
    speed_quantum_rad_s : float
        Quantization of the wheel speed [rad/s].
    reference_rate_hz : float
        Rate of the reference speed (radar) [Hz].
    reference_noise_m_s : float
        Its noise [m/s RMS].
    reference_scale_error : float
        Its scale error [-].
    """

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
    """Everything the train twin needs (:func:`load_train_config`).

    Attributes
    ----------
    vehicle : VehicleParams
        The axle and its share of the vehicle.
    track : TrackParams
        Friction map and irregularity.
    controller : ControllerParams
        Driver and traction control.
    sensors : TrainSensorParams
        The logger.
    modulation_frequency_hz : float
        Modulation frequency [Hz]. Default 5.
    modulation_amplitude_nm : float
        Modulation amplitude [N*m]. Default 2000.
    initial_speed_m_s : float
        Speed at the start [m/s]. Default 20.
    substeps : int
        RK4 steps per logger sample [-]. Default 8.
    raw : dict
        The configuration document as read.
    """

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
    """The default train configuration (TOML) as shipped with the package.

    Returns
    -------
    str
        ``torquemod/data/train_default.toml``.
    """
    return (resources.files("torquemod") / "data" / "train_default.toml").read_text("utf-8")


_POSITIVE_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")
#: the most logger samples a simulated run may hold (track length / initial speed x sample
#: rate; ~50 million: the twin keeps ~13 float64 columns of them in memory, ~5 GB)
MAX_SAMPLES = 5e7
#: the train configuration's top-level tables and keys
_TOP = ("kind", "run", "vehicle", "test", "track", "controller", "sensors")

#: Ranges of the values (besides their types): positive unless listed otherwise.
_VEHICLE = {"coupling_damping_nm_s_rad": NON_NEGATIVE, "davis_a_n": NON_NEGATIVE,
            "davis_b_n_s_m": NON_NEGATIVE, "davis_c_n_s2_m2": NON_NEGATIVE,
            "poisson_ratio": between(0.0, 0.5, lo_open=True, hi_open=True)}
_TRACK = {"transition_m": NON_NEGATIVE, "load_variation_rms": between(0.0, 0.5, hi_open=True)}
_LEG = {"mode": one_of("torque", "speed", "coast", "probe"), "torque_nm": None,
        "speed_m_s": NON_NEGATIVE, "levels": between(0.0, 1.0, lo_open=True, hi_open=True),
        "others_force_n": None}
_CONTROLLER = {"speed_gain_n_s_m": NON_NEGATIVE, "antislip_cut_per_s": NON_NEGATIVE,
               "antislip_floor": between(0.0, 1.0), "antislip_restore_per_s": NON_NEGATIVE}
_SENSORS = {"torque_gain_error": between(-1.0, 1.0, lo_open=True, hi_open=True),
            "torque_bias_nm": None, "torque_noise_nm": NON_NEGATIVE,
            "torque_lag_s": NON_NEGATIVE, "tooth_error_rms": between(0.0, 1.0, hi_open=True),
            "eccentricity": between(0.0, 1.0, hi_open=True),
            "speed_noise_rad_s": NON_NEGATIVE, "speed_quantum_rad_s": NON_NEGATIVE,
            "reference_noise_m_s": NON_NEGATIVE,
            "reference_scale_error": between(-1.0, 1.0, lo_open=True, hi_open=True)}


@dataclass(frozen=True)
class _Test:
    """``[test]``: the modulation [Hz], [N*m] (0: none)."""

    modulation_frequency_hz: float = 5.0
    modulation_amplitude_nm: float = 2000.0


@dataclass(frozen=True)
class _Run:
    """``[run]``: the starting speed [m/s] and RK4 steps per logger sample."""

    initial_speed_m_s: float = 20.0
    substeps: int = 8


@dataclass(frozen=True)
class _Segment:
    start_m: float = 0.0
    condition: str = ""
    mu0: float = 0.0
    a_ratio: float = 0.0
    b_s_m: float = 0.0
    k_a: float = 0.0
    k_s: float = 0.0


def _segment(i: int, entry: object, where: str) -> Segment:
    section = f"track.segment[{i + 1}]"
    seg = read_table(_Segment, entry, section=section, path=where,
                     checks={"start_m": NON_NEGATIVE, "condition": one_of(*CONDITIONS),
                             **dict.fromkeys(_POSITIVE_KEYS, POSITIVE), "b_s_m": NON_NEGATIVE})
    if seg.condition:
        return Segment(seg.start_m, seg.condition, CONDITIONS[seg.condition])
    missing = [k for k in _POSITIVE_KEYS if k not in entry]
    if missing:
        raise InputError(f"[{section}] needs 'condition' or all of "
                         f"{', '.join(_POSITIVE_KEYS)} (missing {', '.join(missing)})",
                         path=where, hint=f"named conditions: {', '.join(CONDITIONS)}")
    pol = PolachParameters(**{k: getattr(seg, k) for k in _POSITIVE_KEYS},
                           source="given in the configuration")
    return Segment(seg.start_m, "custom", pol)


def _table(doc: dict, name: str, where: str) -> dict:
    table = doc.get(name, {})
    if not isinstance(table, dict):
        raise InputError(f"[{name}] must be a table, got {table!r}", path=where)
    return table


def _list(table: dict, key: str, section: str, where: str) -> list:
    items = table.get(key, [])
    if not isinstance(items, list) or not all(isinstance(x, dict) for x in items):
        raise InputError(f"'{section}.{key}' must be tables [[{section}.{key}]]", path=where)
    return items


def config_from_dict(doc: dict, *, where: str = "<train config>") -> TrainConfig:
    """A :class:`TrainConfig` from a parsed TOML document (``kind = "train"``). Every key and
    value is checked (:func:`torquemod._util.tomlcheck.read_table`): unknown keys (with the nearest
    known one), types, finiteness, signs and ranges, the modulation and the reference rate
    below the sample rate's Nyquist frequency; an :class:`InputError` names ``where`` and the
    key.

    Parameters
    ----------
    doc : dict
        The parsed TOML document.
    where : str
        The source, named in messages. Default "<train config>".

    Returns
    -------
    TrainConfig
        The configuration.

    Raises
    ------
    InputError
        An unknown key, a bad type or value, no track segment or driver leg, a missing track
        length, rates above Nyquist, or a run too long to hold.
    """
    unknown_keys(doc, _TOP, "train configuration", where)
    veh = read_table(VehicleParams, _table(doc, "vehicle", where), section="vehicle",
                     path=where, checks=default_checks(VehicleParams, _VEHICLE))
    tr = _table(doc, "track", where)
    segs = sorted((_segment(i, s, where) for i, s in
                   enumerate(_list(tr, "segment", "track", where))), key=lambda s: s.start_m)
    if not segs:
        raise InputError("the track needs at least one [[track.segment]]", path=where)
    if "length_m" not in tr:
        raise InputError("missing key 'track.length_m'", path=where,
                         hint="add 'length_m = <metres>' under [track]")
    track = read_table(TrackParams, tr, section="track", path=where,
                       checks=default_checks(TrackParams, _TRACK), skip=("segment",),
                       given={"segments": tuple(segs)})
    if segs[0].start_m >= track.length_m:
        raise InputError(f"the first [[track.segment]] starts at {segs[0].start_m:g} m, at or "
                         f"beyond track.length_m = {track.length_m:g} m", path=where)
    ctl = _table(doc, "controller", where)
    legs = []
    for i, leg in enumerate(_list(ctl, "leg", "controller", where)):
        if "mode" not in leg or "until_m" not in leg:
            raise InputError(f"[controller.leg[{i + 1}]] needs 'until_m' and 'mode'",
                             path=where, hint="mode is one of torque, speed, coast, probe")
        legs.append(read_table(Leg, leg, section=f"controller.leg[{i + 1}]", path=where,
                               checks=default_checks(Leg, _LEG)))
        need = {"speed": "speed_m_s", "probe": "levels"}.get(legs[-1].mode)
        if need and not getattr(legs[-1], need):
            raise InputError(f"[controller.leg[{i + 1}]] mode = \"{legs[-1].mode}\" needs "
                             f"'{need}'", path=where,
                             hint="the speed to hold [m/s]" if need == "speed_m_s" else
                                  "the fractions of the available adhesion, e.g. [0.2, 0.4]")
    if not legs:
        raise InputError("the driver needs at least one [[controller.leg]]", path=where)
    controller = read_table(ControllerParams, ctl, section="controller", path=where,
                            checks=default_checks(ControllerParams, _CONTROLLER),
                            skip=("leg",), given={"legs": tuple(legs)})
    sensors = read_table(TrainSensorParams, _table(doc, "sensors", where), section="sensors",
                         path=where, checks=default_checks(TrainSensorParams, _SENSORS))
    test = read_table(_Test, _table(doc, "test", where), section="test", path=where,
                      checks={"modulation_frequency_hz": POSITIVE,
                              "modulation_amplitude_nm": NON_NEGATIVE})
    run = read_table(_Run, _table(doc, "run", where), section="run", path=where,
                     checks={"initial_speed_m_s": POSITIVE, "substeps": between(1, None)})
    fs = sensors.sample_rate_hz
    below_nyquist(test.modulation_frequency_hz, fs, "test.modulation_frequency_hz",
                  "sensors.sample_rate_hz", where)
    if sensors.reference_rate_hz > fs:
        raise InputError(f"'sensors.reference_rate_hz' = {sensors.reference_rate_hz:g} Hz is "
                         f"above 'sensors.sample_rate_hz' = {fs:g} Hz", path=where,
                         hint="the logger cannot record the reference faster than it samples")
    n = track.length_m / run.initial_speed_m_s * fs
    if n > MAX_SAMPLES:  # memory grows with the samples: refuse what cannot fit
        raise InputError(f"the run would hold about {n:.3g} samples ({track.length_m:g} m at "
                         f"{run.initial_speed_m_s:g} m/s, {fs:g} Hz), more than "
                         f"{MAX_SAMPLES:.0e}", path=where,
                         hint="shorten track.length_m, lower sensors.sample_rate_hz or raise "
                              "run.initial_speed_m_s")
    if veh.shear_modulus_pa >= veh.youngs_modulus_pa:  # G = E/(2*(1 + nu)) < E
        raise InputError("'vehicle.shear_modulus_pa' must be below 'vehicle.youngs_modulus_pa'",
                         path=where, hint="steel: E = 210e9 Pa, G = 81e9 Pa")
    return TrainConfig(veh, track, controller, sensors, test.modulation_frequency_hz,
                       test.modulation_amplitude_nm, run.initial_speed_m_s, run.substeps,
                       raw=doc)


def is_train_config(doc: dict) -> bool:
    """True when a simulation configuration describes a train run (``kind = "train"``).

    Parameters
    ----------
    doc : dict
        The parsed TOML document.

    Returns
    -------
    bool
        Whether it is a train configuration.
    """
    return doc.get("kind") == "train"


def load_train_config(path: str | Path | None = None) -> TrainConfig:
    """Read a train configuration (TOML).

    Parameters
    ----------
    path : str or pathlib.Path or None
        The file; None: the packaged default.

    Returns
    -------
    TrainConfig
        The configuration.

    Raises
    ------
    InputError
        The file cannot be read, or :func:`config_from_dict` refuses it.
    """
    if path is None:
        return config_from_dict(tomllib.loads(default_train_config_text()),
                                where="train_default.toml")
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the train configuration ({exc})", path=p) from None
    return config_from_dict(doc, where=str(p))
