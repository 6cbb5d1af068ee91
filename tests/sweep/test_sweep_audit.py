"""Regressions from the audit of `torquemod sweep` against an independent simulation (issue 12).

Finding: a step starts from the previous step's steady state and ramps its DC torque; near
the creep curve's peak the wheel's creep mode is slow (tau ~ 1 s at 90 % utilisation on
leaves), and after the 3 s run-in the example sweep gives, the twin's phase was 0.08-0.28 deg
away from the periodic state (measured over 4 conditions x 1-8 Hz, disturbances off; the
independent simulation and the large-signal theory agreed to 1e-5 deg). The sweep now runs
each point in full mode with a run-in of at least 8 time constants of its slowest step
(``evaluate.settle_time_s``, column ``settle_s``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from torquemod.sweep import evaluate as ev
from torquemod.sweep.evaluate import tasks
from torquemod.sweep.spec import parse_sweep

# leaves, 2 Hz, steps at 60 % and 90 % of the creep curve's peak, noise and disturbances off,
# the 3 s run-in of examples/sweep_vtrack_conditions.toml; seed 1 draws a modulation phase
# for which the unsettled transient is large (0.21 deg, measured)
_SWEEP = """
mode = "full"
seeds = [1]
[fixed]
procedure.cycles_per_step = 1
procedure.settle_s = 3.0
disturbances.enabled = false
contact.condition = "leaves"
modulation.frequency_hz = 2.0
[steps]
fractions_of_peak = [0.6, 0.9]
"""


def _point(monkeypatch=None, constants=None):
    if constants is not None:
        monkeypatch.setattr(ev, "SETTLE_TIME_CONSTANTS", constants)
    return ev.evaluate_point(tasks(parse_sweep(_SWEEP))[0])


@pytest.fixture(scope="module")
def fixed_point():
    return _point()


def test_run_in_covers_eight_time_constants_of_the_slowest_step(fixed_point):
    df = fixed_point
    config, _ = ev.point_config(tasks(parse_sweep(_SWEEP))[0])
    rig = config.rig
    # tau from the rigid drive line written out here: (Jw + Jm) V / (Rw^2 N k)
    k = df["creep_coefficient"].to_numpy(float)
    tau = ((rig.wheel_inertia_kg_m2 + rig.drive_inertia_kg_m2) * rig.speed_m_s
           / (rig.wheel_radius_m ** 2 * rig.normal_load_n * k))
    assert tau[1] > tau[0]  # slower nearer the peak
    assert df["settle_s"].iloc[0] == pytest.approx(8.0 * tau.max(), rel=1e-12)
    assert df["settle_s"].iloc[0] > 3.0  # longer than configured: the rule acted
    # a low-utilisation point keeps the configured run-in
    low = tasks(parse_sweep(_SWEEP.replace("[0.6, 0.9]", "[0.3]")))[0]
    config, _ = ev.point_config(low)
    rows = ev._theory_steps(config, ev.point_config(low)[1])
    assert ev.settle_time_s(config, rows) == 3.0


def test_twin_near_the_peak_agrees_with_the_theory_after_the_run_in(fixed_point):
    diff = fixed_point["phase_twin_minus_theory_deg"].to_numpy(float)
    # measured 3.7e-6 and -0.0021 deg; the bound is 0.1 deg, 0.01 is 5x the residue
    assert np.isfinite(diff).all()
    assert np.max(np.abs(diff)) < 0.01, diff


def test_without_the_rule_the_same_step_was_off(monkeypatch):
    """The failure the rule removes (so the test above can fail): 0.21 deg measured."""
    df = _point(monkeypatch, constants=0.0)
    assert df["settle_s"].iloc[0] == 3.0
    assert abs(df["phase_twin_minus_theory_deg"].iloc[1]) > 0.1


def _independent_phase_deg(config, dc_torque_nm: float) -> float:
    """Phase [deg] of the wheel speed behind the shaft torque in the periodic state of the
    rig's equations written out here (motor -- shaft -- wheel, platform with its PI speed
    loop, Polach creep force with falling friction, constant normal load), integrated by
    scipy's DOP853 (rtol 1e-9) from the DC equilibrium over 14 s, then cos/sin/constant
    fitted over the last 4 whole periods. Only the contact's lumped stiffnesses
    (pi*G*a*b*c11/4 from Hertz and Kalker) are taken from the twin's configuration."""
    rig, mod = config.rig, config.modulation
    c = rig.contact
    rw, rp, v, n = rig.wheel_radius_m, rig.platform_radius_m, rig.speed_m_s, rig.normal_load_n
    w0 = v / rp

    def fx(xx, vel):
        xi = math.hypot(xx, c.lateral_creepage)
        mu = c.mu0 * ((1 - c.a_ratio) * math.exp(-c.b_s_m * xi * vel) + c.a_ratio)
        eps = math.hypot(c.stiffness_x_n * xx, c.stiffness_y_n * c.lateral_creepage) / (n * mu)
        f = 2 * n * mu / math.pi * (c.k_a * eps / (1 + (c.k_a * eps) ** 2)
                                    + math.atan(c.k_s * eps))
        return f * xx / xi

    from scipy.optimize import brentq
    xi0 = brentq(lambda x: rw * fx(x, v) - dc_torque_nm, 0.0, 0.2, xtol=1e-15)
    ww0 = w0 * rp * (1 + xi0) / rw
    y0 = [dc_torque_nm / rig.shaft_stiffness_nm_rad, ww0, ww0, w0,
          (rig.rolling_resistance_nm - rp * fx(xi0, v)) / rig.platform_ki_nm_rad]
    f = mod.actual_frequency_hz
    om = 2 * math.pi * f

    def rhs(t, y):
        tw, wm, ww, wp, _ = y
        tsh = rig.shaft_stiffness_nm_rad * tw + rig.shaft_damping_nm_s_rad * (wm - ww)
        force = fx((ww * rw - wp * rp) / (wp * rp), wp * rp)
        tm = dc_torque_nm + mod.amplitude_nm * math.sin(om * t)
        return [wm - ww, (tm - tsh) / rig.drive_inertia_kg_m2,
                (tsh - rw * force) / rig.wheel_inertia_kg_m2,
                (rig.platform_kp_nm_s_rad * (w0 - wp) + rig.platform_ki_nm_rad * y[4]
                 + rp * force - rig.rolling_resistance_nm) / rig.platform_inertia_kg_m2,
                w0 - wp]

    per = 400
    t0 = math.ceil(12.0 * f) / f
    t = t0 + np.arange(4 * per) / (per * f)
    sol = solve_ivp(rhs, (0.0, t[-1] + 1e-9), y0, method="DOP853", rtol=1e-9, atol=1e-12,
                    t_eval=t, max_step=1 / (20 * f))
    assert sol.success
    tw, wm, ww = sol.y[0], sol.y[1], sol.y[2]
    tsh = rig.shaft_stiffness_nm_rad * tw + rig.shaft_damping_nm_s_rad * (wm - ww)
    basis = np.column_stack([np.cos(om * t), np.sin(om * t), np.ones_like(t)])
    (ct, st, _), *_ = np.linalg.lstsq(basis, tsh, rcond=None)
    (cw, sw, _), *_ = np.linalg.lstsq(basis, ww, rcond=None)
    d = math.degrees(math.atan2(ct, st) - math.atan2(cw, sw))
    return (d + 180.0) % 360.0 - 180.0


