"""Parameters of the V-Track digital twin as frozen dataclasses (SI units throughout).

The default values have one source, ``torquemod/data/vtrack_default.toml`` (``torquemod
simulate --print-config``), which says which values come from the V-Track paper and which are
assumed: the dataclasses of its tables take their defaults from it
(:func:`~torquemod._util.tomlcheck.defaults_from`) and declare only the range of each value.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources

from torquemod._util.tomlcheck import NON_NEGATIVE, POSITIVE, Check, between, checked, defaults_from


def default_config_text() -> str:
    """The default configuration (V-Track) as commented TOML text.

    Returns
    -------
    str
        ``torquemod/data/vtrack_default.toml``: every default value of the twin, each marked
        as the V-Track paper's, the project's or assumed.
    """
    return (resources.files("torquemod") / "data" / "vtrack_default.toml").read_text("utf-8")


#: the default configuration's tables, parsed once: the defaults of the dataclasses below
DEFAULT_DOC: dict = tomllib.loads(default_config_text())


@dataclass(frozen=True)
class ContactParams:
    """Polach creep-force parameters and contact geometry of the measuring wheel.

    Attributes
    ----------
    mu0 : float
        Friction coefficient at zero slip velocity [-] (Eq. 9 of [1]_).
    a_ratio : float
        A = mu_inf/mu0 [-] (Eq. 9).
    b_s_m : float
        B, decay rate of friction with slip velocity [s/m] (Eq. 9).
    k_a : float
        Reduction factor in the area of adhesion [-] (Eq. 8).
    k_s : float
        Reduction factor in the area of slip [-] (Eq. 8).
    shear_modulus_pa : float
        Shear modulus G [Pa].
    a_m : float
        Contact semi-axis in the rolling direction [m].
    b_m : float
        Lateral contact semi-axis [m].
    c11 : float
        Kalker's longitudinal coefficient [-].
    c22 : float
        Kalker's lateral coefficient [-].
    lateral_creepage : float
        Constant lateral creepage from running on the ring [-]. Default 0.
    preset : str
        The preset it started from. Default "".

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """

    mu0: float
    a_ratio: float
    b_s_m: float
    k_a: float
    k_s: float
    shear_modulus_pa: float
    a_m: float
    b_m: float
    c11: float
    c22: float
    lateral_creepage: float = 0.0
    preset: str = ""

    @property
    def stiffness_x_n(self) -> float:
        """``pi*G*a*b*c11/4`` [N]: Polach's gradient eps = stiffness*xi/(Q*mu) (P05 Eq. 3)."""
        return math.pi * self.shear_modulus_pa * self.a_m * self.b_m * self.c11 / 4.0

    @property
    def stiffness_y_n(self) -> float:
        """``pi*G*a*b*c22/4`` [N], the lateral counterpart of :attr:`stiffness_x_n`."""
        return math.pi * self.shear_modulus_pa * self.a_m * self.b_m * self.c22 / 4.0

    def polach_kwargs(self) -> dict:
        """Keyword arguments for :func:`torquemod.analysis.contact.polach.creep_force`."""
        return dict(a_m=self.a_m, b_m=self.b_m, c11=self.c11, c22=self.c22,
                    shear_modulus_pa=self.shear_modulus_pa, mu0=self.mu0,
                    a_ratio=self.a_ratio, b_s_m=self.b_s_m, k_a=self.k_a, k_s=self.k_s)


