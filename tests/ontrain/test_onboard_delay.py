"""The net torque-speed delay measured from a run's windows (torquemod.ontrain.delay).

References: ratios T/w built directly from the wheelset's equation of motion (the rigid
wheelset loaded by the contact damping D in series with the vehicle's mass, solved here
independently of load_impedance), rotated by a known delay, with phase noise of a known
standard error; the estimate must find the injected delay within its stated error, and the
estimator's creep coefficients must come back to the truth once it does.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from torquemod.io.run import Vehicle
from torquemod.ontrain import OnboardConfig, OnboardEstimator, measure_window
from torquemod.ontrain.delay import DelayCalibrator, delay_grid

VEH = Vehicle(wheel_radius_m=0.43, normal_load_n=1.6e5, inertia_kg_m2=250.0)
F_HZ, M_VEH, V_M_S = 4.0, 2773.0, 22.0  # modulation, vehicle inertia at the wheel, speed
GRID = np.arange(-0.005, 0.02 + 1e-12, 2.5e-4)


def _true_ratio(k: float) -> complex:
    """T/w of the wheel of inertia J loaded by D = R^2*N*k/V in series with j*Omega*M'."""
    jw = 2j * math.pi * F_HZ
    d = VEH.wheel_radius_m ** 2 * VEH.normal_load_n * k / V_M_S
    return jw * VEH.inertia_kg_m2 + 1.0 / (1.0 / d + 1.0 / (jw * M_VEH))


def _windows(delay_s: float, rng, n: int = 200, se_deg: float = 1.5, k_range=(3.0, 80.0)):
    """(ratio, phase se [rad]) of n windows whose k spans k_range (log-uniform), with the
    torque ``delay_s`` late and phase and log-amplitude noise of ``se_deg``."""
    se = math.radians(se_deg)
    ks = np.exp(rng.uniform(*np.log(k_range), n))
    out = []
    for k in ks:
        r = _true_ratio(k) * cmath.exp(-2j * math.pi * F_HZ * delay_s)
        r *= (1 + se * rng.standard_normal()) * cmath.exp(1j * se * rng.standard_normal())
        out.append((r, se))
    return out


@pytest.mark.parametrize("delay_s", [0.0, 0.003, 0.008])
def test_injected_delay_found(delay_s):
    cal = DelayCalibrator(VEH, F_HZ, GRID)
    for r, se in _windows(delay_s, np.random.default_rng(1)):
        cal.add(r, se)
    est = cal.estimate()
    assert est.trusted
    assert est.se_s < 5e-4
    assert abs(est.delay_s - delay_s) < 3 * est.se_s


def test_stated_error_covers_the_truth():
    """Monte Carlo, 60 runs of 120 windows (3 ms injected): the truth within 1.96 standard
    errors in >= 85 % of them (95 % nominal; binomial 5th percentile for 60 draws at 0.95 is
    ~0.90, the first-order error propagation is allowed a little)."""
    rng = np.random.default_rng(7)
    hits = runs = 0
    for _ in range(60):
        cal = DelayCalibrator(VEH, F_HZ, GRID)
        for r, se in _windows(0.003, rng, n=120):
            cal.add(r, se)
        est = cal.estimate()
        assert est.trusted
        runs += 1
        hits += abs(est.delay_s - 0.003) <= 1.96 * est.se_s
    assert hits / runs >= 0.85


def test_one_operating_point_does_not_determine_the_delay():
    """All windows at one k: Re(1/G) does not spread, so no delay is taken out."""
    cal = DelayCalibrator(VEH, F_HZ, GRID)
    for r, se in _windows(0.003, np.random.default_rng(2), k_range=(20.0, 20.0001)):
        cal.add(r, se)
    est = cal.estimate()
    assert not est.trusted and est.delay_s == 0.0


def test_too_few_windows_give_no_estimate():
    cal = DelayCalibrator(VEH, F_HZ, GRID, min_windows=40)
    for r, se in _windows(0.003, np.random.default_rng(3), n=39):
        cal.add(r, se)
    assert cal.estimate() == type(cal.estimate())(0.0, math.nan, 39, False)


