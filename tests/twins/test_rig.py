"""The twin's equations of motion, integrator, disturbances and sensors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from torquemod.twins.vtrack.rig.dynamics import (
    OUT_COLUMNS,
    _wob_rev,
    _wob_set,
    _wob_step,
    _wobble,
    initial_state,
    normal_load,
    pack_parameters,
    wobble_reference,
    wobble_table,
)
from torquemod.twins.vtrack.rig.lanes import integrate
from torquemod.twins.vtrack.rig.sensors import encoder_speed, measure
from torquemod.twins.vtrack.simulate import MAX_LAMBDA_H, load_config, stiffest_rate
from torquemod.twins.vtrack.theory import operating_point

COL = {n: i for i, n in enumerate(OUT_COLUMNS)}
FS = 16670.0


@pytest.fixture(scope="module")
def quiet():
    return load_config(overrides={"disturbances": {"enabled": False}})


@pytest.fixture(scope="module")
def noisy():
    return load_config()


@pytest.fixture(scope="module")
def wobble(noisy):
    """The default speed-loop wobble as drawn for one run."""
    return wobble_table(noisy.disturbances, noisy.rig.platform_speed_rad_s,
                        np.random.default_rng(5))


def run(cfg, dc, seconds, *, amp=0.0, substeps=1, samples_per_step=None, dc_from=None,
        phase=0.3, ramp_s=0.5, final_state=False, wobble=None):
    """Integrate from the steady state at ``dc_from`` (default ``dc``) with the configured
    step unless ``samples_per_step`` is given, the speed reference wobbling by ``wobble``
    (rows of :func:`wobble_table`; None: steady)."""
    rig = cfg.rig
    m = cfg.procedure.samples_per_step if samples_per_step is None else samples_per_step
    op = operating_point(dc if dc_from is None else dc_from, rig)
    y = initial_state(rig, creepage=op.creepage, dc_torque_nm=op.dc_torque_nm,
                      contact_fx_n=op.fx_n)
    if wobble is not None:  # start on the wobbling reference, the wheel rolling with it
        y[[1, 2, 5]] *= 1.0 + _wobble(0.0, 0.0, wobble) / rig.platform_speed_rad_s
    p = pack_parameters(rig, cfg.disturbances)
    n = int(seconds * FS)
    out = np.empty((n, len(OUT_COLUMNS)))
    done, slipped = integrate(y, 0.0, n, 1 / FS, substeps, p, op.dc_torque_nm, dc, 0.0,
                              ramp_s, amp, 2 * np.pi * 2.0, phase, 0.0, 0.05, out, m, wobble)
    return (out[:done], slipped, y) if final_state else (out[:done], slipped)


def test_default_step():
    """The configured step spans twelve samples (h = 12/16670 s, within MAX_STEP_S). The
    stiffest mode, the platform's PI loop (lambda ~ 3300 1/s, lambda*h = 2.4), is taken
    exactly; the explicit part's fastest, the torsional mode (~196 1/s), sits at
    lambda*h = 0.14, far inside RK4's stability region (2.78 on the real axis) and the
    twin's limit 2.5."""
    from torquemod.twins.vtrack.params import MAX_STEP_S, explicit_rate

    cfg = load_config()
    assert (cfg.procedure.samples_per_step, cfg.procedure.substeps) == (12, 1)
    assert 12 / FS <= MAX_STEP_S
    assert stiffest_rate(cfg.rig) == pytest.approx(3333.3, rel=1e-3)
    assert stiffest_rate(cfg.rig) * 12 / FS == pytest.approx(2.4, rel=1e-3)
    assert explicit_rate(cfg.rig) == pytest.approx(195.7, rel=1e-3)
    assert explicit_rate(cfg.rig) * 12 / FS <= 0.15 < MAX_LAMBDA_H < 2.78


def test_normal_load_disturbances(quiet, noisy):
    p0 = pack_parameters(quiet.rig, quiet.disturbances)
    th = np.linspace(0, 2 * np.pi, 20001)
    assert all(normal_load(t, p0) == quiet.rig.normal_load_n for t in th[::1000])
    p1 = pack_parameters(noisy.rig, noisy.disturbances)
    n = np.array([normal_load(t, p1) for t in th]) - noisy.rig.normal_load_n
    spec = np.abs(np.fft.rfft(n[:-1]))
    # sleeper passing: 100 per revolution is the strongest periodic line of the load
    assert np.argmax(spec[50:]) + 50 == 100
    # four joint impacts per revolution: the joint part repeats every quarter revolution
    joints = dataclasses.replace(noisy.disturbances, sleeper_load_n=0.0)
    pj = pack_parameters(noisy.rig, joints)
    q = np.array([normal_load(t, pj) for t in th[:5000]])
    q2 = np.array([normal_load(t + np.pi / 2, pj) for t in th[:5000]])
    np.testing.assert_allclose(q, q2, atol=1e-6)
    assert np.ptp(q) > 0.5 * noisy.disturbances.joint_load_n


