"""``torquemod onboard`` on a train run NOT made by torquemod's twin (issue 10's hidden check):
a 1.5-km run of :mod:`torquemod.twins.independent.train` (tanh creep law, dry/wet/leaves, 4 Hz,
torque
and speed at the motor behind a gear ratio of 5.2, a 10-Hz radar in its own MDF4 channel
group, no position channel, logger names mapped in ``[channels]``, logger clock from 1532 s)
read and processed end to end with the default settings."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("asammdf")

from torquemod.ontrain.run import run_onboard
from torquemod.twins.independent.compare import match_segments
from torquemod.twins.independent.train import (
    FrictionSegment,
    IndependentRunSpec,
    creep_law,
    creep_slope,
    write_independent_run,
)

SPEC = IndependentRunSpec(
    segments=(FrictionSegment("dry", 0.0, 0.35, 110.0), FrictionSegment("wet", 500.0, 0.20, 70.0),
              FrictionSegment("leaves", 1000.0, 0.10, 40.0)),
    length_m=1500.0, seed=3)


@pytest.fixture(scope="module")
def processed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("independent")
    path, _ = write_independent_run(SPEC, folder / "run")
    res = run_onboard(path, folder / "out", force=True)[0]
    truth = pd.read_parquet(folder / "run" / "truth.parquet")
    t = res.track
    ts = t["time_s"].to_numpy()
    at = {c: np.interp(ts, truth["time_s"], truth[c]) for c in
          ("position_m", "speed_m_s", "coa", "mu", "creep_coefficient", "utilisation")}
    return res, t, at


def test_generator_laws_match_their_slopes():
    """The truth's creep coefficient is the analytic slope of the law (checked against a
    central difference; tolerance 1e-3 relative: the difference's truncation error at
    h = 1e-7 is far below it) and each curve's maximum is mu (tanh, Burckhardt)."""
    xi = np.linspace(1e-4, 0.02, 50)
    h = 1e-7
    for law in ("tanh", "burckhardt", "polach"):
        num = (creep_law(xi + h, 0.2, 60.0, law, 3.0) - creep_law(xi - h, 0.2, 60.0, law, 3.0)) \
            / (2 * h)
        assert np.allclose(creep_slope(xi, 0.2, 60.0, law, 3.0), num, rtol=1e-3, atol=1e-3)
    grid = np.linspace(0, 0.5, 500_001)
    for law in ("tanh", "burckhardt"):
        assert creep_law(grid, 0.2, 60.0, law, 3.0).max() == pytest.approx(0.2, rel=1e-4)


def test_reader_took_mapped_channels_gear_and_radar_group(processed):
    res, t, at = processed
    notes = " ".join(res.notes)
    assert "x5.2" in notes  # the gear ratio of run.toml was applied
    assert "own time base" in notes and "10 Hz" in notes  # the radar's own group and rate
    assert "position integrated" in notes
    # the logger clock (t0 = 1532.25 s) is kept: the first window's centre is ~0.6 s later
    assert 1532.25 < t["time_s"].iloc[0] < 1532.25 + 1.0
    # speed: radar scale error 0.2 % (0.044 m/s at 22 m/s) + noise 0.03 m/s averaged over a
    # 1.25-s window (~12 radar samples): 0.1 m/s holds with margin; a km/h read as m/s or
    # a wrong group would be off by >= 3.6x
    assert np.max(np.abs(t["speed_m_s"] - at["speed_m_s"])) < 0.1
    # position: integrated from the radar (0.2 % scale error: 3 m over 1.5 km) plus the
    # radar's interpolation at the start; 0.3 % + 1 m
    err = np.abs(t["position_m"].to_numpy() - at["position_m"])
    assert np.all(err < 0.003 * at["position_m"] + 1.0)
    # CoA from the motor torque x gear ratio: on windows without a DC step the error is the
    # torque noise and the 1-ms lag (< 0.005 median); without the gear it would be 5.2x off
    steady = (t["dc_step_ratio"] <= 0.25).to_numpy()
    assert np.median(np.abs(t["coa"].to_numpy()[steady] - at["coa"][steady])) < 0.005
    # the creep coefficient from phase and amplitude (speed / gear ratio): median within
    # 10 % of the law's slope (measured: ~2 % low; a wrong gear ratio scales it by 5.2^2)
    ratio = t["creep_coefficient"].to_numpy()[steady] / at["creep_coefficient"][steady]
    assert 0.9 < np.median(ratio) < 1.1