def test_twin_near_the_peak_agrees_with_an_independent_simulation(fixed_point):
    """Against scipy's integration of the rig's equations written out above: the audit
    measured |twin - independent| <= 0.0036 deg over 4 conditions x 1, 2, 4, 8 Hz x 7 steps
    (and theory - independent <= 1.1e-5 deg); 0.01 deg here."""
    config, _ = ev.point_config(tasks(parse_sweep(_SWEEP))[0])
    row = fixed_point.iloc[1]
    assert row["utilisation"] == pytest.approx(0.9)
    ref = _independent_phase_deg(config, float(row["dc_torque_nm"]))
    assert ref == pytest.approx(row["phase_theory_deg"], abs=1e-3)
    assert row["phase_simulated_deg"] == pytest.approx(ref, abs=0.01)


def test_theory_mode_has_no_run_in():
    df = ev.evaluate_point(tasks(parse_sweep(_SWEEP.replace('"full"', '"theory"')))[0])
    assert np.isnan(df["settle_s"]).all()


def test_a_list_valued_parameter_is_swept_and_reported(tmp_path):
    """Sweeping procedure.dc_torques_nm (a list per point) crashed the report: the column
    comes back from Parquet as arrays, which pandas cannot group ("unhashable type")."""
    from torquemod.sweep.run import run_sweep
    spec = parse_sweep("""
mode = "theory"
[[point]]
procedure.dc_torques_nm = [10.0, 50.0]
[[point]]
procedure.dc_torques_nm = [20.0, 40.0, 60.0]
""")
    res = run_sweep(spec, tmp_path / "dc", in_process=True)
    assert res.count("done") == 2, res.failures
    assert res.report is not None and res.report.is_file()
    assert list(res.table.groupby("point_index").size()) == [2, 3]
    # the Parquet table keeps the lists as lists of numbers
    import pandas as pd
    tab = pd.read_parquet(tmp_path / "dc" / "sweep.parquet")
    assert [list(v) for v in tab.groupby("point_index")["procedure.dc_torques_nm"].first()] \
        == [[10.0, 50.0], [20.0, 40.0, 60.0]]
    assert (tmp_path / "dc" / "figures" / "phase_by_condition.png").is_file()


def test_dc_torques_together_with_fractions_of_peak_is_refused():
    from torquemod.errors import InputError
    with pytest.raises(InputError, match=r"dc_torques_nm.*\[steps\]"):
        parse_sweep("""
[steps]
fractions_of_peak = [0.3, 0.6]
[grid]
procedure.dc_torques_nm = [[10.0, 20.0]]
""")


def test_chain_resamples_faster_above_2_hz():
    from torquemod.io.config import ProcessingConfig
    rate = ProcessingConfig().resample.target_hz
    assert ev.chain_config(1.0).resample.target_hz == rate  # never slower than the paper's
    assert ev.chain_config(2.0).resample.target_hz == rate
    assert ev.chain_config(8.0).resample.target_hz == pytest.approx(4.0 * rate)
    given = ev.chain_config(8.0, {"resample": {"target_hz": 100.0}})
    assert given.resample.target_hz == 100.0  # a [processing] key wins


def test_chain_phase_at_8_hz_on_the_noise_free_twin():
    """The paper's peak/valley phase at 8 Hz: with the paper's 53.344 Hz (6.7 samples a
    period) it was 0.079 and 0.050 deg off the large-signal theory (measured), with a
    standard error of 1e-4 deg; with the rate scaled by f/2, 0.0012 deg at most over
    dry and wet, 0-80 %. 0.01 deg here."""
    df = ev.evaluate_point(tasks(parse_sweep("""
mode = "full"
seeds = [3]
[fixed]
procedure.cycles_per_step = 1
disturbances.enabled = false
contact.condition = "dry"
modulation.frequency_hz = 8.0
[steps]
fractions_of_peak = [0.5, 0.7]
"""))[0])
    d = (df["phase_deg"] - df["phase_theory_deg"]).to_numpy(float)
    assert np.isfinite(d).all() and np.max(np.abs(d)) < 0.01, d
