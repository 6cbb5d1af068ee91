"""Logger realities (issue 8): channels on their own time bases are put on the torque
channel's sample times (or refused), never silently misaligned; provenance notes say so.
Also: jittered and epoch time stamps, int16 counts with a scale, optional channels.

Truth: every channel is a smooth function of absolute time (``_signal``), written at the times
its file declares. Read back, each channel must equal that function at the torque's sample
times. Tolerances: linear interpolation of a sine of frequency f between samples dt apart errs
by at most (2*pi*f*dt)^2/8 of its amplitude; the test signals have a 2 Hz sine (amplitude 1)
and a cosine of 0.7*k Hz (k <= 6, amplitude 0.3), so at 10 kHz the bound is
2.0e-7 + 0.3 * 8.7e-7 < 1e-6 (tolerance 1e-6); at 2.5 kHz it is 3.2e-6 + 0.3 * 1.4e-5 < 1e-5.
"""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
import scipy.io

from torquemod.errors import InputError
from torquemod.io import read_recording, write_recording
from torquemod.io.convert import convert_file
from torquemod.io.experiment import CHANNELS, OPTIONAL_CHANNELS, REQUIRED_CHANNELS, Recording
from torquemod.io.timebase import SAME_INSTANT_SAMPLES
from torquemod.io.validate import fit_time_grid, sample_rate_from_time

FS = 10_000.0
N = 20_000
NAMES = CHANNELS[:6]  # the rig's channels (the train's reference speed: tests/test_train_io.py)
EPOCH = 1.7e9


def _signal(name: str, t: np.ndarray) -> np.ndarray:
    """Each channel a distinct smooth function of time [s] (relative to EPOCH if above)."""
    k = {"torque_nm": 1.0, "wheel_speed_rad_s": 2.0, "platform_speed_rad_s": 3.0,
         "fx_n": 4.0, "fy_n": 5.0, "fz_n": 6.0, "vehicle_speed_m_s": 7.0,
         "position_m": 8.0}[name]
    return 10 * k + np.sin(2 * np.pi * 2.0 * t + k) + 0.3 * np.cos(2 * np.pi * 0.7 * t * k)


