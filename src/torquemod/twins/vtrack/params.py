"""Parameters of the V-Track digital twin as frozen dataclasses (SI units throughout).

Which values come from the V-Track paper and which are assumed is documented where the
defaults live: ``torquemod/data/vtrack_default.toml`` (``torquemod simulate --print-config``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


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
class ModulationParams:
    """Motor controller: DC torque plus ``amplitude_nm`` [N*m] at ``frequency_hz`` [Hz]
    (nominal) generated on the controller's own clock, which runs ``frequency_offset``
    (relative, e.g. 1e-3) fast; ``random_phase`` draws the generator phase per recording."""

    amplitude_nm: float = 8.0
    frequency_hz: float = 2.0
    frequency_offset: float = 0.0
    random_phase: bool = True

    @property
    def actual_frequency_hz(self) -> float:
        return self.frequency_hz * (1.0 + self.frequency_offset)


@dataclass(frozen=True)
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

    enabled: bool = True
    wheel_encoder_ecc1_rad: float = 0.0
    wheel_encoder_ecc2_rad: float = 0.0
    wheel_encoder_phase1_rad: float = 0.0
    wheel_encoder_phase2_rad: float = 0.0
    platform_encoder_ecc1_rad: float = 0.0
    platform_encoder_ecc2_rad: float = 0.0
    platform_encoder_phase1_rad: float = 0.0
    platform_encoder_phase2_rad: float = 0.0
    sleeper_count: int = 100
    sleeper_load_n: float = 0.0
    joint_count: int = 4
    joint_load_n: float = 0.0
    joint_frequency_hz: float = 40.0
    joint_damping_ratio: float = 0.1
    speed_wobble_enabled: bool = True
    speed_wobble_rms: float = 0.0
    speed_wobble_band_hz: tuple[float, float] = (0.2, 0.6)
    speed_wobble_components: int = 3
    speed_wobble_rev1: float = 0.0
    speed_wobble_rev2: float = 0.0


@dataclass(frozen=True)
class SensorParams:
    """Sampling rate [Hz] and white-noise standard deviations of each sensor."""

    sample_rate_hz: float = 16670.0
    torque_noise_nm: float = 0.0
    wheel_speed_noise_rad_s: float = 0.0
    platform_speed_noise_rad_s: float = 0.0
    force_noise_n: float = 0.0


@dataclass(frozen=True)
class ProcedureParams:
    """Test procedure: DC torque steps [N*m], platform revolutions recorded per step,
    settling time after each step change [s], ramp time of the DC change [s], the creepage
    above which the wheel counts as slipping [-], and the integrator's step: ``substeps``
    classical RK4 steps per ``samples_per_step`` output samples (samples inside a step are
    interpolated, see :func:`torquemod.twins.vtrack.rig.lanes.integrate`)."""

    dc_torques_nm: tuple[float, ...] = (0.23, 22.84, 44.47, 55.22, 60.45, 65.82, 72.0)
    cycles_per_step: int = 3
    settle_s: float = 4.0
    ramp_s: float = 0.5
    slip_creepage: float = 0.05
    substeps: int = 1
    samples_per_step: int = 8


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