@dataclass(frozen=True)
class RigParams:
    """Mechanics of the rig, every rotation referred to the measuring wheel's axle.

    Drive line: motor and both gearboxes -- torque shaft -- torque sensor with its encoder --
    wheel (everything rigidly attached downstream of the sensor). Platform: frame plus
    reflected drive under a PI speed controller against the rolling resistance; it carries
    the wheel at ``platform_radius_m`` and feels the traction force's reaction ``Fx*Rp``.

    Attributes
    ----------
    wheel_radius_m : float
        Wheel radius Rw [m].
    platform_radius_m : float
        Radius of the wheel path on the ring Rp [m].
    speed_m_s : float
        Set rolling speed V [m/s].
    normal_load_n : float
        Normal load N [N].
    wheel_inertia_kg_m2 : float
        Inertia downstream of the torque sensor Jw [kg*m^2].
    drive_inertia_kg_m2 : float
        Motor and gearboxes Jm [kg*m^2].
    shaft_stiffness_nm_rad : float
        Torque shaft stiffness [N*m/rad].
    shaft_damping_nm_s_rad : float
        Torque shaft damping [N*m*s/rad].
    platform_inertia_kg_m2 : float
        Platform inertia Jp [kg*m^2].
    platform_kp_nm_s_rad : float
        Speed controller's proportional gain [N*m*s/rad].
    platform_ki_nm_rad : float
        Its integral gain [N*m/rad].
    rolling_resistance_nm : float
        Rolling resistance torque on the platform [N*m].
    contact : ContactParams
        The contact.
    """

    wheel_radius_m: float
    platform_radius_m: float
    speed_m_s: float
    normal_load_n: float
    wheel_inertia_kg_m2: float
    drive_inertia_kg_m2: float
    shaft_stiffness_nm_rad: float
    shaft_damping_nm_s_rad: float
    platform_inertia_kg_m2: float
    platform_kp_nm_s_rad: float
    platform_ki_nm_rad: float
    rolling_resistance_nm: float
    contact: ContactParams

    @property
    def platform_speed_rad_s(self) -> float:
        """Set platform angular speed ``Omega = V/Rp`` [rad/s]."""
        return self.speed_m_s / self.platform_radius_m

    @property
    def revolution_s(self) -> float:
        """Duration of one platform revolution at the set speed [s]."""
        return 2.0 * math.pi / self.platform_speed_rad_s


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["modulation"])
class ModulationParams:
    """The motor controller's torque modulation.

    The DC torque plus ``amplitude_nm`` at ``frequency_hz``, generated on the controller's own
    clock.

    Attributes
    ----------
    amplitude_nm : float
        Modulation amplitude [N*m]. Default 8 (the V-Track paper's).
    frequency_hz : float
        Nominal modulation frequency [Hz]. Default 2.
    frequency_offset : float
        How fast the controller's clock runs, relative (e.g. 1e-3) [-]. Default 1.2e-3.
    random_phase : bool
        Draw the generator phase per recording. Default True.
    """

    amplitude_nm: float = checked(check=NON_NEGATIVE)
    frequency_hz: float = checked(check=POSITIVE)
    frequency_offset: float = checked(check=between(-0.5, 0.5, lo_open=True, hi_open=True))
    random_phase: bool = checked()

    @property
    def actual_frequency_hz(self) -> float:
        return self.frequency_hz * (1.0 + self.frequency_offset)


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["disturbances"])
class DisturbanceParams:
    """Rig disturbances.

    Encoder eccentricity as angle errors ``e1*sin(theta + phi1) + e2*sin(2*theta + phi2)``;
    normal-load variation from sleepers and rail joints (a decaying oscillation per joint);
    the platform's speed loop wobbles: its reference ``W_ref = W0*(1 + w(t, theta_p))``
    carries ``speed_wobble_components`` sines of equal amplitude at random frequencies in
    ``speed_wobble_band_hz``, together ``speed_wobble_rms`` RMS, and once- and
    twice-per-revolution terms; frequencies and phases are drawn once per run from the seed.
    The wheel follows through the contact (:func:`torquemod.twins.vtrack.rig.wobble.wobble_table`).

    Attributes
    ----------
    enabled : bool
        False switches all disturbances and the sensor noise off. Default True.
    wheel_encoder_ecc1_rad, wheel_encoder_ecc2_rad : float
        The wheel encoder's once- and twice-per-revolution angle errors e1, e2 [rad].
    wheel_encoder_phase1_rad, wheel_encoder_phase2_rad : float
        Their phases phi1, phi2 [rad].
    platform_encoder_ecc1_rad, platform_encoder_ecc2_rad : float
        The platform encoder's angle errors [rad].
    platform_encoder_phase1_rad, platform_encoder_phase2_rad : float
        Their phases [rad].
    sleeper_count : int
        Sleepers per revolution [-]. Default 100.
    sleeper_load_n : float
        Amplitude of the sleeper-passing load variation [N].
    joint_count : int
        Rail joints per revolution [-]. Default 4.
    joint_load_n : float
        Amplitude of a joint's load oscillation [N].
    joint_frequency_hz : float
        Its frequency [Hz]. Default 40.
    joint_damping_ratio : float
        Its damping ratio [-]. Default 0.1.
    speed_wobble_enabled : bool
        The speed loop wobbles (only with ``enabled``). Default True.
    speed_wobble_rms : float
        RMS of the random sines, relative [-].
    speed_wobble_band_hz : tuple of float
        Band of their frequencies [Hz]. Default (0.2, 0.6).
    speed_wobble_components : int
        How many sines [-]. Default 3.
    speed_wobble_rev1, speed_wobble_rev2 : float
        Relative amplitudes of the once- and twice-per-revolution terms [-].
    """

    enabled: bool = checked()
    wheel_encoder_ecc1_rad: float = checked()
    wheel_encoder_ecc2_rad: float = checked()
    wheel_encoder_phase1_rad: float = checked()
    wheel_encoder_phase2_rad: float = checked()
    platform_encoder_ecc1_rad: float = checked()
    platform_encoder_ecc2_rad: float = checked()
    platform_encoder_phase1_rad: float = checked()
    platform_encoder_phase2_rad: float = checked()
    sleeper_count: int = checked()
    sleeper_load_n: float = checked()
    joint_count: int = checked()
    joint_load_n: float = checked()
    joint_frequency_hz: float = checked()
    joint_damping_ratio: float = checked()
    speed_wobble_enabled: bool = checked()
    speed_wobble_rms: float = checked(check=NON_NEGATIVE)
    speed_wobble_band_hz: tuple[float, float] = checked(check=Check(
        lo=0.0, lo_open=True, test=lambda b: len(b) == 2 and b[0] <= b[1],
        need="[low, high] with 0 < low <= high"))
    speed_wobble_components: int = checked(check=NON_NEGATIVE)
    speed_wobble_rev1: float = checked(check=NON_NEGATIVE)
    speed_wobble_rev2: float = checked(check=NON_NEGATIVE)


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["sensors"])
class SensorParams:
    """Sampling rate and white-noise standard deviation of each sensor.

    Attributes
    ----------
    sample_rate_hz : float
        Sample rate [Hz]. Default 16 670 (the V-Track paper's).
    torque_noise_nm : float
        Torque noise [N*m].
    wheel_speed_noise_rad_s : float
        Wheel speed noise [rad/s].
    platform_speed_noise_rad_s : float
        Platform speed noise [rad/s].
    force_noise_n : float
        Force noise [N].
    """

    sample_rate_hz: float = checked(check=POSITIVE)
    torque_noise_nm: float = checked(check=NON_NEGATIVE)
    wheel_speed_noise_rad_s: float = checked(check=NON_NEGATIVE)
    platform_speed_noise_rad_s: float = checked(check=NON_NEGATIVE)
    force_noise_n: float = checked(check=NON_NEGATIVE)


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["procedure"])
class ProcedureParams:
    """The test procedure and the integrator's step.

    Attributes
    ----------
    dc_torques_nm : tuple of float
        DC torque steps [N*m]. Default the V-Track paper's Table 1 plus one step above the
        creep-curve peak.
    cycles_per_step : int
        Platform revolutions recorded per step [-]. Default 3.
    settle_s : float
        Settling time after each step change [s]. Default 4.
    ramp_s : float
        Ramp time of the DC change [s]. Default 0.5.
    slip_creepage : float
        Creepage above which the wheel counts as slipping [-]. Default 0.05.
    substeps : int
        Classical RK4 steps per ``samples_per_step`` output samples [-]. Default 1.
    samples_per_step : int
        Output samples per integration step (those inside a step are interpolated,
        :func:`torquemod.twins.vtrack.rig.lanes.integrate`) [-]. Default 16; a loaded
        configuration lowers it to keep the step within :data:`MAX_STEP_S` and
        :data:`ACCURACY_LAMBDA_H`.
    """

    dc_torques_nm: tuple[float, ...] = checked()
    cycles_per_step: int = checked(check=between(1, None))
    settle_s: float = checked(check=NON_NEGATIVE)
    ramp_s: float = checked(check=NON_NEGATIVE)
    slip_creepage: float = checked(check=POSITIVE)
    substeps: int = checked(check=between(1, None))
    samples_per_step: int = checked(check=between(1, None))


