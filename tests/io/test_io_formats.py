"""Readers of every acquisition format, the [channels] mapping, units and conversion."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from torquemod.errors import InputError, ManifestError, OutputError
from torquemod.io import read_experiment, read_recording, write_manifest
from torquemod.io.channels import QUANTITY, default_channel_map, resolve_channel_map
from torquemod.io.convert import convert_experiment, convert_file
from torquemod.io.experiment import CHANNEL_UNITS, CHANNELS, Recording
from torquemod.io.recording import read_entry, supported_suffixes
from torquemod.io.units import UNITS, canonical_unit, convert_units

FS_HZ = 2000.0
T0_S = 0.25
N = 400
ALL_FORMATS = ("csv", "hdf5", "tdms", "mdf", "mat5", "mat73", "parquet")
SUFFIX = {"csv": ".csv", "hdf5": ".h5", "tdms": ".tdms", "mdf": ".mf4", "mat5": ".mat",
          "mat73": ".mat", "parquet": ".parquet"}
#: Formats that can carry their own sample rate instead of a time column.
NATIVE_RATE_FORMATS = ("hdf5", "tdms", "mdf", "mat5", "mat73", "parquet")


@pytest.fixture(scope="module")
def reference() -> Recording:
    """A recording with full-precision values (no short decimal forms)."""
    rng = np.random.default_rng(20240501)
    scale = {"torque_nm": 40.0, "wheel_speed_rad_s": 30.0, "platform_speed_rad_s": 0.7,
             "fx_n": 900.0, "fy_n": 150.0, "fz_n": 4200.0, "vehicle_speed_m_s": 20.0,
             "position_m": 500.0}
    channels = {c: scale[c] * (1 + 0.1 * rng.standard_normal(N)) for c in CHANNELS}
    return Recording(channels, FS_HZ, T0_S, "reference")


def _time(rec: Recording) -> np.ndarray:
    return rec.time_s()


def _assert_same(rec: Recording, ref: Recording, *, rtol: float = 1e-12) -> None:
    assert set(rec.channels) == set(CHANNELS)
    for c in CHANNELS:
        np.testing.assert_allclose(rec.channels[c], ref.channels[c], rtol=rtol, atol=1e-9,
                                   err_msg=c)
        assert rec.channels[c].dtype == np.float64
    assert rec.fs_hz == pytest.approx(ref.fs_hz, rel=1e-9)
    assert rec.t0_s == pytest.approx(ref.t0_s, abs=1e-9)


def _write(write_columns, tmp_path: Path, fmt: str, columns: dict, **kw) -> Path:
    path = tmp_path / f"rec_{fmt}{SUFFIX[fmt]}"
    return write_columns(fmt, path, columns, **kw)


# --- the same recording in every format ----------------------------------------------------

@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_every_format_with_time_column_matches_csv(fmt, reference, tmp_path, write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    csv_rec = read_recording(_write(write_columns, tmp_path, "csv", columns))
    kw = {"fs_hz": FS_HZ, "t0_s": T0_S} if fmt == "mdf" else {}
    rec = read_recording(_write(write_columns, tmp_path, fmt, columns, **kw))
    _assert_same(rec, csv_rec)
    _assert_same(rec, reference)


@pytest.mark.parametrize("fmt", NATIVE_RATE_FORMATS)
def test_native_sample_rate_without_time_column(fmt, reference, tmp_path, write_columns):
    path = _write(write_columns, tmp_path, fmt, dict(reference.channels), fs_hz=FS_HZ,
                  t0_s=T0_S)
    _assert_same(read_recording(path), reference)


def test_suffixes_cover_every_format():
    assert {".csv", ".h5", ".hdf5", ".tdms", ".mf4", ".mat", ".parquet"} <= set(
        supported_suffixes())


# --- renamed channels and units -------------------------------------------------------------

#: file name, unit, factor from SI to the file's unit (values in the file = SI * factor)
RENAMED = {
    "torque_nm": ("Torque", "kN*m", 1e-3),
    "wheel_speed_rad_s": ("WheelSpeed", "rpm", 60.0 / (2 * math.pi)),
    "platform_speed_rad_s": ("PlatformSpeed", "deg/s", 180.0 / math.pi),
    "fx_n": ("Fx", "kN", 1e-3),
    "fy_n": ("Fy", "N", 1.0),
    "fz_n": ("Fz", "daN", 0.1),
    "vehicle_speed_m_s": ("Radar", "km/h", 3.6),
    "position_m": ("Odometer", "km", 1e-3),
}
SHORT = {"torque_nm": "torque", "wheel_speed_rad_s": "wheel_speed",
         "platform_speed_rad_s": "platform_speed", "fx_n": "fx", "fy_n": "fy", "fz_n": "fz",
         "vehicle_speed_m_s": "vehicle_speed", "position_m": "position"}


def _renamed_columns(ref: Recording, prefix: str = "") -> dict:
    cols = {f"{prefix}Time": (_time(ref) * 1e3)}  # in ms
    cols.update({prefix + RENAMED[c][0]: ref.channels[c] * RENAMED[c][2] for c in CHANNELS})
    return cols


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_renamed_channels_with_units_from_the_manifest(fmt, reference, tmp_path,
                                                       write_columns):
    prefix = {"tdms": "Rig/", "mat5": "daq.", "mat73": "daq."}.get(fmt, "")
    kw = {"fs_hz": FS_HZ, "t0_s": T0_S} if fmt == "mdf" else {}
    path = _write(write_columns, tmp_path, fmt, _renamed_columns(reference, prefix), **kw)
    table = {SHORT[c]: {"name": prefix + RENAMED[c][0], "unit": RENAMED[c][1]}
             for c in CHANNELS}
    table["time"] = {"name": prefix + "Time", "unit": "ms"}
    _assert_same(read_recording(path, channel_map=table), reference, rtol=1e-12)


@pytest.mark.parametrize("fmt", ["hdf5", "tdms", "mdf", "parquet"])
def test_units_declared_in_the_file_are_used(fmt, reference, tmp_path, write_columns):
    columns = _renamed_columns(reference)
    units = {RENAMED[c][0]: RENAMED[c][1] for c in CHANNELS}
    units["Time"] = "ms"
    kw = {"fs_hz": FS_HZ, "t0_s": T0_S} if fmt == "mdf" else {}
    path = _write(write_columns, tmp_path, fmt, columns, units=units, **kw)
    table = {SHORT[c]: RENAMED[c][0] for c in CHANNELS}  # names only: units from the file
    table["time"] = "Time"
    _assert_same(read_recording(path, channel_map=table), reference)


def test_manifest_unit_overrides_the_file_unit(reference, tmp_path, write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    path = _write(write_columns, tmp_path, "hdf5", columns, units={"fx_n": "kN"})
    # the file wrongly says kN; the manifest knows better
    rec = read_recording(path, channel_map={"fx": {"name": "fx_n", "unit": "N"}})
    np.testing.assert_array_equal(rec.channels["fx_n"], reference.channels["fx_n"])
    rec = read_recording(path)
    np.testing.assert_allclose(rec.channels["fx_n"], reference.channels["fx_n"] * 1e3)


def test_unknown_unit_declared_in_the_file_names_it(reference, tmp_path, write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    path = _write(write_columns, tmp_path, "tdms", columns, units={"torque_nm": "V"})
    with pytest.raises(InputError, match=r"torque_nm.*'V'") as info:
        read_recording(path)
    assert path.name in str(info.value)


def test_linear_speed_with_radius(reference, tmp_path, write_columns):
    radius_m = 0.0675
    columns = {"time_s": _time(reference), **reference.channels}
    columns["v_kmh"] = reference.channels["wheel_speed_rad_s"] * radius_m * 3.6
    del columns["wheel_speed_rad_s"]
    path = _write(write_columns, tmp_path, "csv", columns)
    table = {"wheel_speed": {"name": "v_kmh", "unit": "km/h", "radius_m": radius_m}}
    _assert_same(read_recording(path, channel_map=table), reference)


def test_full_channel_names_as_keys(reference, tmp_path, write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    columns["T"] = columns.pop("torque_nm")
    path = _write(write_columns, tmp_path, "csv", columns)
    _assert_same(read_recording(path, channel_map={"torque_nm": "T"}), reference)


def test_sample_rate_from_the_channels_table(reference, tmp_path, write_columns):
    path = _write(write_columns, tmp_path, "csv", dict(reference.channels))
    rec = read_recording(path, channel_map={"sample_rate_hz": FS_HZ, "t0_s": T0_S})
    _assert_same(rec, reference)


def test_per_recording_sample_rate_overrides_the_file(reference, tmp_path, write_columns):
    path = _write(write_columns, tmp_path, "tdms", dict(reference.channels), fs_hz=1000.0)
    assert read_recording(path).fs_hz == pytest.approx(1000.0)
    assert read_recording(path, sample_rate_hz=FS_HZ).fs_hz == FS_HZ


# --- convert_units ---------------------------------------------------------------------------

@pytest.mark.parametrize(("value", "unit", "quantity", "expected"), [
    (60.0, "rpm", "angular_speed", 2 * math.pi),
    (60.0, "1/min", "angular_speed", 2 * math.pi),
    (180.0, "deg/s", "angular_speed", math.pi),
    (1.0, "rev/s", "angular_speed", 2 * math.pi),
    (2.5, "kN", "force", 2500.0),
    (2.5, "KN", "force", 2500.0),
    (3.0, "daN", "force", 30.0),
    (1.5, "kN*m", "torque", 1500.0),
    (1.5, "kNm", "torque", 1500.0),
    (7.0, "Nm", "torque", 7.0),
    (7.0, "N m", "torque", 7.0),
    (250.0, "ms", "time", 0.25),
    (2.0, "min", "time", 120.0),
    (5.0, None, "force", 5.0),
    (5.0, "", "force", 5.0),
])
def test_convert_units(value, unit, quantity, expected):
    out = convert_units(np.array([value, 2 * value]), unit, quantity)
    np.testing.assert_allclose(out, [expected, 2 * expected], rtol=1e-15)
    assert out.dtype == np.float64


def test_convert_units_scalar_and_no_mutation():
    x = np.array([1.0, 2.0])
    out = convert_units(x, "kN", "force")
    assert out is not x and x.tolist() == [1.0, 2.0]
    assert convert_units(3.6, "km/h", "angular_speed", radius_m=0.5) == pytest.approx(2.0)


def test_convert_units_datetime_time():
    t = np.datetime64("2024-01-01T00:00:00") + np.arange(4) * np.timedelta64(500, "us")
    np.testing.assert_allclose(convert_units(t, None, "time"), [0, 5e-4, 1e-3, 1.5e-3])


def test_first_unit_of_each_quantity_is_the_method_unit():
    for channel, unit in CHANNEL_UNITS.items():
        assert next(iter(UNITS[QUANTITY[channel]])) == unit
        assert canonical_unit(unit) == (QUANTITY[channel], unit)


@pytest.mark.parametrize(("unit", "quantity", "pattern"), [
    ("N", "torque", r"unit 'N' is a force.*needs a torque.*N\*m, kN\*m"),
    ("furlong", "force", r"unknown unit 'furlong'.*use one of N, kN"),
    ("km/h", "angular_speed", r"'km/h' is a linear speed.*radius_m"),
    ("rpm", "force", r"'rpm' is an angular speed"),
])
def test_convert_units_rejects_wrong_units(unit, quantity, pattern):
    with pytest.raises(InputError, match=pattern):
        convert_units([1.0], unit, quantity, channel="x")


def test_convert_units_rejects_text():
    with pytest.raises(InputError, match="not numeric"):
        convert_units(np.array(["a", "b"]), None, "force")


# --- [channels] table errors ----------------------------------------------------------------

def test_default_map_is_the_csv_layout():
    cmap = resolve_channel_map({})
    assert cmap == default_channel_map() == resolve_channel_map(None)
    assert cmap.names() == list(CHANNELS)
    assert cmap.time.name == "time_s" and cmap.sample_rate_hz is None


@pytest.mark.parametrize(("table", "pattern"), [
    ({"torque": {"name": "T", "unit": "N"}}, r"channel 'torque_nm'.*unit 'N'.*N\*m"),
    ({"torq": "T"}, r"unknown key 'channels.torq'; did you mean 'torque'\?.*wheel_speed"),
    ({"torque": "T", "torque_nm": "U"}, r"maps 'torque_nm' twice"),
    ({"fx": "F", "fy": "F"}, r"'F' is mapped to both fx_n and fy_n"),
    ({"torque": {"name": "T", "units": "N*m"}},
     r"unknown key 'channels.torque.units'; did you mean 'unit'\?"),
    ({"fx": {"name": "F", "radius_m": 0.1}}, r"radius_m only applies to the speed"),
    ({"sample_rate_hz": -5.0}, r"sample_rate_hz.*positive"),
    ({"sample_rate_hz": 100.0, "time": "t"}, r"both a sample rate.*and a time channel"),
    ({"t0_s": 1.0}, r"'t0_s' in \[channels\] needs 'sample_rate_hz'"),
    ({"torque": 3}, r"must be a channel name or a table"),
])
def test_bad_channel_tables(table, pattern):
    with pytest.raises(InputError, match=pattern) as info:
        resolve_channel_map(table, "exp/experiment.toml")
    assert "exp/experiment.toml" in str(info.value)


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_missing_channel_names_file_channel_and_mapped_name(fmt, reference, tmp_path,
                                                            write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    del columns["fz_n"]  # forces are optional, but Fx without Fz is no force measurement
    kw = {"fs_hz": FS_HZ} if fmt == "mdf" else {}
    path = _write(write_columns, tmp_path, fmt, columns, **kw)
    with pytest.raises(InputError) as info:
        read_recording(path)
    text = str(info.value)
    assert path.name in text and "channel 'fz_n'" in text
    with pytest.raises(InputError, match=r"channel 'torque_nm'.*Drehmoment") as info:
        read_recording(path, channel_map={"torque": "Drehmoment"})
    assert path.name in str(info.value)


@pytest.mark.parametrize("fmt", ["csv", "hdf5", "tdms", "mdf", "parquet"])
def test_wrong_unit_for_a_channel_names_file_channel_and_unit(fmt, reference, tmp_path,
                                                              write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    kw = {"fs_hz": FS_HZ} if fmt == "mdf" else {}
    path = _write(write_columns, tmp_path, fmt, columns, **kw)
    with pytest.raises(InputError) as info:
        read_recording(path, channel_map={"torque": {"name": "torque_nm", "unit": "N"}})
    text = str(info.value)
    assert path.name in text and "torque_nm" in text and "'N'" in text and "N*m" in text


def test_csv_missing_column_message_unchanged(reference, tmp_path, write_columns):
    columns = {"time_s": _time(reference), **reference.channels}
    del columns["torque_nm"], columns["wheel_speed_rad_s"]
    path = _write(write_columns, tmp_path, "csv", columns)
    with pytest.raises(InputError, match=r"channel 'torque_nm': missing column\(s\) "
                                         r"torque_nm, wheel_speed_rad_s"):
        read_recording(path)
    del columns["fz_n"], columns["fx_n"]  # Fy alone is no force measurement
    columns["torque_nm"] = columns["wheel_speed_rad_s"] = columns["fy_n"]
    path = _write(write_columns, tmp_path, "csv", columns)
    with pytest.raises(InputError, match=r"channel 'fx_n'"):
        read_recording(path)


@pytest.mark.parametrize("fmt", ["csv", "mat5"])
def test_no_time_base_says_what_to_do(fmt, reference, tmp_path, write_columns):
    path = _write(write_columns, tmp_path, fmt, dict(reference.channels))
    with pytest.raises(InputError, match=r"time_s.*sample_rate_hz"):
        read_recording(path)


def test_tdms_bare_name_in_two_groups_is_ambiguous(reference, tmp_path, write_columns):
    columns = {f"A/{c}": v for c, v in reference.channels.items()}
    columns["B/torque_nm"] = reference.channels["torque_nm"]
    path = _write(write_columns, tmp_path, "tdms", columns, fs_hz=FS_HZ, t0_s=T0_S)
    with pytest.raises(InputError, match=r"'torque_nm' is in several groups \(A, B\)"):
        read_recording(path)
    _assert_same(read_recording(path, group="A"), reference)
    rec = read_recording(path, channel_map={"torque": "/'B'/'torque_nm'"})
    _assert_same(rec, reference)


def test_mdf_group_must_be_an_index(reference, tmp_path, write_columns):
    path = _write(write_columns, tmp_path, "mdf", dict(reference.channels), fs_hz=FS_HZ)
    with pytest.raises(InputError, match="channel-group index"):
        read_recording(path, group="Rig")


def test_mat_struct_group(reference, tmp_path, write_columns):
    columns = {f"run1.{c}": v for c, v in reference.channels.items()}
    columns["run1.time_s"] = _time(reference)
    for fmt in ("mat5", "mat73"):
        path = _write(write_columns, tmp_path, fmt, columns)
        _assert_same(read_recording(path, group="run1"), reference)
        with pytest.raises(InputError, match="no struct 'run2'"):
            read_recording(path, group="run2")


@pytest.mark.parametrize(("module", "suffix", "extra"),
                         [("nptdms", ".tdms", "tdms"), ("asammdf", ".mf4", "mdf")])
def test_optional_package_missing(module, suffix, extra, tmp_path, monkeypatch):
    path = tmp_path / f"x{suffix}"
    path.write_bytes(b"\0" * 64)
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` fail
    with pytest.raises(InputError, match=rf"install torquemod\[{extra}\]"):
        read_recording(path)


# --- the manifest ---------------------------------------------------------------------------

RIG = {"wheel_radius_m": 0.0675, "platform_radius_m": 2.0}
TEST = {"normal_load_n": 4200.0, "modulation_frequency_hz": 2.0,
        "modulation_amplitude_nm": 8.0}


def test_manifest_channels_and_per_recording_rate(reference, tmp_path, write_columns):
    write_columns("tdms", tmp_path / "a.tdms", _renamed_columns(reference, "Rig/"),
                  fs_hz=1000.0)
    write_columns("csv", tmp_path / "b.csv", _renamed_columns(reference))
    channels = {SHORT[c]: {"name": RENAMED[c][0], "unit": RENAMED[c][1]} for c in CHANNELS}
    channels["time"] = {"name": "Time", "unit": "ms"}
    manifest = write_manifest(
        tmp_path / "experiment.toml", rig=RIG, test=TEST, extra={"channels": channels},
        recordings=[{"step": 1, "dc_torque_nm": 0.2, "file": "b.csv"}])
    exp = read_experiment(manifest)
    _assert_same(read_entry(exp, exp.recordings[0]), reference)

    del channels["time"]
    manifest = write_manifest(
        tmp_path / "experiment.toml", rig=RIG, test=TEST, extra={"channels": channels},
        recordings=[{"step": 1, "dc_torque_nm": 0.2, "file": "a.tdms", "group": "Rig",
                     "sample_rate_hz": FS_HZ}])
    exp = read_experiment(manifest)
    assert exp.recordings[0].sample_rate_hz == FS_HZ
    rec = read_entry(exp, exp.recordings[0])
    assert rec.fs_hz == FS_HZ and rec.t0_s == 0.0


@pytest.mark.parametrize(("channels", "rec_extra", "pattern"), [
    ({"torque": {"name": "T", "unit": "N"}}, {}, r"experiment.toml: channel 'torque_nm'"),
    ({}, {"sample_rate_hz": 0}, r"'sample_rate_hz' must be a positive number"),
    ({"time": "t"}, {"sample_rate_hz": 100.0}, r"both a sample rate"),
])
def test_manifest_rejects_bad_channels(channels, rec_extra, pattern, tmp_path):
    (tmp_path / "a.csv").write_text("x\n")
    manifest = write_manifest(
        tmp_path / "experiment.toml", rig=RIG, test=TEST,
        extra={"channels": channels} if channels else None,
        recordings=[{"step": 1, "dc_torque_nm": 0.2, "file": "a.csv", **rec_extra}])
    with pytest.raises(ManifestError, match=pattern):
        read_experiment(manifest)


# --- convert --------------------------------------------------------------------------------

@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_convert_file_to_hdf5(fmt, reference, tmp_path, write_columns):
    kw = {"fs_hz": FS_HZ, "t0_s": T0_S} if fmt == "mdf" else {}
    src = _write(write_columns, tmp_path, fmt, _renamed_columns(reference), **kw)
    table = {SHORT[c]: {"name": RENAMED[c][0], "unit": RENAMED[c][1]} for c in CHANNELS}
    table["time"] = {"name": "Time", "unit": "ms"}
    out = convert_file(src, tmp_path / "out" / "rec.h5", channel_map=table)
    assert out == tmp_path / "out" / "rec.h5"
    assert sorted(p.name for p in out.parent.iterdir()) == ["rec.h5"]  # no temp files left
    _assert_same(read_recording(out), reference)


def test_convert_file_rejects_an_output_format_it_cannot_write(reference, tmp_path,
                                                               write_columns):
    src = _write(write_columns, tmp_path, "csv", {"time_s": _time(reference),
                                                  **reference.channels})
    with pytest.raises(InputError, match=r"output must be \.h5, .*\.parquet, \.mat, \.csv"):
        convert_file(src, tmp_path / "out.tdms")
    assert not (tmp_path / "out.tdms").exists()


def test_convert_experiment(reference, tmp_path, write_columns):
    src = tmp_path / "exp"
    src.mkdir()
    write_columns("tdms", src / "s1.tdms", _renamed_columns(reference), fs_hz=FS_HZ)
    write_columns("csv", src / "s2.csv", _renamed_columns(reference))
    channels = {SHORT[c]: {"name": RENAMED[c][0], "unit": RENAMED[c][1]} for c in CHANNELS}
    channels["time"] = {"name": "Time", "unit": "ms"}
    write_manifest(src / "experiment.toml", rig=RIG, test={**TEST, "operator": "A. B."},
                   extra={"channels": channels},
                   recordings=[{"step": 1, "cycle": 1, "dc_torque_nm": 0.2, "file": "s1.tdms",
                                "note": "first"},
                               {"step": 2, "dc_torque_nm": 0.4, "file": "s2.csv"}])
    out = tmp_path / "converted"
    manifest = convert_experiment(src / "experiment.toml", out)
    assert manifest == out.absolute() / "experiment.toml"
    assert sorted(p.name for p in out.iterdir()) == [".torquemod-results", "experiment.toml",
                                                 "s1.h5", "s2.h5"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    old, new = read_experiment(src), read_experiment(manifest)
    assert new.rig == old.rig and new.test == old.test and new.channel_map == {}
    assert [(r.step, r.cycle, r.dc_torque_nm) for r in new.recordings] == \
        [(r.step, r.cycle, r.dc_torque_nm) for r in old.recordings]
    assert "note = \"first\"" in manifest.read_text()
    _assert_same(read_entry(new, new.recordings[0]), reference)
    _assert_same(read_entry(new, new.recordings[1]), reference)

    with pytest.raises(OutputError, match="already exists"):
        convert_experiment(src / "experiment.toml", out)
    with pytest.raises(InputError, match="holds the experiment"):
        convert_experiment(src / "experiment.toml", src, force=True)


def test_convert_experiment_failure_leaves_nothing(reference, tmp_path, write_columns):
    src = tmp_path / "exp"
    src.mkdir()
    write_columns("csv", src / "ok.csv", {"time_s": _time(reference), **reference.channels})
    write_columns("csv", src / "bad.csv", dict(reference.channels))  # no time column
    write_manifest(src / "experiment.toml", rig=RIG, test=TEST,
                   recordings=[{"step": 1, "dc_torque_nm": 0.2, "file": "ok.csv"},
                               {"step": 2, "dc_torque_nm": 0.4, "file": "bad.csv"}])
    with pytest.raises(InputError, match=r"bad\.csv"):
        convert_experiment(src / "experiment.toml", tmp_path / "converted")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp"]


@pytest.mark.parametrize("fmt", ALL_FORMATS)
@pytest.mark.parametrize("absent", [("fy_n",), ("fx_n", "fy_n", "fz_n"),
                                    ("platform_speed_rad_s", "fx_n", "fy_n", "fz_n")])
def test_optional_channels_may_be_absent(fmt, absent, reference, tmp_path, write_columns):
    """Issue 8: the forces (all, or Fy alone) and the platform speed are optional; mapping an
    absent optional channel explicitly is still an error."""
    columns = {"time_s": _time(reference), **{k: v for k, v in reference.channels.items()
                                              if k not in absent}}
    kw = {"fs_hz": FS_HZ} if fmt == "mdf" else {}
    path = _write(write_columns, tmp_path, fmt, columns, **kw)
    rec = read_recording(path)
    assert set(rec.channels) == set(reference.channels) - set(absent)
    for k, v in rec.channels.items():
        np.testing.assert_allclose(v, reference.channels[k], rtol=1e-12)
    if absent == ("fy_n",):
        assert any("|Fx|/Fz" in n for n in rec.notes)
    with pytest.raises(InputError, match=absent[-1]):
        read_recording(path, channel_map={absent[-1].rsplit("_", 1)[0]
                                          .replace("_speed", "_speed"): absent[-1]})