def test_encoder_eccentricity_tones():
    th = np.linspace(0, 2 * np.pi, 4096, endpoint=False)
    w = encoder_speed(np.full(th.size, 30.0), th, ecc1_rad=1e-3, ecc2_rad=5e-4,
                      phase1_rad=0.2, phase2_rad=1.0)
    spec = np.abs(np.fft.rfft(w)) / th.size * 2
    assert spec[1] == pytest.approx(30 * 1e-3, rel=1e-9)
    assert spec[2] == pytest.approx(30 * 2 * 5e-4, rel=1e-9)
    assert np.mean(w) == pytest.approx(30.0, rel=1e-12)  # no bias in the mean speed


def test_initial_state_is_an_equilibrium(quiet):
    out, slipped = run(quiet, 44.47, 0.5)
    assert not slipped
    op = operating_point(44.47, quiet.rig)
    np.testing.assert_allclose(out[:, COL["creepage"]], op.creepage, rtol=1e-8)
    np.testing.assert_allclose(out[:, COL["torque_nm"]], 44.47, rtol=1e-8)


def test_dc_torque_balances_creep_moment(quiet):
    """Step 44.47 -> 55.22 N*m; after settling the mean shaft torque, the creep-force moment
    R*Fx and the commanded DC agree (energy/consistency of the drive line)."""
    out, slipped = run(quiet, 55.22, 6.0, dc_from=44.47)
    assert not slipped
    tail = out[int(4 * FS):]
    rw = quiet.rig.wheel_radius_m
    assert np.mean(tail[:, COL["torque_nm"]]) == pytest.approx(55.22, rel=1e-5)
    assert np.mean(tail[:, COL["fx_n"]]) * rw == pytest.approx(55.22, rel=1e-5)
    # with modulation, over whole modulation periods the balance holds in the mean
    out, _ = run(quiet, 55.22, 6.0, amp=8.0)
    tail = out[int(1 * FS):int(1 * FS) + int(10 * FS / 2.0)]  # 10 whole periods
    t_mean = np.mean(tail[:, COL["torque_nm"]])
    assert t_mean == pytest.approx(55.22, abs=0.02)
    assert np.mean(tail[:, COL["fx_n"]]) * rw == pytest.approx(t_mean, abs=0.02)


def _max_diff(a, b):
    """Largest differences: wheel speed (relative), torque [N*m], Fx [N], creepage."""
    w = COL["wheel_speed_rad_s"]
    return (np.max(np.abs(a[:, w] - b[:, w]) / a[:, w]),
            np.max(np.abs(a[:, COL["torque_nm"]] - b[:, COL["torque_nm"]])),
            np.max(np.abs(a[:, COL["fx_n"]] - b[:, COL["fx_n"]])),
            np.max(np.abs(a[:, COL["creepage"]] - b[:, COL["creepage"]])))


