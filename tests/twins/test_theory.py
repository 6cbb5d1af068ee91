"""Small-signal theory: rigid-wheel formula, drive-line response, steady state."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import curve_fit

from torquemod.analysis.contact.polach import adhesion_curve
from torquemod.errors import InputError
from torquemod.twins.vtrack.rig.dynamics import N_STATES, _deriv, initial_state, pack_parameters
from torquemod.twins.vtrack.simulate import load_config
from torquemod.twins.vtrack.smallsignal import (
    creep_coefficient_from_phase,
    creep_coefficient_from_predicted_phase,
    drive_line_response,
    predicted_phase_deg,
    rigid_wheel_phase_deg,
)
from torquemod.twins.vtrack.theory import creep_curve_peak, large_signal_phase_deg, operating_point

TABLE1 = (0.23, 22.84, 44.47, 55.22, 60.45, 65.82)
RIGID = dict(inertia_kg_m2=1.5, speed_m_s=7 / 3.6, wheel_radius_m=0.0675, normal_load_n=4200.0,
             frequency_hz=2.0)


@pytest.fixture(scope="module")
def cfg():
    return load_config(overrides={"disturbances": {"enabled": False}})


def test_rigid_phase_formula_by_hand():
    k = 20.0
    tan = 2 * math.pi * 2.0 * 1.5 * (7 / 3.6) / (0.0675**2 * 4200 * k)
    assert rigid_wheel_phase_deg(k, **RIGID) == pytest.approx(math.degrees(math.atan(tan)))
    assert rigid_wheel_phase_deg(0.0, **RIGID) == pytest.approx(90.0)
    ks = np.array([1.0, 10.0, 100.0])
    ph = rigid_wheel_phase_deg(ks, **RIGID)
    assert ph.shape == (3,) and np.all(np.diff(ph) < 0)


def test_rigid_inverse_round_trip():
    ks = np.array([0.5, 3.0, 30.0, 300.0])
    back = creep_coefficient_from_phase(rigid_wheel_phase_deg(ks, **RIGID), **RIGID)
    np.testing.assert_allclose(back, ks, rtol=1e-10)
    with pytest.raises(InputError):
        creep_coefficient_from_phase(-3.0, **RIGID)


def test_full_model_reduces_to_rigid_for_stiff_platform(cfg):
    rig = dataclasses.replace(cfg.rig, platform_kp_nm_s_rad=1e15, platform_ki_nm_rad=0.0)
    ks = np.array([0.3, 3.0, 30.0])
    ref = rigid_wheel_phase_deg(ks, inertia_kg_m2=rig.wheel_inertia_kg_m2,
                                speed_m_s=rig.speed_m_s, wheel_radius_m=rig.wheel_radius_m,
                                normal_load_n=rig.normal_load_n, frequency_hz=2.0)
    np.testing.assert_allclose(predicted_phase_deg(ks, rig, 2.0), ref, atol=1e-6)


def test_phase_does_not_depend_on_what_is_upstream_of_the_sensor(cfg):
    """The sensor measures the shaft torque and its encoder turns with the wheel, so motor
    inertia and shaft stiffness change amplitudes but not the phase between them."""
    ks = np.array([0.5, 5.0, 25.0])
    base = predicted_phase_deg(ks, cfg.rig, 2.0)
    other = dataclasses.replace(cfg.rig, drive_inertia_kg_m2=5.0, shaft_stiffness_nm_rad=3e3,
                                shaft_damping_nm_s_rad=1.0)
    np.testing.assert_allclose(predicted_phase_deg(ks, other, 2.0), base, atol=1e-9)
    h1 = drive_line_response(ks, cfg.rig, 2.0)[0]
    h2 = drive_line_response(ks, other, 2.0)[0]
    assert not np.allclose(h1, h2)


def test_predicted_phase_monotone_and_inverse(cfg):
    # over the creep coefficients the contact model can take (initial slope ~30); far beyond,
    # the stiff contact locks the wheel to the platform and the platform drive sets the phase
    ks = np.geomspace(0.05, 50, 40)
    ph = predicted_phase_deg(ks, cfg.rig, 2.0)
    assert np.all(np.diff(ph) < 0) and ph[0] < 90 and ph[-1] > 0
    for k in (0.2, 5.0, 40.0):
        phase = float(predicted_phase_deg(k, cfg.rig, 2.0))
        assert creep_coefficient_from_predicted_phase(phase, cfg.rig, 2.0) == pytest.approx(
            k, rel=1e-8)


def _jacobian_response(cfg, dc, freq):
    """Transfer functions from the numerical Jacobian of the simulator's own equations."""
    rig = cfg.rig
    op = operating_point(dc, rig)
    p = pack_parameters(rig, cfg.disturbances)
    y0 = initial_state(rig, creepage=op.creepage, dc_torque_nm=dc, contact_fx_n=op.fx_n)
    f = np.empty(4)

    def rhs(y, tm=dc):
        dy = np.empty(N_STATES)
        _deriv(y, tm, p, dy, f)
        return dy

    a = np.zeros((N_STATES, N_STATES))
    for j in range(N_STATES):
        h = 1e-7 * max(1.0, abs(y0[j]))
        e = np.zeros(N_STATES)
        e[j] = h
        a[:, j] = (rhs(y0 + e) - rhs(y0 - e)) / (2 * h)
    b = (rhs(y0, dc + 1.0) - rhs(y0, dc - 1.0)) / 2.0
    s = 2j * np.pi * freq
    x = np.linalg.solve(s * np.eye(N_STATES) - a, b)
    torque = rig.shaft_stiffness_nm_rad * x[0] + rig.shaft_damping_nm_s_rad * (x[1] - x[2])
    return op, torque, x[2]


