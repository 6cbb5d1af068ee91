"""The twin's speed-ups (issue 12): the compiled noise generator and the coarse settling."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from torquemod.twins.vtrack.params import (
    ACCURACY_LAMBDA_H,
    MAX_LAMBDA_H,
    explicit_rate,
    stiffest_rate,
)
from torquemod.twins.vtrack.rig.batch import plan_run
from torquemod.twins.vtrack.rig.dynamics import pack_parameters
from torquemod.twins.vtrack.rig.noise import ZIG_R, add_normal, standard_normal, ziggurat_tables
from torquemod.twins.vtrack.rig.steps import integrate_step, settle_samples_per_step
from torquemod.twins.vtrack.rig.truth import recorded_step_truth
from torquemod.twins.vtrack.simulate import load_config

N = 2_000_000


@pytest.fixture(scope="module")
def draws():
    return standard_normal(N, 20261123)


def test_ziggurat_layers_have_equal_area():
    """Every layer of the table (the base one with its tail, the top one up to f(0) = 1)
    has the area V: the recursion closes on itself (independent check of the constants)."""
    k, w, f = ziggurat_tables()
    x = np.append(w * 2.0 ** 52, 0.0)
    areas = x[1:-1] * (f[2:] - f[1:-1])  # layers 1..255: width x_i, height f(x_{i+1}) - f(x_i)
    tail = math.sqrt(math.pi / 2.0) * math.erfc(ZIG_R / math.sqrt(2.0))
    base = ZIG_R * f[1] + tail
    np.testing.assert_allclose(areas, base, rtol=1e-9)  # V to the constants' 12 digits
    assert x[0] * f[1] == pytest.approx(base, rel=1e-9)
    assert np.all(np.diff(x[:-1]) < 0) and k[-1] == 0


def test_normals_are_standard_normal(draws):
    """2e6 draws: mean and standard deviation within 4 standard errors (mean 1/sqrt(N),
    std 1/sqrt(2N)), Kolmogorov-Smirnov and a 200-bin chi-square against N(0, 1) not
    rejected at 1e-3, the tail beyond R (the separate exponential branch) within 4 sigma of
    its binomial count, and the wedges (|z| just inside a layer edge) by the chi-square."""
    z = draws
    assert abs(z.mean()) < 4.0 / math.sqrt(N)
    assert abs(z.std() - 1.0) < 4.0 / math.sqrt(2.0 * N)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    edges = np.linspace(-4.0, 4.0, 201)
    counts = np.histogram(z, bins=edges)[0]
    expect = np.diff(stats.norm.cdf(edges))
    expect *= counts.sum() / expect.sum()
    assert stats.chisquare(counts, expect).pvalue > 1e-3
    p_tail = 2.0 * stats.norm.sf(ZIG_R)
    n_tail = np.sum(np.abs(z) > ZIG_R)
    assert abs(n_tail - N * p_tail) < 4.0 * math.sqrt(N * p_tail)
    assert np.all(np.isfinite(z))


def test_streams_are_deterministic_and_independent(draws):
    """The same state gives the same numbers; another state gives uncorrelated ones (|r| <
    4/sqrt(n)); a strided source is read as its elements."""
    n = 200_000
    np.testing.assert_array_equal(standard_normal(n, 20261123), draws[:n])
    other = standard_normal(n, 20261124)
    assert abs(np.corrcoef(other, draws[:n])[0, 1]) < 4.0 / math.sqrt(n)
    src = np.arange(3.0 * n).reshape(n, 3)
    out = np.empty(n)
    add_normal(src[:, 1], 0.5, 20261123, out)
    np.testing.assert_allclose(out, src[:, 1] + 0.5 * draws[:n], rtol=0, atol=1e-12)


def test_settling_step_is_stable_and_longer():
    """Default rig: the settling at 32 samples per RK4 step, twice the recorded 16 (the
    platform's PI loop, ~3300 1/s, is taken exactly: only the torsional mode, ~200 1/s,
    bounds the step, lambda*h = 0.38); a stiffer platform loop changes neither step; a
    stiff shaft (torsion ~3900 1/s) lowers the recorded step to 2 (lambda*h = 0.47 <=
    ACCURACY_LAMBDA_H) and settles at 4; never shorter than the recorded step."""
    cfg = load_config()
    fs = cfg.sensors.sample_rate_hz
    r = settle_samples_per_step(cfg)
    assert r == 32 and cfg.procedure.samples_per_step == 16
    assert explicit_rate(cfg.rig) * r / fs <= 0.4
    assert stiffest_rate(cfg.rig) * r / fs > 4.0  # beyond classical RK4's stability
    stiff = load_config(overrides={"rig": {"platform_kp_nm_s_rad": 2.0e7},
                                   "procedure": {"samples_per_step": 4}})
    assert settle_samples_per_step(stiff) == 8
    stiff = load_config(overrides={"rig": {"platform_kp_nm_s_rad": 1.4e7}})
    assert stiff.procedure.samples_per_step == 16 and settle_samples_per_step(stiff) == 32
    shaft = load_config(overrides={"rig": {"shaft_stiffness_nm_rad": 1.0e7}})
    assert shaft.procedure.samples_per_step == 2  # 3 would be lambda*h = 0.70
    assert explicit_rate(shaft.rig) * 2 / fs <= ACCURACY_LAMBDA_H
    assert settle_samples_per_step(shaft) == 4
    assert explicit_rate(shaft.rig) * 4 / fs <= MAX_LAMBDA_H


def test_coarse_settling_keeps_the_phases():
    """One recorded revolution after the default 4 s of settling, integrated with and without
    the coarse settling step: the simulated phases agree to 1e-5 deg (measured < 5e-7 deg on
    the default experiment; the difference left at the end of settling decays with the
    settling, rig/steps.py) and the mean creepage to 1e-9."""
    cfg = load_config(overrides={"procedure": {"dc_torques_nm": [44.47, 60.45],
                                               "cycles_per_step": 1}})
    rp = plan_run(cfg, 3)
    params = pack_parameters(cfg.rig, cfg.disturbances)
    for plan in rp.steps:
        got = []
        for quiet in (0, rp.n_settle):
            out, n, slipped, _ = integrate_step(cfg, params, rp.wobble, plan, rp.n_step, None,
                                                quiet)
            assert not slipped and n == rp.n_step
            entry, _ = recorded_step_truth(plan.index, plan.dc_nm, cfg, out, n, plan.t0_s,
                                           rp.wobble, rp.n_settle, large_signal=False)
            got.append(entry["simulated"])
        assert got[0]["phase_deg"] == pytest.approx(got[1]["phase_deg"], abs=1e-5)
        assert got[0]["creepage_mean"] == pytest.approx(got[1]["creepage_mean"], abs=1e-9)


def test_partition_moments_match_numpy():
    """Means and standard deviations of the whole and of each part in two passes: numpy's
    over each slice to rounding (1e-12 relative: summation order only)."""
    from torquemod.twins.vtrack.rig.truth import _partition_moments

    rng = np.random.default_rng(5)
    raw = rng.standard_normal((3000, 9)) * np.arange(1, 10) + 50.0
    cols, std_cols = np.array([8, 0, 3, 4, 5, 2]), np.array([0, 5])
    edges = np.array([40, 1000, 1990, 2977])
    mean, std = np.empty((4, cols.size)), np.empty((4, 2))
    _partition_moments(raw, edges, cols, mean, std_cols, std)
    spans = [(40, 2977), (40, 1000), (1000, 1990), (1990, 2977)]
    for i, (a, b) in enumerate(spans):
        np.testing.assert_allclose(mean[i], raw[a:b, cols].mean(axis=0), rtol=1e-13)
        np.testing.assert_allclose(std[i], raw[a:b, cols[std_cols]].std(axis=0), rtol=1e-12)


def test_hdf5_data_written_after_close_is_the_same(tmp_path):
    """``write_hdf5(..., data_after_close=True)`` (the twin's files: values copied in by
    ``os.pwrite`` after h5py closes the file) gives the datasets, dtypes, attributes and
    values -- bit for bit -- of the ordinary write, read back by h5py and by the project's
    reader; an empty channel falls back to the ordinary write."""
    import h5py

    from torquemod.io import read_recording, write_recording
    from torquemod.io.experiment import Recording

    rng = np.random.default_rng(9)
    names = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")
    block = rng.standard_normal((len(names), 12345)) * 40.0
    rec = Recording({k: block[i, 17:] for i, k in enumerate(names)}, fs_hz=16670.0,
                    t0_s=4.25, source="test")
    files = {}
    for flag in (False, True):
        files[flag] = tmp_path / f"r{int(flag)}.h5"
        write_recording(files[flag], rec, fmt="hdf5", write_time=True, data_after_close=flag)
    with h5py.File(files[False]) as a, h5py.File(files[True]) as b:
        assert sorted(a) == sorted(b) and dict(a.attrs) == dict(b.attrs)
        for k in a:
            assert a[k].dtype == b[k].dtype == np.float64 and dict(a[k].attrs) == dict(b[k].attrs)
            assert np.array_equal(a[k][()], b[k][()])
    got = read_recording(files[True])
    for k in names:
        assert np.array_equal(got.channels[k], rec.channels[k])
    empty = Recording({k: np.empty(0) for k in names}, fs_hz=100.0, source="test")
    write_recording(tmp_path / "e.h5", empty, fmt="hdf5", data_after_close=True)
    with h5py.File(tmp_path / "e.h5") as fh:
        assert fh["torque_nm"].shape == (0,)


def test_creep_curve_peak_is_remembered_per_parameter_set():
    """The memos return what the computations give, per parameter set (another friction
    gives another peak) and DC torque, and other parameter objects are computed directly."""
    import dataclasses

    from torquemod.twins.vtrack.theory import (
        _creep_curve_peak,
        _operating_point,
        creep_curve_peak,
        operating_point,
    )

    rig = load_config().rig
    assert creep_curve_peak(rig) == _creep_curve_peak(rig, 0.5)
    assert creep_curve_peak(rig) is creep_curve_peak(rig)
    wet = dataclasses.replace(rig, contact=dataclasses.replace(rig.contact, mu0=0.15))
    assert creep_curve_peak(wet) == _creep_curve_peak(wet, 0.5)
    assert creep_curve_peak(wet)[1] < creep_curve_peak(rig)[1]

    class Unhashable:  # the same parameters, not hashable
        __hash__ = None

        def __getattr__(self, name):
            return getattr(rig, name)

    assert creep_curve_peak(Unhashable()) == creep_curve_peak(rig)
    for dc in (0.23, 44.47, 65.82, 72.0):
        for params in (rig, wet):
            assert operating_point(dc, params) == _operating_point(dc, params) or \
                operating_point(dc, params).slipped
        assert operating_point(dc, rig) is operating_point(dc, rig)
    assert operating_point(44.47, Unhashable()) == operating_point(44.47, rig)
    assert operating_point(72.0, rig).slipped and not operating_point(65.82, rig).slipped


def test_twin_recording_times_are_the_recordings():
    """The twin's files take their ``time_s`` from a compiled kernel: bit for bit
    :meth:`Recording.time_s` (``t0 + k/fs``)."""
    from torquemod.io.experiment import Recording
    from torquemod.twins.vtrack.simulate import _TwinRecording

    for n, t0, fs in [(107001, 12.3456789, 16670.0), (7, 0.0, 3.0), (0, 1.0, 2.0),
                      (99991, 1e4 / 3, 16670.0)]:
        ch = {"torque_nm": np.zeros(n)}
        want = Recording(ch, fs_hz=fs, t0_s=t0).time_s()
        assert np.array_equal(_TwinRecording(ch, fs_hz=fs, t0_s=t0).time_s(), want)


def test_fused_sensor_passes_equal_the_separate_ones():
    """The encoder with its noise in one pass, and two noisy channels in one pass, give the
    values of the separate passes bit for bit (strided columns of an output block as in
    ``measure``; the tail and wedge draws, ~1 % of the numbers, included)."""
    from torquemod.twins.vtrack.rig.noise import _ZF, _ZK, _ZW, add_normal_pair
    from torquemod.twins.vtrack.rig.sensors import _encoder_kernel, _encoder_noise_kernel

    rng = np.random.default_rng(11)
    n = 40_000
    raw = np.empty((n, 9))
    raw[:, 0] = 30.0 + rng.standard_normal(n)
    raw[:, 1] = 1.0 + 0.01 * rng.standard_normal(n)
    raw[:, 6] = np.cumsum(np.full(n, 1e-3)) + 0.2 * (np.arange(n) == n // 2)  # a jump
    raw[:, 3] = rng.standard_normal(n)
    enc = (0.004, 0.0015, 0.7, 2.1)
    want = np.empty(n)
    _encoder_kernel(raw[:, 1], raw[:, 6], *enc, want)
    end = add_normal(want, 0.02, 123456789, want)
    got = np.empty(n)
    got_end = _encoder_noise_kernel(raw[:, 1], raw[:, 6], *enc, 0.02, np.uint64(123456789),
                                    _ZK, _ZW, _ZF, got)
    np.testing.assert_array_equal(got, want)
    assert int(got_end) == end
    a, b = np.empty(n), np.empty(n)
    ends = (add_normal(raw[:, 0], 0.5, 7, a), add_normal(raw[:, 3], 2.0, 2**64 - 3, b))
    pa, pb = np.empty(n), np.empty(n)
    assert add_normal_pair(raw[:, 0], 0.5, 7, pa, raw[:, 3], 2.0, 2**64 - 3, pb) == ends
    np.testing.assert_array_equal(pa, a)
    np.testing.assert_array_equal(pb, b)
    with pytest.raises(ValueError, match="differ in shape"):
        add_normal_pair(raw[:, 0], 0.5, 7, pa, raw[:10, 3], 2.0, 1, pb)


def test_one_pass_sensors_equal_the_channel_passes():
    """``measure``'s one-pass kernel for six noisy channels gives the channel-by-channel
    passes' values bit for bit (rows of a C-ordered integrator output; encoder angles with
    a jump and more than 256 samples; the generators' wedge and tail draws, ~1 % of the
    numbers, included), and no channel shares another's stream."""
    from torquemod.twins.vtrack.rig.noise import _ZF, _ZK, _ZW
    from torquemod.twins.vtrack.rig.sensors import (
        _COLS,
        _SIGN,
        _measure_kernel,
        _measure_passes,
    )

    rng = np.random.default_rng(5)
    n = 30_000
    raw = rng.standard_normal((n, 9))
    raw[:, 1] += 10.0
    raw[:, 2] += 0.5
    raw[:, 6] = np.cumsum(np.full(n, 2e-3)) + 0.3 * (np.arange(n) >= n // 3)
    raw[:, 7] = np.cumsum(np.full(n, 4e-4))
    states = np.array([7, 2**64 - 3, 123456789, 2**63, 1, 99], dtype=np.uint64)
    enc = np.array([[0.004, 0.0015, 0.7, 2.1], [0.002, 0.0005, -1.0, 0.4]])
    sd = np.array([0.2, 0.01, 0.002, 3.0, 2.0, 1.0])
    want, got = np.empty((6, n)), np.empty((6, n))
    _measure_passes(raw, states, enc, sd, want)
    _measure_kernel(raw, _COLS, sd, states, enc, _ZK, _ZW, _ZF, _SIGN, got)
    assert got.tobytes() == want.tobytes()
    noise = (got - raw[:, _COLS[:6]].T)[[0, 3, 4, 5]] / sd[[0, 3, 4, 5], None]
    assert np.all(np.abs(np.corrcoef(noise)[np.triu_indices(4, 1)]) < 0.05)


def test_reference_angle_shares_the_band_sines():
    """The step starts' reference angle with the band rows' sines evaluated twice per RK4
    step is, bit for bit, the RK4 that evaluates the whole wobble four times (plain Python
    over the compiled ``_wobble``), for wobble tables with band rows first, revolution rows
    first, and band rows only."""
    import math as _m

    from torquemod.twins.vtrack.rig.dynamics import wobble_table
    from torquemod.twins.vtrack.rig.steps import _ANGLE_STEP_S, _reference_angle
    from torquemod.twins.vtrack.rig.wobble import _wobble

    def plain(t_ends, phi, w0, ipi, wob):
        out, t = [], 0.0
        for k, te in enumerate(t_ends):
            n = max(1, _m.ceil((te - t) / _ANGLE_STEP_S))
            h, q = (te - t) / n, ipi[k]
            for _ in range(n):
                k1 = w0 + _wobble(t, phi - q, wob)
                k2 = w0 + _wobble(t + 0.5 * h, phi + 0.5 * h * k1 - q, wob)
                k3 = w0 + _wobble(t + 0.5 * h, phi + 0.5 * h * k2 - q, wob)
                k4 = w0 + _wobble(t + h, phi + h * k3 - q, wob)
                phi += h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
                t += h
            out.append(phi)
        return np.array(out)

    cfg = load_config()
    rng = np.random.default_rng(12)
    full = wobble_table(cfg.disturbances, 0.97, rng)
    for wob in (full, np.ascontiguousarray(full[::-1]), np.ascontiguousarray(full[:3])):
        t_ends = np.array([0.37, 1.2, 1.9])
        ipi = np.array([1e-3, -2e-3, 5e-4])
        np.testing.assert_array_equal(_reference_angle(t_ends, 0.4, 0.97, ipi, wob),
                                      plain(t_ends, 0.4, 0.97, ipi, wob))
