"""The V-Track twin's configuration: the default TOML (``data/vtrack_default.toml``), a
user's file merged over it key by key, and the typed :class:`SimConfig` built from the result.

Kept apart from the simulator so that checking a configuration needs neither the compiled
kernels nor the large-signal theory (a bad file is refused before any stage starts).
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

from torquemod._util.tomlcheck import (
    NON_NEGATIVE,
    POSITIVE,
    below_nyquist,
    between,
    check_key,
    checked,
    defaults_from,
    one_of,
    read_table,
)
from torquemod.analysis.contact.hertz import hertz_ellipse
from torquemod.analysis.contact.kalker import kalker_coefficients
from torquemod.analysis.contact.presets import POLACH_PRESETS, polach_preset
from torquemod.errors import InputError
from torquemod.twins.vtrack.params import (
    DEFAULT_DOC,
    MAX_LAMBDA_H,
    MAX_STEP_S,
    ContactParams,
    DisturbanceParams,
    ModulationParams,
    ProcedureParams,
    RigParams,
    SensorParams,
    SimConfig,
    default_config_text,
    explicit_rate,
)

__all__ = ["SimTables", "config_from_dict", "config_from_tables", "default_config_text",
           "default_tables", "load_config", "twin_key_check"]

_POLACH_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["rig"])
class RigTable:
    """The ``[rig]`` table as the file gives it; :class:`RigParams` is built from it.

    Every value a positive number; the defaults are ``vtrack_default.toml``'s.

    Attributes
    ----------
    wheel_radius_m : float
        Rolling radius of the measuring wheel [m].
    platform_radius_m : float
        Radius of the wheel path on the ring [m].
    speed_km_h : float
        Set speed at the wheel path [km/h].
    normal_load_n : float
        Normal load [N].
    wheel_inertia_kg_m2 : float
        Everything rigidly attached downstream of the torque sensor, at the wheel axle
        [kg*m^2].
    drive_inertia_kg_m2 : float
        Motor and gearboxes referred to the wheel axle [kg*m^2].
    shaft_stiffness_nm_rad : float
        Torque shaft and sensor [N*m/rad].
    shaft_damping_nm_s_rad : float
        Their damping [N*m*s/rad].
    platform_inertia_kg_m2 : float
        Platform with the reflected drive [kg*m^2].
    platform_kp_nm_s_rad : float
        Proportional gain of the platform's speed controller [N*m*s/rad].
    platform_ki_nm_rad : float
        Its integral gain [N*m/rad].
    rolling_resistance_nm : float
        Rolling resistance at the platform axis [N*m].
    """

    wheel_radius_m: float = checked(check=POSITIVE)
    platform_radius_m: float = checked(check=POSITIVE)
    speed_km_h: float = checked(check=POSITIVE)
    normal_load_n: float = checked(check=POSITIVE)
    wheel_inertia_kg_m2: float = checked(check=POSITIVE)
    drive_inertia_kg_m2: float = checked(check=POSITIVE)
    shaft_stiffness_nm_rad: float = checked(check=POSITIVE)
    shaft_damping_nm_s_rad: float = checked(check=POSITIVE)
    platform_inertia_kg_m2: float = checked(check=POSITIVE)
    platform_kp_nm_s_rad: float = checked(check=POSITIVE)
    platform_ki_nm_rad: float = checked(check=POSITIVE)
    rolling_resistance_nm: float = checked(check=POSITIVE)


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["contact"])
class ContactTable:
    """The ``[contact]`` table; :class:`ContactParams` is built from it.

    A Polach preset and its five parameters (a preset named in a file fills those the file
    does not give), the materials and the geometry: the semi-axes given, or both 0 and the
    ellipse from Hertz's theory with the transverse radii. The defaults are
    ``vtrack_default.toml``'s.

    Attributes
    ----------
    preset : str
        A Polach preset's name (:data:`torquemod.analysis.contact.presets.POLACH_PRESETS`).
    mu0 : float
        Static friction coefficient [-] (Polach 2005).
    a_ratio : float
        Ratio of the friction at infinite slip velocity to ``mu0`` [-].
    b_s_m : float
        Friction decay with slip velocity [s/m].
    k_a : float
        Polach's reduction factor in the area of adhesion [-].
    k_s : float
        Polach's reduction factor in the area of slip [-].
    youngs_modulus_pa : float
        Young's modulus [Pa].
    poisson_ratio : float
        Poisson's ratio [-], in (0, 0.5).
    wheel_transverse_radius_m : float
        Transverse radius of the wheel tread [m]; 0 for a flat tread.
    rail_transverse_radius_m : float
        Crown radius of the rail head [m]; 0 for a flat head.
    semi_axis_a_m : float
        Contact semi-axis in the rolling direction [m]; 0: from Hertz.
    semi_axis_b_m : float
        Lateral contact semi-axis [m]; 0: from Hertz.
    lateral_creepage : float
        Constant lateral creepage from running on the ring [-].
    """

    preset: str = checked(check=one_of(*POLACH_PRESETS))
    mu0: float = checked(check=POSITIVE)
    a_ratio: float = checked(check=POSITIVE)
    b_s_m: float = checked(check=NON_NEGATIVE)
    k_a: float = checked(check=POSITIVE)
    k_s: float = checked(check=POSITIVE)
    youngs_modulus_pa: float = checked(check=POSITIVE)
    poisson_ratio: float = checked(check=between(0.0, 0.5, lo_open=True, hi_open=True))
    wheel_transverse_radius_m: float = checked(check=NON_NEGATIVE)
    rail_transverse_radius_m: float = checked(check=NON_NEGATIVE)
    semi_axis_a_m: float = checked(check=NON_NEGATIVE)
    semi_axis_b_m: float = checked(check=NON_NEGATIVE)
    lateral_creepage: float = checked()


@dataclass(frozen=True)
class SimTables:
    """The twin's configuration file, table by table, as read and checked.

    Read by :func:`~torquemod._util.tomlcheck.read_table`; the defaults are
    ``vtrack_default.toml``'s.

    Attributes
    ----------
    rig : RigTable
        ``[rig]``.
    contact : ContactTable
        ``[contact]``.
    modulation : ModulationParams
        ``[modulation]``.
    disturbances : DisturbanceParams
        ``[disturbances]``.
    sensors : SensorParams
        ``[sensors]``.
    procedure : ProcedureParams
        ``[procedure]``.
    """

    rig: RigTable = field(default_factory=RigTable)
    contact: ContactTable = field(default_factory=ContactTable)
    modulation: ModulationParams = field(default_factory=ModulationParams)
    disturbances: DisturbanceParams = field(default_factory=DisturbanceParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    procedure: ProcedureParams = field(default_factory=ProcedureParams)


def _parse(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # the message names line and column
        raise InputError(f"TOML syntax error: {exc}", path=where,
                         hint="fix the line named") from None


@functools.cache
def default_tables() -> SimTables:
    """The default configuration (``vtrack_default.toml``), read and checked as a user's.

    Returns
    -------
    SimTables
        Its tables.
    """
    return read_table(SimTables, DEFAULT_DOC, section="", path="vtrack_default.toml")


def _merge(base: SimTables, doc: dict, where: str) -> SimTables:
    """``doc`` (any subset of the tables and keys) read over ``base``; a preset it names
    fills the Polach values it does not give itself."""
    tables = read_table(SimTables, doc, section="", path=where, base=base)
    contact = doc.get("contact", {})
    if "preset" in contact:
        vals = polach_preset(tables.contact.preset).as_dict()
        tables = replace(tables, contact=replace(tables.contact, **{
            k: vals[k] for k in _POLACH_KEYS if k not in contact}))
    return tables


def twin_key_check(key: str, value: object, path: object) -> None:
    """Check a value for one key as the configuration file's would be: its type and range.

    Parameters
    ----------
    key : str
        The dotted key, e.g. ``"contact.mu0"``.
    value : object
        Its value.
    path : object
        The file, named in the message (None: none).

    Raises
    ------
    InputError
        The value has the wrong type or is out of range; the message names the key.
    """
    section, name = key.split(".", 1)
    check_key(type(getattr(default_tables(), section)), name, value, key, path)


def _contact(c: ContactTable, rig: RigTable, where: str) -> ContactParams:
    e_mod, nu = c.youngs_modulus_pa, c.poisson_ratio
    a, b = c.semi_axis_a_m, c.semi_axis_b_m
    if a > 0 and b > 0:
        pass
    elif a == 0 and b == 0:
        rw_t, rr_t = c.wheel_transverse_radius_m, c.rail_transverse_radius_m
        ky = (1.0 / rw_t if rw_t > 0 else 0.0) + (1.0 / rr_t if rr_t > 0 else 0.0)
        if ky <= 0:
            raise InputError("the contact needs a lateral curvature: give "
                             "rail_transverse_radius_m or wheel_transverse_radius_m > 0",
                             path=where)
        el = hertz_ellipse(rig.normal_load_n, curvature_x_1_m=1.0 / rig.wheel_radius_m,
                           curvature_y_1_m=ky, youngs_modulus_pa=e_mod, poisson_ratio=nu)
        a, b = el.a_m, el.b_m
    else:
        raise InputError("give both contact.semi_axis_a_m and semi_axis_b_m (> 0) or neither",
                         path=where)
    kc = kalker_coefficients(a / b, nu)
    return ContactParams(mu0=c.mu0, a_ratio=c.a_ratio, b_s_m=c.b_s_m, k_a=c.k_a, k_s=c.k_s,
                         shear_modulus_pa=e_mod / (2.0 * (1.0 + nu)), a_m=a, b_m=b,
                         c11=kc.c11, c22=kc.c22, lateral_creepage=c.lateral_creepage,
                         preset=c.preset)


def config_from_tables(t: SimTables, *, where: str = "<config>") -> SimConfig:
    """The configuration the twin runs from the checked tables of a file.

    The rig's mechanics and contact are built (the contact ellipse from Hertz's theory when
    its semi-axes are not given, Kalker's coefficients), the modulation is checked against
    the Nyquist frequency and the integrator's step against the rig's fastest mode.

    Parameters
    ----------
    t : SimTables
        The tables.
    where : str
        The source, named in messages. Default "<config>".

    Returns
    -------
    SimConfig
        The configuration.

    Raises
    ------
    InputError
        No lateral curvature, one semi-axis without the other, a modulation at or above
        the Nyquist frequency, or an integrator step too long for the rig.
    """
    r = t.rig
    rig = RigParams(
        wheel_radius_m=r.wheel_radius_m, platform_radius_m=r.platform_radius_m,
        speed_m_s=r.speed_km_h / 3.6, normal_load_n=r.normal_load_n,
        wheel_inertia_kg_m2=r.wheel_inertia_kg_m2, drive_inertia_kg_m2=r.drive_inertia_kg_m2,
        shaft_stiffness_nm_rad=r.shaft_stiffness_nm_rad,
        shaft_damping_nm_s_rad=r.shaft_damping_nm_s_rad,
        platform_inertia_kg_m2=r.platform_inertia_kg_m2,
        platform_kp_nm_s_rad=r.platform_kp_nm_s_rad, platform_ki_nm_rad=r.platform_ki_nm_rad,
        rolling_resistance_nm=r.rolling_resistance_nm, contact=_contact(t.contact, r, where))
    below_nyquist(t.modulation.actual_frequency_hz, t.sensors.sample_rate_hz,
                  "modulation.frequency_hz", "sensors.sample_rate_hz", where)
    procedure = _check_step(rig, t.sensors, t.procedure, where)
    return SimConfig(rig=rig, modulation=t.modulation, disturbances=t.disturbances,
                     sensors=t.sensors, procedure=procedure)


def config_from_dict(doc: dict, *, where: str = "<config>") -> SimConfig:
    """Build a :class:`SimConfig` from a configuration dict, checked as a file.

    Parameters
    ----------
    doc : dict
        The configuration's tables and keys; a missing one keeps the default.
    where : str
        The source, named in messages. Default "<config>".

    Returns
    -------
    SimConfig
        The configuration.

    Raises
    ------
    InputError
        An unknown key (with the nearest known one), a value of the wrong type or out of
        range, or a mistake :func:`config_from_tables` finds.
    """
    return config_from_tables(_merge(default_tables(), doc, where), where=where)


def _check_step(rig: RigParams, sensors: SensorParams, proc: ProcedureParams,
                where: str) -> ProcedureParams:
    """``proc`` with an RK4 step the rig allows: within :data:`MAX_STEP_S` (accuracy) and
    with ``lambda*h <= MAX_LAMBDA_H`` for the explicit part's fastest mode
    (:func:`explicit_rate`; the platform's PI loop is taken exactly) -- ``samples_per_step``
    is halved (12, 6, 3, 1) while the step is too long (a shorter step is only more
    accurate, so a stiffer rig or a lower sample rate just runs slower); refused when even
    one sample per step is too long (raise ``substeps``)."""
    lam = explicit_rate(rig)

    def too_long(sps: int) -> bool:
        h = sps / (proc.substeps * sensors.sample_rate_hz)
        return lam * h > MAX_LAMBDA_H or h > MAX_STEP_S

    sps = proc.samples_per_step
    while sps > 1 and too_long(sps):
        sps //= 2
    h = sps / (proc.substeps * sensors.sample_rate_hz)
    if lam * h > MAX_LAMBDA_H:
        raise InputError(f"integrator step {h:.3g} s too long for the rig's fastest mode "
                         f"(lambda*h = {lam * h:.2f} > {MAX_LAMBDA_H} with one sample per "
                         "step)", path=where, hint="raise procedure.substeps")
    if h > MAX_STEP_S:
        raise InputError(f"integrator step {h:.3g} s too long for the twin's accuracy "
                         f"(> {MAX_STEP_S:g} s with one sample per step)", path=where,
                         hint="raise procedure.substeps")
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
    tables = default_tables()
    where = "<default>"
    if path is not None:
        path = Path(path)
        where = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read the configuration ({exc})", path=path) from None
        tables = _merge(tables, _parse(text, where), where)
    if overrides:
        tables = _merge(tables, overrides, "<overrides>")
    return config_from_tables(tables, where=where)