def test_honesty_targets(processed):
    """Issue 10: the lower bound exceeds the truth in <= 3 % of the rows without mu; where mu
    is given (>= 20 rows), the 95 % interval contains the truth in >= 90 % of them."""
    _, t, at = processed
    mu = t["mu"].to_numpy()
    given = np.isfinite(mu)
    lb = t["mu_low_95"].to_numpy()[~given]
    assert np.mean(lb > at["mu"][~given]) <= 0.03
    if given.sum() >= 20:
        lo, hi = t["mu_low_95"].to_numpy()[given], t["mu_high_95"].to_numpy()[given]
        truth = at["mu"][given]
        assert np.mean((lo <= truth) & (truth <= hi)) >= 0.9
    # no false low_adhesion at <= 50 % utilisation (issue: < 1 % of windows)
    low = at["utilisation"] <= 0.5
    assert np.mean(t["low_adhesion"].to_numpy()[low]) < 0.01


def test_generator_drive_line_against_motor_side_impedance():
    """With a compliant coupling and the encoder on the motor, the generator's torque/speed
    ratio at 4 Hz must give the true creep coefficient through the motor-side drive-line
    relation (derived independently: motor J_m*dw_m/dt = T - T_c, T_c = Z*(w_m - w_w),
    wheelset (J - J_m)*dw_w/dt = T_c - R*F, so 1/(T/w_m - j*Omega*J_m) = 1/Z + 1/(j*Omega*J_w
    + G)) and D = 1/Re(1/G), k = D*V/(R^2*N) (torquemod.ontrain.window's definition).
    Noise-free sensors, steady windows at 40 % and 80 % utilisation; tolerance 6 %: the
    window's creep curve is linearised over a +-9 % modulation of the CoA."""
    from dataclasses import replace

    from torquemod.dsp.phase import sinefit_phase
    from torquemod.twins.independent.train import simulate_independent, truth_table
    kc = 6e5
    spec = replace(SPEC, length_m=400.0, coupling_stiffness_nm_rad=kc, encoder_eccentricity=0.0,
                   axle_ripple=0.0, torque_noise_nm=0.0, speed_quantum_rpm=1e-6,
                   torque_lag_s=0.0, encoder_gate_samples=1, load_variation=())
    run = simulate_independent(spec)
    truth = truth_table(run)
    fs, f, g = spec.sample_rate_hz, spec.modulation_frequency_hz, spec.gear_ratio
    torque = run.motor_torque_nm * g
    speed = run.motor_speed_rpm * 2 * np.pi / 60 / g
    om = 2 * np.pi * f
    z = kc / (1j * om) + spec.coupling_damping_nm_s_rad
    jm, jw = spec.motor_inertia_kg_m2, spec.inertia_kg_m2 - spec.motor_inertia_kg_m2
    n = round(5 * fs / f)
    for t_start, util in ((3.0, 0.4), (7.5, 0.8)):
        seg = slice(round(t_start * fs), round(t_start * fs) + n)
        fit = sinefit_phase(torque[seg], speed[seg], fs, f, trend=True)
        ratio = fit.torque_amplitude / fit.wheel_amplitude * np.exp(1j * np.radians(fit.phase_deg))
        big_g = 1 / (1 / (ratio - 1j * om * jm) - 1 / z) - 1j * om * jw
        k = (1 / (1 / big_g).real) * run.speed_m_s[seg].mean() \
            / (spec.wheel_radius_m ** 2 * spec.normal_load_n)
        t_mid = run.t_s[seg].mean()
        assert np.interp(t_mid, truth["time_s"], truth["utilisation"]) == pytest.approx(util,
                                                                                      abs=0.03)
        assert k == pytest.approx(np.interp(t_mid, truth["time_s"], truth["creep_coefficient"]),
                                  rel=0.06)


