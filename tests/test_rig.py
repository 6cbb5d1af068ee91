"""The twin's equations of motion, integrator, disturbances and sensors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from torquemod.rig.dynamics import (
    OUT_COLUMNS,
    initial_state,
    integrate,
    normal_load,
    pack_parameters,
)
from torquemod.rig.sensors import encoder_speed, measure
from torquemod.simulate import load_config
from torquemod.theory import operating_point

COL = {n: i for i, n in enumerate(OUT_COLUMNS)}
FS = 16670.0


@pytest.fixture(scope="module")
def quiet():
    return load_config(overrides={"disturbances": {"enabled": False}})


@pytest.fixture(scope="module")
def noisy():
    return load_config()


def run(cfg, dc, seconds, *, amp=0.0, substeps=1, dc_from=None, phase=0.3):
    rig = cfg.rig
    op = operating_point(dc if dc_from is None else dc_from, rig)
    y = initial_state(rig, creepage=op.creepage, dc_torque_nm=op.dc_torque_nm,
                      contact_fx_n=op.fx_n)
    p = pack_parameters(rig, cfg.disturbances)
    n = int(seconds * FS)
    out = np.empty((n, len(OUT_COLUMNS)))
    done, slipped = integrate(y, 0.0, n, 1 / FS, substeps, p, op.dc_torque_nm, dc, 0.0, 0.5,
                              amp, 2 * np.pi * 2.0, phase, 0.0, 0.05, out)
    return out[:done], slipped


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


def test_halving_the_step_changes_nothing(noisy):
    """RK4 at 1/16670 s vs 1/33340 s, disturbances on, 8 N*m modulation, near saturation.
    Tolerance: 1e-6 relative on wheel speed and 1e-3 N*m on torque."""
    a, _ = run(noisy, 60.45, 2.0, amp=8.0, substeps=1, dc_from=55.22)
    b, _ = run(noisy, 60.45, 2.0, amp=8.0, substeps=2, dc_from=55.22)
    w = COL["wheel_speed_rad_s"]
    assert np.max(np.abs(a[:, w] - b[:, w]) / a[:, w]) < 1e-6
    assert np.max(np.abs(a[:, COL["torque_nm"]] - b[:, COL["torque_nm"]])) < 1e-3
    assert np.max(np.abs(a[:, COL["fx_n"]] - b[:, COL["fx_n"]])) < 1e-2


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