@pytest.mark.parametrize("dc", [22.84, 55.22, 65.82])
def test_theory_matches_linearised_simulator_equations(cfg, dc):
    op, h_t, h_w = _jacobian_response(cfg, dc, 2.0)
    th_t, th_w = drive_line_response(op.creep_coefficient, cfg.rig, 2.0, creepage=op.creepage)
    assert abs(h_t / th_t - 1) < 2e-3 and abs(h_w / th_w - 1) < 2e-3
    ph_jac = math.degrees(np.angle(h_t / h_w))
    assert ph_jac == pytest.approx(
        float(predicted_phase_deg(op.creep_coefficient, cfg.rig, 2.0, creepage=op.creepage)),
        abs=0.02)


def test_operating_point_balances_torque(cfg):
    for dc in TABLE1:
        op = operating_point(dc, cfg.rig)
        assert not op.slipped
        assert op.fx_n * cfg.rig.wheel_radius_m == pytest.approx(dc, rel=1e-9, abs=1e-12)
        assert op.creep_coefficient > 0
    assert operating_point(72.0, cfg.rig).slipped
    xi_peak, t_peak = creep_curve_peak(cfg.rig)
    assert 65.82 < t_peak < 72.0 and 0 < xi_peak < 0.05


def test_default_theory_phase_flat_then_rising_and_fit_near_024(cfg):
    """What the default rig's small-signal theory gives at the paper's six torques (not the
    paper's phases themselves): phase within a factor 1.8 over steps 1-3, rising by > 1.5x at
    step 4, steps 1 and 6 in broad bands, and a noise-free Polach fit (no velocity
    dependence) of the steady-state points giving mu within 0.01 of the paper's 0.24."""
    ops = [operating_point(dc, cfg.rig) for dc in TABLE1]
    ph = [float(predicted_phase_deg(o.creep_coefficient, cfg.rig, 2.0)) for o in ops]
    assert max(ph[:3]) / min(ph[:3]) < 1.8
    assert ph[3] / ph[2] > 1.5
    assert 1.0 < ph[0] < 15.0 and 20.0 < ph[5] < 80.0  # J = 4 kg*m^2: about 11 and 70 deg
    xi = np.array([o.creepage for o in ops])
    coa = np.array([o.coa for o in ops])
    popt, _ = curve_fit(lambda x, mu, ka, ks, st: adhesion_curve(x, mu=mu, k_a=ka, k_s=ks,
                                                                  stiffness=st),
                        xi, coa, p0=[0.25, 0.3, 0.3, 100.0],
                        bounds=([0.05, 0.01, 0.001, 1.0], [1.0, 10.0, 10.0, 1e4]))
    assert popt[0] == pytest.approx(0.24, abs=0.01)


# --------------------------------------------------------------------------------------------
# Large-signal prediction (harmonic balance of the nonlinear wheel + contact + platform)
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("drive", ["shaft", "motor"])
def test_large_signal_tends_to_small_signal(cfg, drive):
    f = cfg.modulation.actual_frequency_hz
    for dc in TABLE1[1:5]:
        r = large_signal_phase_deg(dc, cfg.rig, f, 0.05, drive=drive)
        assert not r.slipped
        assert r.phase_deg == pytest.approx(r.small_signal_phase_deg, abs=0.02)
        op = operating_point(dc, cfg.rig)
        assert r.small_signal_phase_deg == pytest.approx(float(predicted_phase_deg(
            op.creep_coefficient, cfg.rig, f, creepage=op.creepage)), abs=1e-12)
        assert r.mean_creepage == pytest.approx(op.creepage, rel=1e-3)
        assert r.mean_creep_coefficient == pytest.approx(op.creep_coefficient, rel=1e-3)
    # without the platform loop it tends to the rigid-wheel formula (stiff platform)
    op = operating_point(TABLE1[3], cfg.rig)
    r = large_signal_phase_deg(TABLE1[3], cfg.rig, f, 0.05, platform=False)
    rig = cfg.rig
    assert r.phase_deg == pytest.approx(float(rigid_wheel_phase_deg(
        op.creep_coefficient, inertia_kg_m2=rig.wheel_inertia_kg_m2, speed_m_s=rig.speed_m_s,
        wheel_radius_m=rig.wheel_radius_m, normal_load_n=rig.normal_load_n, frequency_hz=f)),
        abs=0.02)