def test_hdf5_logger_export_reads_like_the_mdf4(processed, tmp_path):
    """The same run as a logger-style HDF5 (times in ms, the radar on its own time vector
    named in [channels]) gives the same track as the MDF4 file: the readers put the radar
    on the torque's times the same way (tolerance 1e-9 relative: the ms time stamps are
    float64, 1532250.0 ms with ~1e-10 ms resolution)."""
    _, t, _ = processed
    path, _ = write_independent_run(SPEC, tmp_path / "h5run", fmt="hdf5")
    h5 = run_onboard(path, tmp_path / "h5out", force=True)[0].track
    assert len(h5) == len(t)
    for col in ("time_s", "position_m", "speed_m_s", "coa", "phase_deg", "creep_coefficient"):
        np.testing.assert_allclose(h5[col], t[col], rtol=1e-9, atol=1e-9, err_msg=col)
    assert h5["mu"].isna().equals(t["mu"].isna())


@pytest.mark.parametrize("fmt", ["csv", "parquet", "mat", "tdms"])
def test_other_logger_formats_read_like_the_mdf4(processed, tmp_path, fmt):
    """The MDF4 run's samples exported the way other loggers and tools write them give the
    same track: CSV and Parquet as one table with the 10 Hz radar's time and value columns
    padded with empty cells below their last sample (cut off, with a note), MATLAB v5 with
    vectors of different lengths, TDMS with the radar in its own group (waveform
    properties). Tolerance: exact for the tables and .mat (the same float64 stamps); TDMS
    carries a rate instead of stamps (the logger's median step): 1e-6 relative (measured
    2e-8 on the creep coefficient, 3e-7 deg on the phase)."""
    from asammdf import MDF
    res, t, _ = processed
    src = res.run.recordings[0].path
    with MDF(src) as m:
        tq, sp, rv = (m.get(c) for c in ("EM1_Trq", "EM1_Spd", "Radar_v"))
    text = res.run.manifest_path.read_text()
    name = {"csv": "run.csv", "parquet": "run.parquet", "mat": "run.mat", "tdms": "run.tdms"}[fmt]
    if fmt in ("csv", "parquet", "mat"):
        text = text.replace('vehicle_speed = { name = "Radar_v", unit = "km/h" }',
                            'time = "t"\nvehicle_speed = { name = "Radar_v", unit = "km/h", '
                            'time = "radar_t" }')
    n, nr = tq.samples.size, rv.samples.size
    if fmt in ("csv", "parquet"):
        pad = np.full(n - nr, np.nan)
        table = pd.DataFrame({"t": tq.timestamps, "EM1_Trq": tq.samples, "EM1_Spd": sp.samples,
                              "radar_t": np.concatenate([rv.timestamps, pad]),
                              "Radar_v": np.concatenate([rv.samples, pad])})
        if fmt == "csv":
            table.to_csv(tmp_path / name, index=False)
        else:
            table.to_parquet(tmp_path / name, index=False)
    elif fmt == "mat":
        import scipy.io
        scipy.io.savemat(tmp_path / name, {"t": tq.timestamps, "EM1_Trq": tq.samples,
                                           "EM1_Spd": sp.samples, "radar_t": rv.timestamps,
                                           "Radar_v": rv.samples})
    else:
        pytest.importorskip("nptdms")
        from nptdms import ChannelObject, TdmsWriter
        dt = float(np.median(np.diff(tq.timestamps)))
        with TdmsWriter(tmp_path / name) as w:
            w.write_segment([ChannelObject("logger", c, x.samples, properties={
                "wf_increment": dt, "wf_start_offset": float(tq.timestamps[0]),
                "unit_string": u}) for c, x, u in (("EM1_Trq", tq, "N*m"),
                                                   ("EM1_Spd", sp, "rpm"))]
                            + [ChannelObject("radar", "Radar_v", rv.samples, properties={
                                "wf_increment": 0.1, "wf_start_offset": float(rv.timestamps[0]),
                                "unit_string": "km/h"})])
    (tmp_path / "run.toml").write_text(text.replace('"run.mf4"', f'"{name}"'))
    got = run_onboard(tmp_path / "run.toml", tmp_path / "out", force=True)[0]
    if fmt in ("csv", "parquet"):
        assert any(f"{n - nr} empty rows below its last sample" in s for s in got.notes)
    rtol, atol = (1e-6, 1e-5) if fmt == "tdms" else (0.0, 0.0)
    assert len(got.track) == len(t)
    for col in ("position_m", "speed_m_s", "coa", "phase_deg", "creep_coefficient"):
        np.testing.assert_allclose(got.track[col], t[col], rtol=rtol, atol=atol, err_msg=col)