def _window_signals(k: float, delay_s: float, fs: float = 1000.0, seconds: float = 1.25):
    """Noise-free torque and axle speed of one window at creep coefficient k, the torque
    recorded ``delay_s`` late."""
    t = np.arange(round(seconds * fs)) / fs
    om, amp = 2 * math.pi * F_HZ, 600.0
    h = 1.0 / _true_ratio(k)
    torque = 8000.0 + amp * np.sin(om * (t - delay_s))
    wheel = V_M_S / VEH.wheel_radius_m * 1.002 + amp * abs(h) * np.sin(om * t + cmath.phase(h))
    return torque, wheel, np.full(t.size, V_M_S), V_M_S * t


def test_estimator_takes_the_measured_delay_out():
    """Windows over k from 4 to 60, the torque 3 ms late, undeclared: once the calibrator
    trusts its estimate, the rows' creep coefficients are within 0.5 % of the truth (the
    delay's bias was > 5 % on some); with calibrate_delay = 0 they stay biased."""
    rng = np.random.default_rng(4)
    ks = np.exp(rng.uniform(np.log(4.0), np.log(60.0), 120))
    wins = [measure_window(*_window_signals(k, 0.003), 1000.0, 1.0, VEH, F_HZ) for k in ks]
    # noise-free windows report a phase se of ~0: give them a realistic one for the weights
    wins = [w.__class__(**{**w.__dict__, "phase_se_deg": 1.0}) for w in wins]
    rows = {}
    for flag in (1, 0):
        est = OnboardEstimator(VEH, F_HZ, 1000.0,
                               config=OnboardConfig(calibrate_delay=flag, min_windows=1000))
        rows[flag] = [est.update(w) for w in wins]
    late = slice(80, None)
    got = np.array([r["creep_coefficient"] for r in rows[1][late]])
    raw = np.array([r["creep_coefficient"] for r in rows[0][late]])
    assert rows[1][-1]["delay_s"] == pytest.approx(0.003, abs=2e-5)
    assert np.max(np.abs(got / ks[late] - 1)) < 0.005
    assert np.max(np.abs(raw / ks[late] - 1)) > 0.05


def test_grid_searches_both_signs_within_a_sixth_of_the_period():
    """delay_grid: -tau..tau in 0.25 ms steps, tau = min(delay_max_s, 1/(6 f))."""
    g = delay_grid(0.02, 4.0)
    assert g[0] == pytest.approx(-0.02) and g[-1] == pytest.approx(0.02)
    assert np.allclose(np.diff(g), 2.5e-4) and np.any(np.abs(g) < 1e-15)
    g10 = delay_grid(0.02, 10.0)  # 1/60 s = 16.7 ms caps it
    assert g10[-1] == pytest.approx(0.0165) and g10[0] == pytest.approx(-0.0165)
    assert 2 * math.pi * 10.0 * g10[-1] <= math.pi / 3


def test_speed_behind_the_torque_found():
    """A speed counted over a gate lags the torque: a net delay of -5 ms (e.g. a two-sample
    gate at 200 Hz) is found on the default grid within 3 standard errors."""
    cal = DelayCalibrator(VEH, F_HZ, delay_grid(0.02, F_HZ))
    for r, se in _windows(-0.005, np.random.default_rng(5)):
        cal.add(r, se)
    est = cal.estimate()
    assert est.trusted and abs(est.delay_s + 0.005) < 3 * est.se_s


def test_estimator_keeps_the_last_trusted_delay():
    """120 windows with the torque 3 ms late make the delay trusted; then 120 windows whose
    delays scatter by +-15 ms (the stated phase error far too small) inflate the standard
    error until the estimate is no longer trusted: the rows keep the 3 ms found before
    instead of falling back to no correction."""
    rng = np.random.default_rng(6)
    ks = np.exp(rng.uniform(np.log(4.0), np.log(60.0), 240))
    delays = np.concatenate([np.full(120, 0.003), rng.uniform(-0.015, 0.015, 120)])
    wins = [measure_window(*_window_signals(k, d), 1000.0, 1.0, VEH, F_HZ)
            for k, d in zip(ks, delays, strict=True)]
    wins = [w.__class__(**{**w.__dict__, "phase_se_deg": 1.0}) for w in wins]
    est = OnboardEstimator(VEH, F_HZ, 1000.0, config=OnboardConfig(min_windows=1000))
    rows = [est.update(w) for w in wins]
    assert rows[119]["delay_s"] == pytest.approx(0.003, abs=2e-5)
    assert not est.delay.estimate().trusted
    assert rows[-1]["delay_s"] == pytest.approx(0.003, abs=5e-4)