def test_large_signal_is_resolved_and_its_shaft_amplitude_is_exact(cfg):
    f = cfg.modulation.actual_frequency_hz
    for dc in (TABLE1[0], TABLE1[5]):  # the swing through zero creepage; near saturation
        a = large_signal_phase_deg(dc, cfg.rig, f, 8.0, drive="motor")
        b = large_signal_phase_deg(dc, cfg.rig, f, 8.0, drive="motor", n_samples=256)
        assert b.phase_deg == pytest.approx(a.phase_deg, abs=1e-6)
        assert b.mean_creepage == pytest.approx(a.mean_creepage, rel=1e-9)
        s = large_signal_phase_deg(dc, cfg.rig, f, 8.0)
        assert s.torque_amplitude_nm == pytest.approx(8.0, rel=1e-12)
        # the motor's 8 N*m arrive in the shaft reduced, as drive_line_response says
        h_t = drive_line_response(a.mean_creep_coefficient, cfg.rig, f)[0]
        assert a.torque_amplitude_nm == pytest.approx(8.0 * abs(h_t), rel=0.02)


def test_large_signal_matches_time_integration_of_the_wheel(cfg):
    """Independent check of the collocation: integrate the 1-DOF wheel (platform at its set
    speed, driven by the shaft torque) with solve_ivp until periodic and fit harmonic 1."""
    from scipy.integrate import solve_ivp

    from torquemod.analysis.contact.polach import creep_force_kernel

    rig, f = cfg.rig, cfg.modulation.actual_frequency_hz
    c = rig.contact
    om, v, rw, amp = 2 * np.pi * f, rig.speed_m_s, rig.wheel_radius_m, 8.0
    for dc in (TABLE1[0], TABLE1[5]):
        op = operating_point(dc, rig)

        def rhs(t, y, dc=dc):
            xi = y[0] * rw / v - 1.0
            fx = creep_force_kernel(xi, c.lateral_creepage, rig.normal_load_n, v,
                                    c.stiffness_x_n, c.stiffness_y_n, c.mu0, c.a_ratio,
                                    c.b_s_m, c.k_a, c.k_s)[0]
            return [(dc + amp * math.sin(om * t) - rw * fx) / rig.wheel_inertia_kg_m2]

        periods = 12
        t_eval = (periods - 1 + np.arange(400) / 400) / f  # the last period
        sol = solve_ivp(rhs, (0, periods / f), [v * (1 + op.creepage) / rw], method="DOP853",
                        rtol=1e-11, atol=1e-12, t_eval=t_eval)
        w = sol.y[0]
        basis = np.column_stack([np.sin(om * t_eval), np.cos(om * t_eval),
                                 np.ones_like(t_eval)])
        sin_c, cos_c, _ = np.linalg.lstsq(basis, w, rcond=None)[0]
        phase = -math.degrees(math.atan2(cos_c, sin_c))  # torque is a pure sine
        xi_mean = float(np.mean(w * rw / v - 1.0))
        r = large_signal_phase_deg(dc, rig, f, amp, platform=False)
        assert r.phase_deg == pytest.approx(phase, abs=1e-3)
        assert r.speed_amplitude_rad_s == pytest.approx(math.hypot(sin_c, cos_c), rel=1e-4)
        assert r.mean_creepage == pytest.approx(xi_mean, rel=1e-4)


@pytest.fixture(scope="module")
def short_simulation(tmp_path_factory):
    """The simulator without disturbances: step 1, a middle step and the step nearest
    saturation, one revolution each after 2 s of settling (about 0.2 s of simulation)."""
    from torquemod.twins.vtrack.simulate import run_simulation

    steps = [TABLE1[0], TABLE1[2], TABLE1[5]]
    config = load_config(None, overrides={
        "disturbances": {"enabled": False},
        "procedure": {"dc_torques_nm": steps, "cycles_per_step": 1, "settle_s": 2.0}})
    out = tmp_path_factory.mktemp("large_signal") / "exp"
    truth = run_simulation(config, out, fmt="hdf5", progress=False, files_per_cycle=False)
    return config, out, truth