def test_halving_the_step_changes_nothing(noisy, wobble):
    """Default step (RK4 at h = 4/16670 s, samples inside a step cubic-Hermite interpolated)
    against the halved step (h = 1/16670 s, every sample a step end) and the quartered one,
    disturbances on (rail-joint kinks in the load), 8 N*m modulation, near saturation, an
    odd number of samples (the last block is one sample), the speed loop wobbling. Tolerance
    as for the step before
    it was doubled: 1e-6 relative on wheel speed, 1e-3 N*m on torque, 1e-2 N on Fx (the
    differences are ~3e-9, 5e-6 N*m, 1.5e-4 N) -- far below the sensors' noise."""
    a, _, ya = run(noisy, 60.45, 2.0001, amp=8.0, dc_from=55.22, final_state=True,
                   wobble=wobble)
    for m, s in ((1, 1), (1, 2)):
        b, _, yb = run(noisy, 60.45, 2.0001, amp=8.0, dc_from=55.22, samples_per_step=m,
                       substeps=s, final_state=True, wobble=wobble)
        assert a.shape == b.shape and a.shape[0] % 2 == 1
        dw, dt, dfx, dxi = _max_diff(a, b)
        assert dw < 1e-6 and dt < 1e-3 and dfx < 1e-2 and dxi < 1e-6
        # the state handed on is the one at t0 + n*dt in both
        np.testing.assert_allclose(ya, yb, rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("with_wobble", [False, True])
def test_integrator_converges_at_fourth_order(quiet, wobble, with_wobble):
    """Smooth forcing (no DC ramp, no load disturbances, 8 N*m modulation; with or without
    the speed loop's wobble, which is smooth too): halving the step shrinks the difference
    16-fold (classical RK4 and the cubic Hermite samples are both O(h^4)), so Richardson's
    estimate of the default step's own error, 16/15 of its difference to the halved step, is
    tiny: < 1e-10 relative on wheel speed and 1e-6 N*m on torque (measured ~7e-13 and
    ~1.5e-8). The same from the default 8 samples per step (issue 12) down to 4: the ratio
    stays near 16 and the 8-sample step's own error estimate, 16/15 of its difference to the
    4-sample one, < 1e-8 relative on wheel speed and 1e-5 N*m on torque (16**2 times the
    bounds above, the error growing with h**4 from the 2-sample step; measured ~2e-10 and
    ~4e-6 N*m, ratios 16.05)."""
    wob = wobble if with_wobble else None
    runs = {m: run(quiet, 55.22, 2.0, amp=8.0, ramp_s=0.0, samples_per_step=m, wobble=wob)[0]
            for m in (8, 4, 2, 1)}
    d84, d42 = _max_diff(runs[8], runs[4]), _max_diff(runs[4], runs[2])
    d21 = _max_diff(runs[2], runs[1])
    for coarse, fine in zip(d42[:2], d21[:2], strict=True):
        assert 10.0 < coarse / fine < 25.0  # 2**4 = 16
    for coarse, fine in zip(d84[:2], d42[:2], strict=True):
        assert 10.0 < coarse / fine < 25.0
    assert d21[0] * 16 / 15 < 1e-10
    assert d21[1] * 16 / 15 < 1e-6
    assert d84[0] * 16 / 15 < 1e-8
    assert d84[1] * 16 / 15 < 1e-5


def test_step_blocks_and_interpolated_slip(quiet):
    """Samples land on the same time grid whatever the step: two calls of 3 and 4 samples
    per block give the same record (to the method's error); a slip found on an interpolated
    sample stops there with that sample's state."""
    a, _ = run(quiet, 44.47, 0.3, amp=8.0, samples_per_step=3)
    b, _ = run(quiet, 44.47, 0.3, amp=8.0, samples_per_step=4)
    dw, dt, dfx, _ = _max_diff(a, b)
    assert dw < 1e-9 and dt < 1e-5 and dfx < 1e-3
    out, slipped, y = run(quiet, 72.0, 8.0, dc_from=65.82, final_state=True)
    assert slipped
    assert y[2] == out[-1, COL["wheel_speed_rad_s"]] and y[4] == out[-1, COL["platform_angle_rad"]]


def test_slip_is_detected_from_the_state(quiet):
    out, slipped = run(quiet, 72.0, 8.0, dc_from=65.82)
    assert slipped
    assert out[-1, COL["creepage"]] >= 0.05
    assert out.shape[0] < int(8.0 * FS)
    _, slipped = run(quiet, 65.82, 3.0, amp=8.0, dc_from=60.45)
    assert not slipped


def test_measure_noise_and_switch_off(quiet, noisy):
    raw, _ = run(quiet, 22.84, 0.2)
    clean = measure(raw, disturbances=quiet.disturbances, sensors=quiet.sensors,
                    rng=np.random.default_rng(0))
    np.testing.assert_array_equal(clean["torque_nm"], raw[:, COL["torque_nm"]])
    dirty = measure(raw, disturbances=noisy.disturbances, sensors=noisy.sensors,
                    rng=np.random.default_rng(0))
    resid = dirty["torque_nm"] - raw[:, COL["torque_nm"]]
    assert np.std(resid) == pytest.approx(noisy.sensors.torque_noise_nm, rel=0.1)
    assert set(dirty) == {"torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n",
                          "fy_n", "fz_n"}
    assert math.isclose(np.mean(dirty["fz_n"]), quiet.rig.normal_load_n, rel_tol=1e-3)


def test_measured_encoder_speed_matches_the_formula(quiet, noisy):
    """measure()'s compiled encoder model (rotation from sample to sample) reproduces
    :func:`encoder_speed` to rounding; noise drawn per channel, deterministic for a seed."""
    raw, _ = run(quiet, 22.84, 0.3, amp=8.0)
    no_noise = dataclasses.replace(noisy.sensors, torque_noise_nm=0.0,
                                   wheel_speed_noise_rad_s=0.0, platform_speed_noise_rad_s=0.0,
                                   force_noise_n=0.0)
    ch = measure(raw, disturbances=noisy.disturbances, sensors=no_noise,
                 rng=np.random.default_rng(0))
    d = noisy.disturbances
    for name, angle, ecc in (
            ("wheel_speed_rad_s", "wheel_angle_rad",
             (d.wheel_encoder_ecc1_rad, d.wheel_encoder_ecc2_rad, d.wheel_encoder_phase1_rad,
              d.wheel_encoder_phase2_rad)),
            ("platform_speed_rad_s", "platform_angle_rad",
             (d.platform_encoder_ecc1_rad, d.platform_encoder_ecc2_rad,
              d.platform_encoder_phase1_rad, d.platform_encoder_phase2_rad))):
        ref = encoder_speed(raw[:, COL[name]], raw[:, COL[angle]], ecc1_rad=ecc[0],
                            ecc2_rad=ecc[1], phase1_rad=ecc[2], phase2_rad=ecc[3])
        np.testing.assert_allclose(ch[name], ref, rtol=1e-13)
    np.testing.assert_array_equal(ch["fz_n"], raw[:, COL["fz_n"]])
    runs = [measure(raw, disturbances=noisy.disturbances, sensors=noisy.sensors,
                    rng=np.random.default_rng(s)) for s in (1, 1, 2)]
    for name in runs[0]:
        np.testing.assert_array_equal(runs[0][name], runs[1][name])
        assert runs[0][name].flags.c_contiguous
    assert not np.array_equal(runs[0]["torque_nm"], runs[2]["torque_nm"])


def test_wobble_table(noisy, quiet, wobble):
    """Default wobble: three band lines of equal amplitude in 0.2-0.6 Hz whose RMS together
    is 0.2 % of the set speed, 0.1 % once and 0.05 % twice per platform revolution (functions
    of the platform angle); none when the disturbances or the wobble alone are off."""
    w0 = noisy.rig.platform_speed_rad_s
    band, rev = wobble[wobble[:, 3] == 0], wobble[wobble[:, 3] == 1]
    assert band.shape[0] == 3 and np.all((band[:, 1] >= 2 * np.pi * 0.2)
                                         & (band[:, 1] <= 2 * np.pi * 0.6))
    assert np.sqrt(np.sum(band[:, 0] ** 2) / 2) / w0 == pytest.approx(0.002, rel=1e-12)
    np.testing.assert_allclose(rev[:, :2], [[1e-3 * w0, 1.0], [5e-4 * w0, 2.0]], rtol=1e-12)
    rng = np.random.default_rng(0)
    assert wobble_table(quiet.disturbances, w0, rng).shape == (0, 4)
    alone = dataclasses.replace(noisy.disturbances, speed_wobble_enabled=False)
    assert wobble_table(alone, w0, rng).shape == (0, 4)


def test_wobble_phasors_match_the_exact_wobble(noisy, wobble):
    """The integrator's wobble -- band lines rotated by half steps, revolution lines as a
    cubic in the angle increment -- equals the plain sum of sines (``_wobble``) at every
    stage's time and angle to rounding over 2000 steps (longer than the 1024 between exact
    re-evaluations)."""
    h = 2.0 / FS
    band, rev = wobble[wobble[:, 3] == 0].copy(), wobble[wobble[:, 3] == 1].copy()
    nw = np.array([wobble.shape[0]])  # one lane
    wob = wobble[None]
    ws, wc, s = np.zeros((1, nw[0])), np.zeros((1, nw[0])), np.zeros((1, 6))
    rc, rs = np.cos(0.5 * wob[:, :, 1] * h), np.sin(0.5 * wob[:, :, 1] * h)
    t, th, dth = 3.0, 0.4, 0.0
    _wob_set(t, th, wob, 0, nw, ws, wc)
    w0 = noisy.rig.platform_speed_rad_s
    err = 0.0
    for k in range(2000):
        _wob_step(wob, 0, nw, ws, wc, rc, rs, dth, s)
        th += dth
        err = max(err, abs(s[0, 0] - _wobble(t + h / 2, 0.0, band)),
                  abs(s[0, 1] - _wobble(t + h, 0.0, band)))
        for x in (0.3 * h * w0, h * w0 * (1 + 1e-3)):
            err = max(err, abs(_wob_rev(s, 0, x) - _wobble(0.0, th + x, rev)))
        dth = h * w0 * (1.0 + 2e-3 * math.sin(k / 50))  # the platform's angle advances unevenly
        t += h
    assert err < 1e-14 * w0


def test_wheel_follows_the_wobbling_platform(quiet, wobble):
    """The speed reference wobbles (0.22 % RMS here), the stiff platform loop follows it (max
    error 0.3 % of the wobble measured: the loop's tracking lag ~ omega*Jp/Kp = 1e-3 at
    0.6 Hz), and the wheel follows the platform kinematically through the contact: the
    creepage stays near its steady value while the speeds wobble. At 22.84 N*m the drive
    line's creep time constant is tau = (Jw + Jm)*V/(Rw^2*N*k) = 22 ms, so the creepage moves
    by ~omega*tau = 3-8 % of the relative speed wobble (0.04-0.06 measured; bound 0.1).
    Near saturation (65.82 N*m, k small) the wheel lags more: ~0.4-0.5 measured, bound 0.7,
    and it does not slip."""
    rig = quiet.rig
    w0 = rig.platform_speed_rad_s
    for dc, bound in ((22.84, 0.1), (65.82, 0.7)):
        out, slipped = run(quiet, dc, 8.0, wobble=wobble)
        assert not slipped
        o = out[int(2 * FS):]  # the start's transient (reference jumps to W0 + w(0)) gone
        t = np.arange(int(2 * FS), out.shape[0]) / FS
        ref = w0 + wobble_reference(wobble, t, o[:, COL["platform_angle_rad"]])
        wp, ww = o[:, COL["platform_speed_rad_s"]], o[:, COL["wheel_speed_rad_s"]]
        xi = o[:, COL["creepage"]]
        rel = np.std(wp) / w0
        assert 1.5e-3 < rel < 3e-3
        assert np.max(np.abs(wp - ref)) < 0.01 * np.std(ref)
        assert np.std(xi) < bound * rel
        assert np.std(ww) / np.mean(ww) == pytest.approx(rel, rel=bound)
        assert np.mean(xi) == pytest.approx(operating_point(dc, rig).creepage, rel=0.01)


@pytest.mark.parametrize(("m", "tol_n"), [(4, 1e-4), (12, 2e-3)])
def test_inner_samples_carry_the_contact_at_their_state(noisy, wobble, m, tol_n):
    """Inner samples of an m-sample step take Fx, Fy, N from the cubic through exact values
    (dynamics._cubic_weights) except at rail joints and fast transients: against the contact
    evaluated afresh at every recorded state (Polach and normal_load, independent code), the
    recorded forces agree to ``tol_n`` through a start off equilibrium, the DC ramp and a
    rail joint: 4 samples to 1e-4 N (measured 6e-6 N), the default 12 to 2e-3 N (measured
    1.0e-3 N in N and 9e-4 N in Fx: the cubic's error grows as h^4 through the joint's
    40 Hz ringing); the sensor noise is 3 N."""
    from torquemod.analysis.contact.polach import creep_force
    rig = noisy.rig
    op = operating_point(44.47, rig)
    y = initial_state(rig, creepage=op.creepage, dc_torque_nm=44.47, contact_fx_n=op.fx_n)
    p = pack_parameters(rig, noisy.disturbances)
    out = np.empty((int(2.0 * FS), len(OUT_COLUMNS)))
    # the motor torque starts at 40 N*m on a state balanced at 44.47: off equilibrium
    integrate(y, 0.0, out.shape[0], 1 / FS, 1, p, 40.0, 44.47, 0.0, 0.5, 8.0, 2 * np.pi * 2.0,
              0.3, 0.0, 0.05, out, m, wobble)
    th = out[:, COL["platform_angle_rad"]]
    pitch = 2 * np.pi / noisy.disturbances.joint_count
    assert (np.diff((th - 0.5 * pitch) % pitch) < 0).any()  # a joint is crossed
    n = np.array([normal_load(x, p) for x in th])
    v = out[:, COL["platform_speed_rad_s"]] * rig.platform_radius_m
    fx, fy = creep_force(out[:, COL["creepage"]], rig.contact.lateral_creepage,
                         normal_load_n=n, speed_m_s=v, **rig.contact.polach_kwargs())
    np.testing.assert_allclose(out[:, COL["fz_n"]], n, rtol=0, atol=tol_n)
    np.testing.assert_allclose(out[:, COL["fx_n"]], fx, rtol=0, atol=tol_n)
    np.testing.assert_allclose(out[:, COL["fy_n"]], fy, rtol=0, atol=tol_n)