@dataclass(frozen=True)
class SimConfig:
    """Everything one simulated experiment needs.

    Attributes
    ----------
    rig : RigParams
        The rig and its contact.
    modulation : ModulationParams
        The torque modulation.
    disturbances : DisturbanceParams
        The rig's disturbances.
    sensors : SensorParams
        Sampling and noise.
    procedure : ProcedureParams
        The test procedure.
    """

    rig: RigParams
    modulation: ModulationParams = field(default_factory=ModulationParams)
    disturbances: DisturbanceParams = field(default_factory=DisturbanceParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    procedure: ProcedureParams = field(default_factory=ProcedureParams)


#: largest |lambda*h| accepted for the integrator's explicit part (RK4 is stable to 2.78 on
#: the real axis; the platform's PI loop, taken exactly, does not count:
#: :func:`explicit_rate`)
MAX_LAMBDA_H = 2.5
#: largest |lambda*h| of the explicit part's fastest mode accepted for ACCURACY (not
#: stability): with the disturbances off the simulated phases' error against a step of 4
#: samples grows roughly as (lambda*h)^4 where the creep-force damping (rising as 1/V)
#: dominates, ~1e-4 deg at lambda*h = 0.6 (dry contact at 4 km/h); 0.5 keeps it below
#: ~5e-5 deg (benchmarks/twin_step_accuracy.py, docs/performance.md)
ACCURACY_LAMBDA_H = 0.5
#: longest RK4 step [s] accepted for accuracy: 16 samples at 16 670 Hz (9.6e-4 s). Over the
#: example sweep's conditions, speeds, loads and modulation frequencies, with the
#: disturbances on, the simulated phases stay within 9.0e-4 deg a revolution of a step of 4
#: samples (1 % of 0.145 deg, the smallest per-cycle phase standard error the chain reports
#: at the default sensor noise) and, with them off, within 1e-4 deg (1 % of the 0.01 deg to
#: which the twin is held against an independent simulation); 24 samples exceed the first
#: (1.7e-3 deg), 20 leave a joint's ringing beyond the normal load's fast rotation
#: (rig/dynamics.py) for little gain (docs/performance.md, benchmarks/twin_step_accuracy.py)
MAX_STEP_S = 9.6e-4


def stiffest_rate(rig: RigParams) -> float:
    """Estimate of the fastest eigenvalue of the twin's equations.

    The platform's PI loop ``Kp/Jp``, the torsional mode ``sqrt(k/J) + c/J``
    (``1/J = 1/Jm + 1/Jw``) or the creep-force damping ``(Rw^2/Jw + Rp^2/Jp)*dFx/dxi/V`` at
    zero creepage (dFx/dxi from Eq. (8) of [1]_), whichever is largest.

    Parameters
    ----------
    rig : RigParams
        The rig.

    Returns
    -------
    float
        The rate [1/s].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    """
    return max(rig.platform_kp_nm_s_rad / rig.platform_inertia_kg_m2, explicit_rate(rig))


def explicit_rate(rig: RigParams) -> float:
    """Estimate of the fastest eigenvalue the integrator's explicit (RK4) part sees.

    :func:`stiffest_rate` without the platform's PI loop ``Kp/Jp``, whose linear rate the
    integrator takes exactly (exponential RK4 on the platform speed,
    :mod:`torquemod.twins.vtrack.rig.lanes`): the torsional mode or the creep-force damping
    (dFx/dxi at zero creepage from Eq. (8) of [1]_), whichever is larger.

    Parameters
    ----------
    rig : RigParams
        The rig.

    Returns
    -------
    float
        The rate [1/s].

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eq. (8).
    """
    c = rig.contact
    inv_j = 1.0 / rig.drive_inertia_kg_m2 + 1.0 / rig.wheel_inertia_kg_m2
    torsion = math.sqrt(rig.shaft_stiffness_nm_rad * inv_j) + rig.shaft_damping_nm_s_rad * inv_j
    kx = 2.0 * (c.k_a + c.k_s) * c.stiffness_x_n / math.pi  # dFx/dxi at 0, P05 Eq. (8)
    contact = (rig.wheel_radius_m ** 2 / rig.wheel_inertia_kg_m2
               + rig.platform_radius_m ** 2 / rig.platform_inertia_kg_m2) * kx / rig.speed_m_s
    return max(torsion, contact)