def test_large_signal_matches_the_simulator(short_simulation):
    from torquemod.io import read_recording
    from torquemod.twins.vtrack.simulate import sine_fit_phase_deg

    config, out, truth = short_simulation
    rig, f = config.rig, config.modulation.actual_frequency_hz
    for step in truth["steps"]:
        assert not step["slipped"]
        rec = read_recording(out / f"step{step['step']:02d}.h5")
        ch = rec.channels
        sim_phase = sine_fit_phase_deg(ch["torque_nm"], ch["wheel_speed_rad_s"], rec.fs_hz, f)
        assert sim_phase == pytest.approx(step["simulated"]["phase_deg"], abs=1e-9)
        # whole modulation periods, as the sine fit uses
        n = int(np.floor(rec.n_samples / rec.fs_hz * f) * rec.fs_hz / f)
        xi = ch["wheel_speed_rad_s"][:n] * rig.wheel_radius_m / (
            ch["platform_speed_rad_s"][:n] * rig.platform_radius_m) - 1.0
        tt = np.arange(n) / rec.fs_hz
        basis = np.column_stack([np.cos(2 * np.pi * f * tt), np.sin(2 * np.pi * f * tt),
                                 np.ones(n)])
        torque_amp = float(np.hypot(*np.linalg.lstsq(basis, ch["torque_nm"][:n],
                                                     rcond=None)[0][:2]))

        dc = step["dc_torque_nm"]
        motor = large_signal_phase_deg(dc, rig, f, config.modulation.amplitude_nm,
                                       drive="motor")
        assert motor.phase_deg == pytest.approx(sim_phase, abs=0.3)
        assert motor.torque_amplitude_nm == pytest.approx(torque_amp, rel=1e-3)
        assert motor.mean_creepage == pytest.approx(float(xi.mean()), rel=0.01)
        # driven by the measured torque at its measured amplitude: the drive line drops out
        # up to the torque harmonics the wheel sends back
        shaft = large_signal_phase_deg(dc, rig, f, torque_amp)
        assert shaft.phase_deg == pytest.approx(sim_phase, abs=0.3)
        assert shaft.mean_creepage == pytest.approx(float(xi.mean()), rel=0.01)
        if dc != TABLE1[0]:  # truth.json averages over whole revolutions, not periods
            assert motor.mean_creepage == pytest.approx(step["simulated"]["creepage_mean"],
                                                        rel=0.02)
    # step 1 and the step near saturation are where the small-signal theory misses
    first, last = truth["steps"][0], truth["steps"][-1]
    for step in (first, last):
        assert abs(step["phase_theory_deg"] - step["simulated"]["phase_deg"]) > 0.5


def test_large_signal_input_checks_and_slip(cfg):
    f = cfg.modulation.actual_frequency_hz
    with pytest.raises(InputError):
        large_signal_phase_deg(20.0, cfg.rig, f, 8.0, drive="wheel")
    with pytest.raises(InputError):
        large_signal_phase_deg(20.0, cfg.rig, f, 0.0)
    with pytest.raises(InputError):
        large_signal_phase_deg(20.0, cfg.rig, -2.0, 8.0)
    r = large_signal_phase_deg(72.0, cfg.rig, f, 8.0)
    assert r.slipped and math.isnan(r.phase_deg)
    near = large_signal_phase_deg(69.0, cfg.rig, f, 8.0, drive="motor")
    assert not near.slipped and 80.0 < near.phase_deg < 90.0
    assert near.creepage_max > near.creepage_min > 0


def test_doubled_collocation_starts_from_the_coarser_solution(cfg):
    """Step 1 (creepage through zero) needs 128 points; Newton there starts from the
    64-point solution interpolated and reaches the state a start from the small-signal
    response reaches (phase to 1e-12 deg: both converge quadratically to rounding) in fewer
    iterations. The result is remembered per argument set."""
    from torquemod.twins.vtrack import theory

    rig, f = cfg.rig, cfg.modulation.actual_frequency_hz
    dc = TABLE1[0]
    op = operating_point(dc, rig)
    coarse = theory._periodic_state(dc, rig, op, f, 8.0, "motor", True, 64, 1e-10, 50)
    cold = theory._periodic_state(dc, rig, op, f, 8.0, "motor", True, 128, 1e-10, 50)
    warm = theory._periodic_state(dc, rig, op, f, 8.0, "motor", True, 128, 1e-10, 50,
                                  coarse[5])

    def phase(sol):
        t1, w1 = np.fft.rfft(sol[0])[1], np.fft.rfft(sol[1])[1]
        return math.degrees(np.angle(t1 / w1))

    assert abs(phase(warm) - phase(cold)) < 1e-12
    assert warm[4] < cold[4]
    res = large_signal_phase_deg(dc, rig, f, 8.0, drive="motor")
    assert res.n_samples == 128 and res.iterations == warm[4]
    assert abs(res.phase_deg - phase(warm)) < 1e-13
    assert large_signal_phase_deg(dc, rig, f, 8.0, drive="motor") is res
