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
    """The default configuration (V-Track) as commented TOML text."""
    return (resources.files("torquemod") / "data" / "vtrack_default.toml").read_text("utf-8")


#: the default configuration's tables, parsed once: the defaults of the dataclasses below
DEFAULT_DOC: dict = tomllib.loads(default_config_text())


@dataclass(frozen=True)
class ContactParams:
    """Polach creep-force parameters and contact geometry of the measuring wheel.

    ``mu0`` [-], ``a_ratio`` A [-], ``b_s_m`` B [s/m], ``k_a``, ``k_s`` [-] as in Polach (2005)
    Eqs. (8)-(9); ``shear_modulus_pa`` G [Pa]; ``a_m``, ``b_m`` contact semi-axes (rolling,
    lateral) [m]; ``c11``, ``c22`` Kalker coefficients [-]; ``lateral_creepage`` the constant
    lateral creepage from running on the ring [-]; ``preset`` the name it started from.
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

    Drive line: motor and both gearboxes (``drive_inertia_kg_m2``) -- torque shaft with
    ``shaft_stiffness_nm_rad`` and ``shaft_damping_nm_s_rad`` -- torque sensor with its
    encoder -- wheel (``wheel_inertia_kg_m2``: everything rigidly attached downstream of the
    sensor). Platform: ``platform_inertia_kg_m2`` (frame plus reflected drive), PI speed
    controller ``platform_kp_nm_s_rad``, ``platform_ki_nm_rad`` against
    ``rolling_resistance_nm``; it carries the wheel at ``platform_radius_m`` and feels the
    traction force's reaction ``Fx*Rp``.
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
    """Motor controller: DC torque plus ``amplitude_nm`` [N*m] at ``frequency_hz`` [Hz]
    (nominal) generated on the controller's own clock, which runs ``frequency_offset``
    (relative, e.g. 1e-3) fast; ``random_phase`` draws the generator phase per recording."""

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
    """Rig disturbances; ``enabled = False`` switches all of them and the sensor noise off.

    Encoder eccentricity as angle errors ``e1*sin(theta+phi1) + e2*sin(2*theta+phi2)`` [rad];
    normal-load variation from ``sleeper_count`` sleepers per revolution
    (``sleeper_load_n`` amplitude [N]) and ``joint_count`` rail joints (a decaying
    oscillation of ``joint_load_n`` [N] at ``joint_frequency_hz`` with ``joint_damping_ratio``).
    The platform's speed loop wobbles (``speed_wobble_enabled``, and only with ``enabled``):
    its reference ``W_ref = W0*(1 + w(t, theta_p))`` carries ``speed_wobble_components`` sines
    of equal amplitude at random frequencies in ``speed_wobble_band_hz`` [Hz], together
    ``speed_wobble_rms`` (relative) RMS, and once- and twice-per-revolution terms
    ``speed_wobble_rev1``/``rev2`` (relative amplitudes, functions of the platform angle);
    frequencies and phases are drawn once per run from the seed. The wheel follows through
    the contact (:func:`torquemod.twins.vtrack.rig.dynamics.wobble_table`).
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
    """Sampling rate [Hz] and white-noise standard deviations of each sensor."""

    sample_rate_hz: float = checked(check=POSITIVE)
    torque_noise_nm: float = checked(check=NON_NEGATIVE)
    wheel_speed_noise_rad_s: float = checked(check=NON_NEGATIVE)
    platform_speed_noise_rad_s: float = checked(check=NON_NEGATIVE)
    force_noise_n: float = checked(check=NON_NEGATIVE)


@dataclass(frozen=True)
@defaults_from(DEFAULT_DOC["procedure"])
class ProcedureParams:
    """Test procedure: DC torque steps [N*m], platform revolutions recorded per step,
    settling time after each step change [s], ramp time of the DC change [s], the creepage
    above which the wheel counts as slipping [-], and the integrator's step: ``substeps``
    classical RK4 steps per ``samples_per_step`` output samples (samples inside a step are
    interpolated, see :func:`torquemod.twins.vtrack.rig.dynamics.integrate`)."""

    dc_torques_nm: tuple[float, ...] = checked()
    cycles_per_step: int = checked(check=between(1, None))
    settle_s: float = checked(check=NON_NEGATIVE)
    ramp_s: float = checked(check=NON_NEGATIVE)
    slip_creepage: float = checked(check=POSITIVE)
    substeps: int = checked(check=between(1, None))
    samples_per_step: int = checked(check=between(1, None))


@dataclass(frozen=True)
class SimConfig:
    """Everything one simulated experiment needs."""

    rig: RigParams
    modulation: ModulationParams = field(default_factory=ModulationParams)
    disturbances: DisturbanceParams = field(default_factory=DisturbanceParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    procedure: ProcedureParams = field(default_factory=ProcedureParams)


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
