"""mu from the phase alone (issue 8): the model against the library's Polach functions, known-
truth recovery with and without the creepage swing, the honesty rule and the 95 % interval's
coverage in a Monte Carlo.

The truth is built independently of :mod:`torquemod.analysis.phasefit`'s parametrisation: Polach
curves
in physical creepage (:func:`torquemod.analysis.contact.polach.adhesion_curve`), operating points by
brentq, the swing's mean point by brentq on
:func:`~torquemod.analysis.contact.polach.swing_average`,
the describing-function slope by :func:`~torquemod.analysis.contact.polach.swing_slope`, and
``tan(phi) = C/k`` (V-Track paper Eq. 1). Rig: V-Track-like, N = 4200 N, R = 0.0675 m,
V = 1.944 m/s, f = 2 Hz, J = 4 kg m^2 (C = Omega*J*V/(R^2*N) = 5.11), T_mod = 8 N*m; six
steps at V-Track's proportions (0.0035, 0.35, 0.68, 0.84, 0.92, 1.0) x u_max.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import binom

from torquemod.analysis.contact.polach import (
    adhesion_curve,
    adhesion_slope,
    swing_average,
    swing_slope,
)
from torquemod.analysis.phasefit import fit_mu_from_phase
from torquemod.analysis.polachshape import (
    inverse_polach_h,
    invert_polach_h,
    polach_h,
    polach_h_curvature,
    polach_h_slope,
)
from torquemod.errors import InputError

FRACTIONS = np.array([0.0035, 0.35, 0.68, 0.84, 0.92, 1.0])
N_LOAD, RADIUS, SPEED, F_MOD, INERTIA, T_MOD = 4200.0, 0.0675, 1.944, 2.0, 4.0, 8.0
C = 2 * np.pi * F_MOD * INERTIA * SPEED / (RADIUS**2 * N_LOAD)
DRY, WET, EVEN = (1.0, 0.4), (0.3, 0.1), (0.55, 0.5)  # (kA, kS); FACTS §2 and kA ~ kS


def truth(mu, shape, k0, u_max, *, swing=False):
    """(CoA, phase [deg], creepage swing or None) of the six steps on a Polach curve with
    initial slope k0 = dCoA/dxi(0); with ``swing`` the modulation's creepage swing
    a = T_mod/(R*N*|jC + k|) and the describing-function slope, iterated to consistency."""
    k_a, k_s = shape
    s = np.pi * k0 / (2 * (k_a + k_s))

    def curve(xi):
        return adhesion_curve(xi, mu=mu, k_a=k_a, k_s=k_s, stiffness=s)

    coa = FRACTIONS * u_max * mu
    xi = np.array([brentq(lambda x, c=c: float(curve(x)) - c, 0, 1, xtol=1e-15) for c in coa])
    k = adhesion_slope(xi, mu=mu, k_a=k_a, k_s=k_s, stiffness=s)
    a = None
    for _ in range(6 if swing else 0):
        a = T_MOD / (RADIUS * N_LOAD * np.abs(1j * C + k))
        xm = np.array([brentq(lambda x, c=c, w=w: float(swing_average(curve, x, w)) - c, -w, 1,
                              xtol=1e-15) for c, w in zip(coa, a, strict=True)])
        k = swing_slope(curve, xm, a)
    return coa, np.degrees(np.arctan(C / k)), a


def test_shape_function_against_the_library_and_finite_differences():
    """mu*h(kS*s*xi/mu; kA/kS) is the library's adhesion_curve (Polach 2005 Eq. 8, lumped);
    h', h'' match central differences (rtol 1e-6: O(step^2) truncation with step 1e-5);
    the inverses round-trip to 1e-9 (Newton-polished)."""
    xi = np.array([0.0, 1e-4, 1e-3, 4e-3, 2e-2])
    for k_a, k_s in (DRY, WET, EVEN):
        s, mu = 80.0, 0.3
        np.testing.assert_allclose(mu * polach_h(k_s * s * xi / mu, k_a / k_s),
                                   adhesion_curve(xi, mu=mu, k_a=k_a, k_s=k_s, stiffness=s),
                                   rtol=1e-13, atol=1e-16)
    x = np.array([0.01, 0.3, 1.0, 4.0])
    e = 1e-5
    for r in (1.0, 2.5, 7.0):
        np.testing.assert_allclose(polach_h_slope(x, r),
                                   (polach_h(x + e, r) - polach_h(x - e, r)) / (2 * e), rtol=1e-6)
        np.testing.assert_allclose(polach_h_curvature(x, r), (polach_h_slope(x + e, r)
                                   - polach_h_slope(x - e, r)) / (2 * e), rtol=1e-6, atol=1e-9)
        u = polach_h(x, r)
        np.testing.assert_allclose(inverse_polach_h(u, r), x, rtol=1e-9)
        np.testing.assert_allclose(invert_polach_h(u, r), x, rtol=1e-9)
    assert np.isnan(inverse_polach_h(1.0, 2.0))
    # initial slope of the lumped curve: 2*(kA + kS)*s/pi (FACTS §2)
    assert polach_h_slope(0.0, 2.5) == pytest.approx(2 / np.pi * 3.5)


@pytest.mark.parametrize("shape", [DRY, WET])
@pytest.mark.parametrize("swing", [False, True])
@pytest.mark.parametrize("known", [True, False])
def test_noise_free_recovery(shape, swing, known):
    """Exact phases up to 80 % of the available adhesion (Polach's dry and wet sets, which
    rise to their friction: the peak is mu), stated with 0.1 deg. With C given: determined,
    the interval holds the truth, the estimate within 0.5 % (measured <= 0.14 %), k0 within
    1.5 % (measured <= 1 %). Without C the falling-friction bound cannot apply and members
    peaking just above the top step fit as well: only the honest range is claimed (measured:
    not determined on the dry set without the swing and the wet set with it) and k is
    relative. The fitted curve passes within 0.5 deg of the phases (measured <= 0.31 deg;
    the model's own 1 % error in k is 0.24 deg at 28 deg)."""
    mu, k0 = 0.25, 100.0
    coa, phase, a = truth(mu, shape, k0, 0.8, swing=swing)
    fit = fit_mu_from_phase(coa, phase, np.full(6, 0.1), constant=C if known else None,
                            creepage_swing=a, speed_m_s=SPEED)
    a = fit.adhesion
    assert a.lower_bound < mu and (not a.closed or mu < a.high)
    if not known and not fit.mu_determined:
        # without C the falling-friction bound cannot apply (k0 unknown): measured on the
        # dry set without the swing and the wet set with it, a member peaking just above
        # the top step fits too; the range stays honest (asserted above)
        assert fit.k_relative
        return
    assert fit.mu_determined
    lo, hi = fit.mu_interval_95
    assert lo < mu < hi and (hi - lo) / 2 <= 0.10 * fit.mu
    if not swing:  # 1 % in k is 0.24 deg at 28 deg (dphi = sin(phi)cos(phi) dk/k)
        np.testing.assert_allclose(fit.phase_curve(coa), phase, atol=0.5)
    if known:
        assert fit.mu == pytest.approx(mu, rel=5e-3)
        assert fit.constant == C
        assert fit.creep_coefficient([0.0])[0] == pytest.approx(k0, rel=1.5e-2)
    else:
        assert fit.k_relative


def test_swing_is_modelled():
    """The modulation's swing raises the top phase (describing-function slope below the
    small-signal slope: +0.5 deg at 86 % on the dry set at V-Track's 8 N*m); with the swing
    modelled the adhesion is within 0.5 % (measured 0.11 %) and its interval holds the
    truth. (Left out, the estimate moves by 0.1 % here: within the broad family and its
    model error the swing matters little at 8 N*m; measured, docs/friction.md.)"""
    coa, phase, a = truth(0.25, DRY, 100.0, 0.86, swing=True)
    _, small, _ = truth(0.25, DRY, 100.0, 0.86)
    assert phase[-1] - small[-1] > 0.3  # [deg], three times the phase noise
    right = fit_mu_from_phase(coa, phase, np.full(6, 0.1), constant=C, creepage_swing=a,
                              speed_m_s=SPEED)
    assert right.mu == pytest.approx(0.25, rel=5e-3)
    assert right.mu_interval_95[0] <= 0.25 <= right.mu_interval_95[1]


def test_low_utilisation_gives_only_a_lower_bound():
    coa, phase, _ = truth(0.25, DRY, 100.0, 0.3)
    rng = np.random.default_rng(0)
    fit = fit_mu_from_phase(coa, phase + 0.1 * rng.standard_normal(6), np.full(6, 0.1))
    assert not fit.mu_determined and fit.mu is None and fit.mu_stderr is None
    lo, hi = fit.mu_interval_95
    assert hi is None and lo == fit.mu_lower_bound and coa.max() <= lo <= 0.25
    assert np.all(np.isnan(fit.utilisation))
    assert any("does not determine" in w for w in fit.warnings)
    d = fit.to_dict()
    json.dumps(d, allow_nan=False)  # strict JSON
    assert d["mu"] is None and d["mu_interval_95"][1] is None
    assert "NOT determined" in fit.report()


def test_without_the_probe_only_the_probe_depth_is_left_out():
    """``probe=False`` skips the search for the probe depth and changes nothing else: every
    field of the adhesion fit but the depth is equal, bit for bit (the depth is searched
    after the fit). The case is not determined, so the probe runs and finds a depth."""
    coa, phase, _ = truth(0.25, DRY, 100.0, 0.6)  # up to 60 %: a depth of 86 % found
    phase = phase + 0.1 * np.random.default_rng(0).standard_normal(6)
    with_probe = fit_mu_from_phase(coa, phase, np.full(6, 0.1))
    without = fit_mu_from_phase(coa, phase, np.full(6, 0.1), probe=False)
    a, b = with_probe.adhesion, without.adhesion
    assert not a.determined and np.isfinite(a.probe_depth) and np.isnan(b.probe_depth)
    for name, value in vars(a).items():
        if name != "probe_depth":
            np.testing.assert_array_equal(np.asarray(value), np.asarray(getattr(b, name)),
                                          err_msg=name)
    assert with_probe.mu_lower_bound == without.mu_lower_bound


def test_understated_errors_widen_the_interval():
    """Twelve steps (each of the six twice) with phase noise ten times the stated 0.1 deg:
    chi2/dof exceeds 1 (measured 2.07; smaller scatter is absorbed by the model's own 1 %
    error in k and in the utilisation, which at these phases is worth 0.1-0.5 deg), the
    level is scaled by it (warning) and the interval is at least as wide as with the
    stated errors taken at face value."""
    coa, phase, _ = truth(0.3, WET, 90.0, 0.86)
    coa2, phase2 = np.r_[coa, coa], np.r_[phase, phase]
    noisy = phase2 + 1.0 * np.random.default_rng(5).standard_normal(12)
    scaled = fit_mu_from_phase(coa2, noisy, np.full(12, 0.1))
    raw = fit_mu_from_phase(coa2, noisy, np.full(12, 0.1), scale_by_chi2=False)
    assert scaled.chi2_scale > 1.5 and any("scatter" in w for w in scaled.warnings)
    assert raw.chi2_scale == 1.0
    assert scaled.adhesion.level > raw.adhesion.level
    assert scaled.adhesion.high >= raw.adhesion.high
    assert scaled.adhesion.low <= raw.adhesion.low


def test_interval_coverage_monte_carlo():
    """Honesty: 90 trials over dry, wet and kA ~ kS curves (mu ~ U(0.2, 0.4), k0 ~ logU(60,
    150)), steps up to 86, 80 and 70 %, phase noise 0.1 deg and CoA noise 1e-4 per step (both
    passed as standard errors). A trial is covered when its 95 % interval holds the truth
    (determined) or its lower bound does not exceed it (not determined). Threshold 81 of 90
    (90 %): with a true coverage of 95 % fewer happens with probability
    binom.cdf(80, 90, 0.95) = 2.4 %; a 85 % coverage would pass with probability 11 %.
    Determined intervals are at most +-10 % wide (the rule), so errors stay within 10 %
    (measured: 90/90 covered, 29/90 determined, errors median 0.45 %, at most 8.9 %: the
    broad family of creep laws is honest where the Polach-only fit of earlier versions
    determined 56/90)."""
    assert binom.cdf(80, 90, 0.95) < 0.03
    rng = np.random.default_rng(2024)
    hits, determined = 0, 0
    for t in range(90):
        shape = (DRY, WET, EVEN)[t % 3]
        u_max = (0.86, 0.80, 0.70)[(t // 3) % 3]
        mu = float(rng.uniform(0.2, 0.4))
        k0 = float(np.exp(rng.uniform(np.log(60), np.log(150))))
        coa, phase, _ = truth(mu, shape, k0, u_max)
        coa_n = coa + 1e-4 * rng.standard_normal(6)
        phase_n = phase + 0.1 * rng.standard_normal(6)
        fit = fit_mu_from_phase(coa_n, phase_n, np.full(6, 0.1), coa_se=np.full(6, 1e-4))
        lo, hi = fit.mu_interval_95
        assert lo >= coa_n.max()
        if fit.mu_determined:
            determined += 1
            hits += lo <= mu <= hi
            assert (hi - lo) / 2 <= 0.10 * fit.mu and abs(fit.mu / mu - 1) < 0.10
            assert lo <= fit.mu <= hi
        else:
            hits += lo <= mu
    assert hits >= 81
    assert determined >= 20  # measured 29/90


def test_bad_input():
    with pytest.raises(InputError, match="at least 4 steps"):
        fit_mu_from_phase([0.1, 0.2, 0.3], [10, 20, 30], [0.1, 0.1, 0.1])
    with pytest.raises(InputError, match="expected 4"):
        fit_mu_from_phase([0.1, 0.2, 0.3, 0.4], [10, 20, 30], [0.1] * 4)
    with pytest.raises(InputError, match="constant"):
        fit_mu_from_phase([0.1, 0.2, 0.3, 0.4], [5, 6, 8, 12], [0.1] * 4, constant=-1.0)
    # steps outside (0, 90) deg or with NaN are left out; five remain when C is fitted
    coa, phase, _ = truth(0.25, DRY, 100.0, 0.8)
    fit = fit_mu_from_phase(np.r_[coa, 0.1], np.r_[phase, np.nan], np.full(7, 0.1))
    assert fit.coa.size == 6


def test_rig_without_forces_or_inertia():
    """The small version of benchmarks/mu_from_phase.py: Polach's dry set (kA/kS = 2.5,
    mu = 0.3) on the independent rig (tests/independent_rig.py: motor, elastic shaft, wheel
    on a platform, DOP853; it shares nothing with the estimator), six steps to 90 % of the
    available adhesion, the phase by that module's reference definition, the creepage swing
    from the wheel speed's amplitude, CoA from the DC torque; no forces, C not given, phases
    stated with 0.3 deg. Determined, within 3 % (the target for such recordings) and the
    truth inside the interval."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import mu_from_phase as bench

    import independent_rig as ir
    from torquemod.analysis.friction import fit_available_adhesion_from_phase

    rig = ir.OrbitRig(mu=0.3, k_a=1.0, k_s=0.4)
    case = bench.simulate_case(rig, 0.9)
    fit = fit_available_adhesion_from_phase(case["coa"], case["phase"], np.full(6, 0.3),
                                            creepage_swing=case["swing"],
                                            speed_m_s=rig.speed_m_s, probe=False)
    assert case["P"] == pytest.approx(0.3)
    assert fit.determined and fit.low <= case["P"] <= fit.high
    assert fit.estimate == pytest.approx(case["P"], rel=0.03)
    # C (and the inertia) from the torque and wheel-speed amplitudes: the true inertia
    # within the stated 95 % range, and the fit with it determined, within 3 %, covered
    est = bench.measured_c(rig, case, case["phase"], np.full(6, 0.3), np.zeros(6))
    assert est.n == 6 and 0.02 <= est.rel_se < 0.1
    assert abs(est.inertia_kg_m2 / rig.wheel_inertia_kg_m2 - 1) <= 1.96 * est.rel_se
    assert abs(est.constant / case["C"] - 1) <= 1.96 * est.rel_se
    fit = fit_available_adhesion_from_phase(case["coa"], case["phase"], np.full(6, 0.3),
                                            constant=est.constant,
                                            constant_rel_se=est.rel_se,
                                            creepage_swing=case["swing"],
                                            speed_m_s=rig.speed_m_s, probe=False)
    assert fit.determined and fit.low <= case["P"] <= fit.high
    assert fit.estimate == pytest.approx(case["P"], rel=0.03)


def test_constant_from_amplitudes_inverts_the_rigid_wheel_impedance():
    """Amplitudes and phases made from dT/dw = j*Omega*J + R^2*N*k/V (the rigid wheel) give
    C = Omega*J*V/(R^2*N) and J back to rounding; the stated error is never below the model
    error; one usable step is not enough."""
    from torquemod.analysis.phasefit import MODEL_REL_CONSTANT, constant_from_amplitudes

    r, n, j, v, f = 0.0675, 4200.0, 4.0, 1.944, 2.0
    k = np.array([150.0, 120.0, 80.0, 40.0, 15.0, 5.0])
    z = 1j * 2 * np.pi * f * j + r * r * n * k / v
    w_amp = 0.03 + 0.01 * np.arange(6)
    t_amp = np.abs(z) * w_amp
    phase = np.degrees(np.angle(z))
    est = constant_from_amplitudes(t_amp, w_amp, phase, np.zeros(6), v, f, wheel_radius_m=r,
                                   normal_load_n=n)
    assert est.constant == pytest.approx(2 * np.pi * f * j * v / (r * r * n), rel=1e-12)
    assert est.inertia_kg_m2 == pytest.approx(j, rel=1e-12)
    assert est.rel_se == pytest.approx(MODEL_REL_CONSTANT)
    noisy = constant_from_amplitudes(t_amp, w_amp, phase, np.full(6, 2.0), v, f,
                                     wheel_radius_m=r, normal_load_n=n)
    assert noisy.rel_se > est.rel_se
    assert constant_from_amplitudes(t_amp[:1], w_amp[:1], phase[:1], [0.1], v, f,
                                    wheel_radius_m=r, normal_load_n=n) is None


def test_analyze_without_inertia_measures_c_from_the_amplitudes():
    """With no wheel inertia given, analyze takes C from the steps' amplitude columns, says
    so in fit.json (``mu_from_phase_constant_source``) and in a warning with its
    uncertainty. The synthetic steps carry no amplitudes; they are written here from the
    rigid-wheel impedance of the experiment's J (``sin(phi)*|T|/|w| = Omega*J``), so the C
    analyze uses must equal Omega*J*V/(R^2*N) to rounding (the wiring, not the accuracy:
    that is the independent rig's test above). With the inertia given, the source says
    so."""
    import dataclasses

    import torquemod as tm
    from torquemod.demo import synthetic_result

    res = synthetic_result(seed=0)
    rig, test = res.experiment.rig, res.experiment.test
    j = rig.extra["wheel_inertia_kg_m2"]
    assert tm.analyze(res).to_dict()["mu_from_phase_constant_source"] == "rig inertia"
    om_j = 2 * np.pi * test.modulation_frequency_hz * j
    steps = res.steps.copy()
    steps["wheel_amplitude_rad_s"] = 0.03
    steps["torque_amplitude_nm"] = om_j / np.sin(np.radians(steps["phase_deg"])) * 0.03
    bare = dataclasses.replace(rig, extra={k: v for k, v in rig.extra.items()
                                           if k != "wheel_inertia_kg_m2"})
    res = dataclasses.replace(res, steps=steps,
                              experiment=dataclasses.replace(res.experiment, rig=bare))
    a = tm.analyze(res)
    assert a.to_dict()["mu_from_phase_constant_source"] == "amplitudes"
    assert any("amplitude ratio" in w for w in a.warnings)
    pf = a.phase_fit
    assert pf.constant_given and pf.constant_rel_se >= 0.02
    c_true = (om_j * float(np.median(steps["speed_m_s"]))
              / (rig.wheel_radius_m**2 * test.normal_load_n))
    assert pf.constant == pytest.approx(c_true, rel=1e-9)