def _segment_against_truth(res, truth, spec):
    """For each true segment, its mu and the estimator's segment (segments.csv) overlapping
    it most (:func:`~torquemod.twins.independent.compare.match_segments`); there must be one."""
    matched = match_segments(spec, res.track, res.segment_table(), truth)
    assert all(seg is not None for _, seg in matched), "a true segment without estimate"
    return [(s.mu, seg) for s, seg in matched]


def test_segments_tanh_interval_honest(processed, tmp_path):
    """The per-segment fit on the tanh run (staircase to 80 %): every segment gets a fit;
    the truth lies inside each 95 % interval (open above where the data allow far larger
    adhesion) and no lower bound exceeds it."""
    res, _, _ = processed
    truth = pd.read_parquet(res.run.folder / "truth.parquet")
    for mu, seg in _segment_against_truth(res, truth, SPEC):
        assert np.isfinite(seg["adhesion_available_best_fit"])
        assert seg["adhesion_available_lower_bound"] <= mu
        assert seg["adhesion_available_low_95"] <= mu
        hi = seg["adhesion_available_high_95"]
        assert not np.isfinite(hi) or mu <= hi


def test_segments_burckhardt_determined_within_10_percent(tmp_path):
    """Burckhardt's law (falling beyond its peak; the generator's own parametrisation),
    three 500-m segments each probed to 80 %: every segment determined, within 10 % (the
    target for constant-friction runs; measured on the benchmark's 4 x 4 segments: within
    6.7 %), the truth inside its interval; the rows' mu, where given, cover the truth in
    >= 90 % (the coverage target)."""
    spec = replace(SPEC, law="burckhardt", seed=5)
    path, _ = write_independent_run(spec, tmp_path / "run")
    res = run_onboard(path, tmp_path / "out", force=True)[0]
    truth = pd.read_parquet(tmp_path / "run" / "truth.parquet")
    for mu, seg in _segment_against_truth(res, truth, spec):
        assert seg["determined"], seg.to_dict()
        assert seg["adhesion_available"] == pytest.approx(mu, rel=0.10)
        assert seg["adhesion_available_low_95"] <= mu <= seg["adhesion_available_high_95"]
    t = res.track
    given = t["mu"].notna().to_numpy()
    mu_t = np.interp(t["time_s"], truth["time_s"], truth["mu"])[given]
    lo, hi = t["mu_low_95"].to_numpy()[given], t["mu_high_95"].to_numpy()[given]
    assert given.sum() >= 20
    assert np.mean((lo <= mu_t) & (mu_t <= hi)) >= 0.9