def _write_tdms(path, offsets_s: dict[str, float], rates_hz: dict[str, float] | None = None,
                extra: list | None = None):
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    rates_hz = rates_hz or {}
    objs = [GroupObject("Meas")]
    for name, off in offsets_s.items():
        fs = rates_hz.get(name, FS)
        n = int(N * fs / FS)
        t = off + np.arange(n) / fs
        objs.append(ChannelObject("Meas", name, _signal(name, t),
                                  properties={"wf_increment": 1.0 / fs, "wf_start_offset": off}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs + (extra or []))
    return path


def _assert_truth(rec: Recording, atol: float, names=NAMES, epoch: float = 0.0) -> None:
    t = rec.time_s() - epoch
    for name in names:
        np.testing.assert_allclose(rec.channels[name], _signal(name, t), atol=atol,
                                   rtol=0, err_msg=name)
        assert rec.channels[name].dtype == np.float64


# --- TDMS: start offsets and rates ----------------------------------------------------------

def test_tdms_whole_sample_offset_is_a_shift(tmp_path):
    offsets = dict.fromkeys(NAMES, 0.0) | {"wheel_speed_rad_s": 3 / FS, "fx_n": -2 / FS}
    rec = read_recording(_write_tdms(tmp_path / "a.tdms", offsets))
    _assert_truth(rec, atol=1e-12)  # shifted, not interpolated: the values are the file's
    assert rec.n_samples == N - 5 and rec.t0_s == pytest.approx(3 / FS, abs=1e-12)
    assert any("wheel_speed_rad_s" in n and "+3 samples" in n and "shifted" in n
               for n in rec.notes)
    assert any("fx_n" in n and "-2 samples" in n for n in rec.notes)
    assert any("3 samples of torque_nm dropped at the start and 2 at the end" in n
               for n in rec.notes)


@pytest.mark.parametrize("offset_s", [2.37 / FS, 0.5 / FS, -0.01253])
def test_tdms_fractional_offsets_are_interpolated(tmp_path, offset_s):
    offsets = dict.fromkeys(NAMES, 0.0) | {"wheel_speed_rad_s": offset_s}
    rec = read_recording(_write_tdms(tmp_path / "a.tdms", offsets))
    _assert_truth(rec, atol=1e-6)
    note = next(n for n in rec.notes if "wheel_speed_rad_s" in n)
    assert "own time base" in note and "interpolated linearly" in note
    assert "error < 4.4e-05" in note  # (2*pi*30 Hz / 10 kHz)^2 / 8
    # cut to the common span: at most the offset plus a sample
    assert N / FS - abs(offset_s) - 2 / FS < rec.duration_s <= N / FS


def test_tdms_without_a_fix_would_be_misaligned(tmp_path):
    """The test's own sensitivity: reading the shifted channel sample for sample (as a
    manifest sample rate would) is wrong by far more than the tolerance above."""
    offsets = dict.fromkeys(NAMES, 0.0) | {"wheel_speed_rad_s": 2.37 / FS}
    rec = read_recording(_write_tdms(tmp_path / "a.tdms", offsets))
    raw = _signal("wheel_speed_rad_s", 2.37 / FS + np.arange(N) / FS)
    t = np.arange(N) / FS
    assert np.max(np.abs(raw - _signal("wheel_speed_rad_s", t))) > 1e-3
    assert rec.n_samples < N


@pytest.mark.parametrize(("rate_hz", "atol"), [(2_500.0, 1e-5), (20_000.0, 1e-5)])
def test_tdms_channel_at_another_rate(tmp_path, rate_hz, atol):
    offsets = dict.fromkeys(NAMES, 0.0) | {"fz_n": 0.37 / rate_hz}
    rec = read_recording(_write_tdms(tmp_path / "b.tdms", offsets, {"fz_n": rate_hz}))
    assert rec.fs_hz == pytest.approx(FS, rel=1e-12)
    _assert_truth(rec, atol=atol)
    note = next(n for n in rec.notes if "fz_n" in n)
    assert f"{rate_hz:.6g} Hz vs 10000 Hz" in note
    assert ("low-passed" in note) == (rate_hz > FS)


def test_faster_channel_noise_does_not_alias(tmp_path):
    """White noise on a 40 kHz channel: low-passed at 4 kHz before it is put on the 10 kHz
    grid, so its variance drops to ~ 2 * 4 kHz / 40 kHz = 0.2 of the original (every fourth
    sample without the filter: all of it, 1.0)."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    rng = np.random.default_rng(5)
    objs = [GroupObject("Meas")]
    for name in REQUIRED_CHANNELS:
        fs = 40_000.0 if name == "wheel_speed_rad_s" else FS
        n = int(N * fs / FS)
        x = _signal(name, np.arange(n) / fs)
        if name == "wheel_speed_rad_s":
            x = x + rng.standard_normal(n)
        objs.append(ChannelObject("Meas", name, x, properties={"wf_increment": 1 / fs}))
    with TdmsWriter(str(tmp_path / "n.tdms")) as w:
        w.write_segment(objs)
    rec = read_recording(tmp_path / "n.tdms")
    resid = rec.channels["wheel_speed_rad_s"] - _signal("wheel_speed_rad_s", rec.time_s())
    assert 0.15 < np.var(resid[100:-100]) < 0.25


def test_tdms_offsets_with_a_time_channel(tmp_path):
    """The time channel gives the time base; the offsets still align the channels."""
    from nptdms import ChannelObject
    offsets = dict.fromkeys(NAMES, 0.0) | {"fx_n": 1.5 / FS}
    time = ChannelObject("Meas", "time_s", np.arange(N) / FS)
    rec = read_recording(_write_tdms(tmp_path / "t.tdms", offsets, extra=[time]))
    _assert_truth(rec, atol=1e-6)
    assert rec.n_samples == N - 2


def test_manifest_sample_rate_with_differing_offsets_is_refused(tmp_path):
    offsets = dict.fromkeys(NAMES, 0.0) | {"fx_n": 2.37 / FS}
    path = _write_tdms(tmp_path / "r.tdms", offsets)
    with pytest.raises(InputError, match=r"r\.tdms: channel 'fx_n': its own time base .*"
                                         r"differs.*remove sample_rate_hz"):
        read_recording(path, sample_rate_hz=FS)
    same = _write_tdms(tmp_path / "s.tdms", dict.fromkeys(NAMES, 0.0))
    assert read_recording(same, sample_rate_hz=FS / 2).fs_hz == FS / 2  # one base: replaced


@pytest.mark.parametrize(("offsets", "pattern"), [
    ({"fx_n": 0.5}, r"c\.tdms: channel 'fx_n': starts 0\.5000 s after torque_nm .*"
                    r"share 75\.0 % .*at least 90 %.*; export all channels over one time"),
    ({"fy_n": -0.3}, r"c\.tdms: channel 'fy_n': ends 0\.3000 s before torque_nm"),
])
def test_channel_not_covering_the_span_is_refused(tmp_path, offsets, pattern):
    path = _write_tdms(tmp_path / "c.tdms", dict.fromkeys(NAMES, 0.0) | offsets)
    with pytest.raises(InputError, match=pattern):
        read_recording(path)


def test_slightly_short_channel_is_cut_not_refused(tmp_path):
    rec = read_recording(_write_tdms(tmp_path / "d.tdms",
                                     dict.fromkeys(NAMES, 0.0) | {"fx_n": 0.15}))
    _assert_truth(rec, atol=1e-12)
    assert rec.t0_s == pytest.approx(0.15) and rec.n_samples == N - 1500
    assert any("1500 samples of torque_nm dropped at the start" in n for n in rec.notes)


# --- MDF4: channel groups on their own masters ---------------------------------------------

def _mdf_two_groups(path, *, t_main, t_force, force_names=("fx_n", "fy_n", "fz_n")):
    from asammdf import MDF, Signal
    mdf = MDF(version="4.10")
    mdf.append([Signal(_signal(k, t_main - EPOCH), t_main, name=k)
                for k in ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s")])
    mdf.append([Signal(_signal(k, t_force - EPOCH), t_force, name=k) for k in force_names])
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def test_mdf_groups_at_different_rates_and_offsets(tmp_path):
    t_main = EPOCH + np.arange(N) / FS  # epoch time stamps
    t_force = EPOCH + 0.00113 + np.arange(N // 4) / (FS / 4)
    rec = read_recording(_mdf_two_groups(tmp_path / "g.mf4", t_main=t_main, t_force=t_force))
    assert rec.fs_hz == pytest.approx(FS, rel=1e-9)
    assert rec.t0_s == pytest.approx(EPOCH + 0.0012, abs=1e-6)
    _assert_truth(rec, atol=1e-5, epoch=EPOCH)  # forces at 2.5 kHz, see the module doc
    assert sum("own time base" in n and "2500 Hz vs 10000 Hz" in n for n in rec.notes) == 3


def test_mdf_groups_with_jittered_epoch_stamps(tmp_path):
    """Both groups at 10 kHz, stamps jittering by +-0.2 sample around their grids, the
    forces' grid 0.4 samples late: the fitted grids align them to 1e-6 of the values."""
    rng = np.random.default_rng(11)
    k = np.arange(N)
    t_main = EPOCH + (k + rng.uniform(-0.2, 0.2, N)) / FS
    t_force = EPOCH + (k + 0.4 + rng.uniform(-0.2, 0.2, N)) / FS
    rec = read_recording(_mdf_two_groups(tmp_path / "j.mf4", t_main=t_main, t_force=t_force))
    # the forces start 0.4 samples late, so the first torque sample is dropped
    true_t = EPOCH + (np.arange(rec.n_samples) + 1) / FS
    np.testing.assert_allclose(rec.time_s(), true_t, atol=0.02 / FS, rtol=0)
    # the values were written at the jittered instants: they differ from the truth on the
    # grid by up to |dx/dt| * 0.2 / FS <= 21/s * 2e-5 s = 4.2e-4 (the file's own error)
    _assert_truth(rec, atol=5e-4, epoch=EPOCH)
    assert sum("starts +0.04" in n for n in rec.notes) == 3


def test_mdf_same_grid_in_two_groups_is_left_alone(tmp_path):
    t = EPOCH + np.arange(N) / FS
    rec = read_recording(_mdf_two_groups(tmp_path / "s.mf4", t_main=t, t_force=t.copy()))
    assert rec.notes == [] and rec.n_samples == N
    _assert_truth(rec, atol=1e-12, epoch=EPOCH)


def test_mdf_group_not_covering_is_refused(tmp_path):
    t_main = np.arange(N) / FS
    t_force = 1.0 + np.arange(N // 4) / (FS / 4)  # starts half way
    path = _mdf_two_groups(tmp_path / "late.mf4", t_main=t_main + EPOCH,
                           t_force=t_force + EPOCH)
    with pytest.raises(InputError, match=r"late\.mf4: channel 'f[xyz]_n': starts 1\.0000 s "
                                         r"after torque_nm"):
        read_recording(path)


def test_mdf_group_with_a_gap_is_refused(tmp_path):
    t = EPOCH + np.arange(N) / FS
    t_force = t.copy()
    t_force[N // 2:] += 5 / FS  # five samples lost
    with pytest.raises(InputError, match=r"gap\.mf4: channel 'f[xyz]_n': time is not "
                                         r"uniformly sampled"):
        read_recording(_mdf_two_groups(tmp_path / "gap.mf4", t_main=t, t_force=t_force))


# --- time stamps: jitter and epoch offsets --------------------------------------------------

@pytest.mark.parametrize("fs", [10_000.0, 25_600.0])
@pytest.mark.parametrize("jitter", [0.0, 0.2])
def test_jittered_epoch_stamps_fit(fs, jitter):
    rng = np.random.default_rng(3)
    n = 200_000
    t0 = EPOCH + 0.123456
    t = t0 + (np.arange(n) + rng.uniform(-jitter, jitter, n)) / fs
    got_fs, got_t0 = sample_rate_from_time(t, path="x")
    # the fitted grid drifts from the true one by < 0.01 sample over the record (the rate's
    # standard error with +-0.2 sample jitter is 0.115 / sqrt(n^3 / 12) = 4.5e-9 relative)
    assert abs(got_fs / fs - 1) * n < 0.01
    # float64 spacing at 1.7e9 s is 2.4e-7 s (0.006 samples at 25.6 kHz)
    assert abs(got_t0 - t0) * fs < 0.01
    _, anchor, rel = fit_time_grid(t, path="x")
    assert anchor == t[0] and abs((anchor - EPOCH) + rel - 0.123456) * fs < 0.005


def test_rounded_stamps_fit():
    """Stamps written with 5 decimals at 25.6 kHz (rounding up to 0.13 sample)."""
    fs = 25_600.0
    t = np.round(12.0 + np.arange(100_000) / fs, 5)
    got_fs, got_t0 = sample_rate_from_time(t, path="x")
    assert got_fs == pytest.approx(fs, rel=1e-8) and abs(got_t0 - 12.0) * fs < 0.05


def test_jitter_above_a_quarter_sample_is_refused():
    rng = np.random.default_rng(4)
    t = (np.arange(20_000) + rng.uniform(-0.3, 0.3, 20_000)) / FS
    with pytest.raises(InputError, match="not uniformly sampled"):
        sample_rate_from_time(t, path="x")


@pytest.mark.parametrize("fmt", ["csv", "mat5", "parquet"])
def test_jittered_epoch_time_column_read(fmt, tmp_path, write_columns):
    rng = np.random.default_rng(8)
    k = np.arange(N)
    true_t = k / FS
    columns = {"time_s": EPOCH + (k + rng.uniform(-0.2, 0.2, N)) / FS}
    columns.update({c: _signal(c, true_t) for c in NAMES})
    rec = read_recording(write_columns(fmt, tmp_path / f"e{SUFFIX[fmt]}", columns))
    assert abs(rec.fs_hz / FS - 1) * N < 0.01  # drift over the record < 0.01 sample
    assert abs(rec.t0_s - EPOCH) * FS < 0.02
    assert rec.n_samples == N and rec.notes == []
    for c in NAMES:  # sample for sample, as written
        np.testing.assert_array_equal(rec.channels[c], columns[c])


def test_epoch_offsets_in_tdms_properties(tmp_path):
    offsets = dict.fromkeys(NAMES, EPOCH) | {"fx_n": EPOCH + 0.37 / FS}
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    objs = [GroupObject("Meas")]
    for name, off in offsets.items():
        t = np.arange(N) / FS + (off - EPOCH)
        objs.append(ChannelObject("Meas", name, _signal(name, t),
                                  properties={"wf_increment": 1 / FS, "wf_start_offset": off}))
    with TdmsWriter(str(tmp_path / "ep.tdms")) as w:
        w.write_segment(objs)
    rec = read_recording(tmp_path / "ep.tdms")
    assert rec.t0_s == pytest.approx(EPOCH + 1 / FS, abs=1e-6)
    _assert_truth(rec, atol=1e-5, epoch=EPOCH)  # time_s() at 1.7e9 is good to 2.4e-7 s
    assert any("fx_n" in n and "+0.0370 ms" in n for n in rec.notes)


# --- per-channel time vectors (.mat, HDF5) through [channels] -------------------------------

@pytest.mark.parametrize("fmt", ["mat5", "mat73", "hdf5"])
def test_per_channel_time_vectors(fmt, tmp_path, write_columns):
    t = np.arange(N) / FS
    t_force = 0.25 / FS + np.arange(N // 2) / (FS / 2)  # forces: 5 kHz, 0.25 samples late
    columns = {"t": t, "t_force": t_force * 1e3}
    columns.update({c: _signal(c, t) for c in ("torque_nm", "wheel_speed_rad_s",
                                                "platform_speed_rad_s")})
    columns.update({c: _signal(c, t_force) for c in ("fx_n", "fy_n", "fz_n")})
    path = write_columns(fmt, tmp_path / ("p.h5" if fmt == "hdf5" else "p.mat"), columns)
    own = {"name": "t_force", "unit": "ms"}
    table = {"time": "t", **{f: {"name": f"{f}_n", "time": own} for f in ("fx", "fy", "fz")}}
    rec = read_recording(path, channel_map=table)
    _assert_truth(rec, atol=1e-5)
    assert sum("own time base" in n and "5000 Hz" in n for n in rec.notes) == 3
    with pytest.raises(InputError, match=r"channel 'fx_n': no channel 'nope' in the file"):
        read_recording(path, channel_map={"time": "t", "fx": {"name": "fx_n", "time": "nope"}})
    with pytest.raises(InputError, match=r"both a sample rate .* own time vector"):
        read_recording(path, channel_map={"fx": {"name": "fx_n", "time": "t_force"}},
                       sample_rate_hz=FS)


@pytest.mark.parametrize(("entry", "pattern"), [
    ({"name": "F", "time": 3}, r"'channels\.fx\.time' must be the name"),
    ({"name": "F", "time": {"name": "t", "unit": "N"}}, r"unit 'N' is a force"),
    ({"name": "F", "time": {"name": "t", "bogus": 1}},
     r"unknown key 'channels\.fx\.time\.bogus'.*takes name, unit"),
])
def test_bad_per_channel_time_entries(entry, pattern):
    from torquemod.io.channels import resolve_channel_map
    with pytest.raises(InputError, match=pattern):
        resolve_channel_map({"fx": entry}, "exp/experiment.toml")


# --- 16-bit counts with a scale --------------------------------------------------------------

FULL_SCALE = {"torque_nm": 100.0, "wheel_speed_rad_s": 100.0, "platform_speed_rad_s": 100.0,
              "fx_n": 1e3, "fy_n": 1e3, "fz_n": 1e4}


def _counts(name: str, t: np.ndarray) -> np.ndarray:
    return np.round(_signal(name, t) / FULL_SCALE[name] * 32767).astype(np.int16)


def _check_counts(rec: Recording, unit_factor: dict[str, float] | None = None) -> None:
    t = rec.time_s()
    for name in NAMES:
        assert rec.channels[name].dtype == np.float64
        lsb = FULL_SCALE[name] / 32767
        np.testing.assert_allclose(rec.channels[name], _signal(name, t), atol=0.5001 * lsb,
                                   rtol=0, err_msg=name)


def test_tdms_int16_with_ni_scaling(tmp_path):
    """Raw int16 counts with a linear NI scale (slope and intercept) and units: read scaled,
    in SI, as float64, within half a count."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    t = np.arange(N) / FS
    objs = [GroupObject("Meas")]
    for name in NAMES:
        lsb = FULL_SCALE[name] / 32767
        unit, k = ("kN", 1e-3) if name[0] == "f" else ("", 1.0)  # the scale gives kN
        props = {"NI_Number_Of_Scales": 1, "NI_Scaling_Status": "unscaled",
                 "NI_Scale[0]_Scale_Type": "Linear", "NI_Scale[0]_Linear_Slope": lsb * k,
                 "NI_Scale[0]_Linear_Y_Intercept": -0.5 * k,
                 "NI_Scale[0]_Linear_Input_Source": 0xFFFFFFFF,
                 "wf_increment": 1 / FS, "wf_start_offset": 0.0}
        if unit:
            props["unit_string"] = unit
        x = np.round((_signal(name, t) + 0.5) / lsb).astype(np.int16)
        objs.append(ChannelObject("Meas", name, x, properties=props))
    with TdmsWriter(str(tmp_path / "q.tdms")) as w:
        w.write_segment(objs)
    from nptdms import TdmsFile
    assert TdmsFile.read(tmp_path / "q.tdms")["Meas"]["fz_n"].data_type.size == 2  # int16
    rec = read_recording(tmp_path / "q.tdms")
    _check_counts(rec)
    assert rec.notes == []


def test_mdf_int16_with_a_linear_conversion(tmp_path):
    from asammdf import MDF, Signal
    t = np.arange(N) / FS
    mdf = MDF(version="4.10")
    sigs = []
    for name in NAMES:
        lsb = FULL_SCALE[name] / 32767
        sigs.append(Signal(_counts(name, t), t, name=name, unit="N" if name[0] == "f" else "",
                           conversion={"a": lsb, "b": 0.0}))
    mdf.append(sigs)
    mdf.save(tmp_path / "q.mf4", overwrite=True)
    mdf.close()
    raw = MDF(tmp_path / "q.mf4")
    assert raw.get("fz_n", raw=True).samples.dtype == np.int16
    raw.close()
    rec = read_recording(tmp_path / "q.mf4")
    _check_counts(rec)


def test_hdf5_int16_with_cf_scale(tmp_path):
    t = np.arange(N) / FS
    with h5py.File(tmp_path / "q.h5", "w") as fh:
        fh.attrs["sample_rate_hz"] = FS
        for name in NAMES:
            ds = fh.create_dataset(name, data=_counts(name, t) - np.int16(100))
            ds.attrs["scale_factor"] = FULL_SCALE[name] / 32767
            ds.attrs["add_offset"] = 100 * FULL_SCALE[name] / 32767
    _check_counts(read_recording(tmp_path / "q.h5"))
    with h5py.File(tmp_path / "q.h5", "a") as fh:
        fh["fz_n"].attrs["scale_factor"] = "x"
    with pytest.raises(InputError, match=r"q\.h5: dataset 'fz_n': attribute scale_factor"):
        read_recording(tmp_path / "q.h5")


def test_int16_without_a_scale_is_noted(tmp_path):
    t = np.arange(N) / FS
    with h5py.File(tmp_path / "raw.h5", "w") as fh:
        fh.attrs["sample_rate_hz"] = FS
        for name in REQUIRED_CHANNELS:
            fh.create_dataset(name, data=_counts(name, t))
    rec = read_recording(tmp_path / "raw.h5")
    assert rec.channels["torque_nm"].dtype == np.float64
    assert any("'torque_nm' is stored as int16 without a scale" in n and "N*m" in n
               for n in rec.notes)


# --- optional channels -----------------------------------------------------------------------

def test_channel_constants():
    assert set(REQUIRED_CHANNELS) | set(OPTIONAL_CHANNELS) == set(CHANNELS)
    assert not set(REQUIRED_CHANNELS) & set(OPTIONAL_CHANNELS)


ALL_FORMATS = ("csv", "hdf5", "tdms", "mdf", "mat5", "mat73", "parquet")
SUFFIX = {"csv": ".csv", "hdf5": ".h5", "tdms": ".tdms", "mdf": ".mf4", "mat5": ".mat",
          "mat73": ".mat", "parquet": ".parquet"}


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_required_channels_only_and_force_rules(fmt, tmp_path, write_columns):
    t = np.arange(400) / 2000.0
    base = {"time_s": t, **{c: _signal(c, t) for c in REQUIRED_CHANNELS}}
    kw = {"fs_hz": 2000.0} if fmt == "mdf" else {}
    rec = read_recording(write_columns(fmt, tmp_path / f"a{SUFFIX[fmt]}", base, **kw))
    assert set(rec.channels) == set(REQUIRED_CHANNELS)
    for cols, missing in (({"fx_n"}, "fz_n"), ({"fz_n"}, "fx_n"), ({"fy_n"}, "fx_n"),
                          ({"fx_n", "fy_n"}, "fz_n")):
        path = write_columns(fmt, tmp_path / f"b{len(cols)}{missing}{SUFFIX[fmt]}",
                             base | {c: _signal(c, t) for c in cols}, **kw)
        with pytest.raises(InputError) as info:
            read_recording(path)
        assert path.name in str(info.value) and f"channel '{missing}'" in str(info.value)
    for req in REQUIRED_CHANNELS:
        path = write_columns(fmt, tmp_path / f"c_{req}{SUFFIX[fmt]}",
                             {k: v for k, v in base.items() if k != req}, **kw)
        with pytest.raises(InputError, match=rf"{path.name}.*channel '{req}'"):
            read_recording(path)


@pytest.mark.parametrize("fmt", ["csv", "hdf5"])
def test_write_and_convert_keep_what_is_there(fmt, tmp_path):
    t = np.arange(400) / 2000.0
    rec = Recording({c: _signal(c, t) for c in ("torque_nm", "wheel_speed_rad_s", "fx_n",
                                                "fz_n")}, 2000.0, 0.0, "x",
                    ["no lateral force channel: CoA = |Fx|/Fz"])
    path = write_recording(tmp_path / f"w{SUFFIX[fmt]}", rec, fmt=fmt)
    back = read_recording(path)
    assert set(back.channels) == set(rec.channels)
    for k, v in rec.channels.items():
        np.testing.assert_allclose(back.channels[k], v, rtol=1e-8)
    out = convert_file(path, tmp_path / "conv.h5")
    conv = read_recording(out)
    assert set(conv.channels) == set(rec.channels)
    if fmt == "hdf5":  # the notes went into the file and come back, marked as such
        assert "as written to the file: no lateral force channel: CoA = |Fx|/Fz" in conv.notes
    # rewriting a group with fewer channels leaves none of the old ones behind
    full = Recording({c: _signal(c, t) for c in CHANNELS}, 2000.0)
    write_recording(tmp_path / "g.h5", full, fmt="hdf5")
    write_recording(tmp_path / "g.h5", rec, fmt="hdf5")
    assert set(read_recording(tmp_path / "g.h5").channels) == set(rec.channels)


def test_convert_keeps_alignment_notes(tmp_path):
    offsets = dict.fromkeys(NAMES, 0.0) | {"fx_n": 2.37 / FS}
    src = _write_tdms(tmp_path / "o.tdms", offsets)
    rec = read_recording(src)
    conv = read_recording(convert_file(src, tmp_path / "o.h5"))
    assert [f"as written to the file: {n}" for n in rec.notes] == conv.notes
    np.testing.assert_allclose(conv.channels["fx_n"], rec.channels["fx_n"], rtol=0, atol=0)


def test_slice_keeps_notes_and_channels():
    t = np.arange(100) / 100.0
    rec = Recording({c: _signal(c, t) for c in REQUIRED_CHANNELS}, 100.0, 1.0, "s", ["a"])
    part = rec.slice(10, 20)
    assert part.notes == ["a"] and part.notes is not rec.notes
    assert set(part.channels) == set(REQUIRED_CHANNELS) and part.t0_s == pytest.approx(1.1)


def test_same_instant_tolerance_is_small():
    """Offsets within SAME_INSTANT_SAMPLES are taken as whole: at 2 Hz and 10 kHz that is a
    phase of at most 360 * 2 * 0.01 / 1e4 = 7e-4 degrees."""
    assert 360 * 2.0 * SAME_INSTANT_SAMPLES / 10_000 < 1e-3
    assert math.isclose(SAME_INSTANT_SAMPLES, 0.01)


def test_mat5_struct_group_is_fine_with_absent_options(tmp_path):
    t = np.arange(400) / 2000.0
    scipy.io.savemat(tmp_path / "s.mat", {"daq": {"time_s": t, "torque_nm": _signal(
        "torque_nm", t), "wheel_speed_rad_s": _signal("wheel_speed_rad_s", t)}})
    rec = read_recording(tmp_path / "s.mat", group="daq")
    assert set(rec.channels) == set(REQUIRED_CHANNELS)
