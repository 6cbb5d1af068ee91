"""Bad input and faults, end to end through the command line (issue 5).

Every case corrupts a small, valid synthetic experiment in one way and runs
``torquemod process``. Each must end with exit code 2, one line on stderr that names what is
wrong (the file, channel or key) and what to do, no traceback, and no results folder (nor a
leftover temporary folder beside it). A few cases run as a subprocess to prove that no
traceback reaches the terminal.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import tomli_w

from torquemod.cli import main
from torquemod.io import write_recording
from torquemod.testing import SyntheticSpec, synthetic_recording, write_synthetic_experiment

FS_HZ = 2000.0  # low rate: the chain only needs > 53 Hz, and the files stay small
BASE = SyntheticSpec(fs_hz=FS_HZ)


# --------------------------------------------------------------------------- helpers

def _manifest(d: Path) -> dict:
    return tomllib.loads((d / "experiment.toml").read_text(encoding="utf-8"))


def _write_manifest(d: Path, doc: dict) -> None:
    (d / "experiment.toml").write_text(tomli_w.dumps(doc), encoding="utf-8")


def _edit_manifest(d: Path, fn: Callable[[dict], None]) -> None:
    doc = _manifest(d)
    fn(doc)
    _write_manifest(d, doc)


def _edit_csv(path: Path, fn: Callable[[pd.DataFrame], pd.DataFrame | None]) -> None:
    df = pd.read_csv(path)
    out = fn(df)
    (df if out is None else out).to_csv(path, index=False, float_format="%.12g")


def _set(column: str, row: int | slice, value) -> Callable[[pd.DataFrame], None]:
    def fn(df: pd.DataFrame) -> None:
        df.loc[row, column] = value
    return fn


def _first_file(d: Path) -> Path:
    return d / "step1_cycle1.csv"


def _spanning_h5(d: Path, *, n_revolutions: float = 2.0, **changes) -> Path:
    """Replace the manifest by one step of one HDF5 file spanning revolutions (no cycle)."""
    spec = SyntheticSpec(**{**BASE.__dict__, "n_revolutions": n_revolutions, **changes})
    write_recording(d / "span.h5", synthetic_recording(spec), fmt="hdf5")
    _edit_manifest(d, lambda doc: doc.__setitem__(
        "recording", [{"step": 1, "dc_torque_nm": 0.23, "file": "span.h5"}]))
    return d / "span.h5"


def _replace_cycle_file(d: Path, **changes) -> Path:
    spec = SyntheticSpec(**{**BASE.__dict__, **changes})
    write_recording(_first_file(d), synthetic_recording(spec), fmt="csv")
    return _first_file(d)


# --------------------------------------------------------------------------- cases
# Each builder corrupts the experiment folder ``d`` and returns the extra CLI arguments and,
# optionally, the experiment path to give instead of the folder.

def c_manifest_missing(d):
    (d / "experiment.toml").unlink()
    return [], None


def c_manifest_empty(d):
    (d / "experiment.toml").write_text("", encoding="utf-8")
    return [], None


def c_manifest_binary(d):
    (d / "experiment.toml").write_bytes(b"\xff\xfe\x00garbage\x81")
    return [], None


def c_toml_syntax(d):
    text = (d / "experiment.toml").read_text(encoding="utf-8")
    (d / "experiment.toml").write_text(text.replace("wheel_radius_m = 0.0675",
                                                    "wheel_radius_m = = 0.0675"))
    return [], None


def c_toml_duplicate_key(d):
    text = (d / "experiment.toml").read_text(encoding="utf-8")
    (d / "experiment.toml").write_text(text.replace(
        "wheel_radius_m = 0.0675", "wheel_radius_m = 0.0675\nwheel_radius_m = 0.07"))
    return [], None


def c_missing_section(d):
    _edit_manifest(d, lambda doc: doc.pop("rig"))
    return [], None


def c_negative_radius(d):
    _edit_manifest(d, lambda doc: doc["rig"].__setitem__("wheel_radius_m", -0.0675))
    return [], None


def c_zero_normal_load(d):
    _edit_manifest(d, lambda doc: doc["test"].__setitem__("normal_load_n", 0.0))
    return [], None


def c_empty_experiment(d):
    _edit_manifest(d, lambda doc: doc.pop("recording"))
    return [], None


def c_step_not_integer(d):
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("step", "1"))
    return [], None


def c_duplicate_step_cycle(d):
    def fn(doc):
        doc["recording"][1]["cycle"] = doc["recording"][0]["cycle"]
    _edit_manifest(d, fn)
    return [], None


def c_same_file_twice(d):
    def fn(doc):
        doc["recording"][1]["file"] = doc["recording"][0]["file"]
    _edit_manifest(d, fn)
    return [], None


def c_cycle_overlap(d):
    # step 1 given as a file spanning two revolutions *and* as single-cycle files
    spec = SyntheticSpec(**{**BASE.__dict__, "n_revolutions": 2.0})
    write_recording(d / "span.h5", synthetic_recording(spec), fmt="hdf5")
    _edit_manifest(d, lambda doc: doc["recording"].append(
        {"step": 1, "dc_torque_nm": 0.23, "file": "span.h5"}))
    return [], None


def c_step_dc_differs(d):
    _edit_manifest(d, lambda doc: doc["recording"][1].__setitem__("dc_torque_nm", 5.0))
    return [], None


def c_file_outside(d):
    shutil.copy(_first_file(d), d.parent / "outside.csv")
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("file", "../outside.csv"))
    return [], None


def c_file_absolute_outside(d):
    shutil.copy(_first_file(d), d.parent / "outside.csv")
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__(
        "file", str(d.parent / "outside.csv")))
    return [], None


def c_symlink_outside(d):
    shutil.copy(_first_file(d), d.parent / "outside.csv")
    os.symlink(d.parent / "outside.csv", d / "link.csv")
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("file", "link.csv"))
    return [], None


def c_file_missing(d):
    _first_file(d).unlink()
    return [], None


def c_file_is_directory(d):
    (d / "adir.csv").mkdir()
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("file", "adir.csv"))
    return [], None


def c_unknown_suffix(d):
    shutil.copy(_first_file(d), d / "rec.xyz")
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("file", "rec.xyz"))
    return [], None


def c_missing_column(d):
    _edit_csv(_first_file(d), lambda df: df.drop(columns=["wheel_speed_rad_s"]))
    return [], None


def c_fx_without_fz(d):
    _edit_csv(_first_file(d), lambda df: df.drop(columns=["fz_n"]))
    return [], None


def c_optional_mapped_absent(d):
    """An optional channel is only optional until the manifest asks for it."""
    _edit_manifest(d, lambda doc: doc.__setitem__("channels",
                                                  {"platform_speed": "PlatformSpeed"}))
    return [], None


def c_tdms_channel_late(d):
    """A logger's force module started 40 % into the torque's recording (wf_start_offset)."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter
    df = pd.read_csv(_first_file(d))
    t = df["time_s"].to_numpy()
    objs = [GroupObject("Meas")]
    for name in df.columns.drop("time_s"):
        late = 0.4 * (t[-1] - t[0]) if name == "fx_n" else 0.0
        objs.append(ChannelObject("Meas", name, df[name].to_numpy(), properties={
            "wf_increment": 1.0 / FS_HZ, "wf_start_offset": float(t[0]) + late}))
    with TdmsWriter(str(d / "rec.tdms")) as w:
        w.write_segment(objs)
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("file", "rec.tdms"))
    return [], None


def c_wrong_unit(d):
    _edit_manifest(d, lambda doc: doc.__setitem__(
        "channels", {"torque": {"name": "torque_nm", "unit": "N"}}))
    return [], None


def c_unknown_unit(d):
    _edit_manifest(d, lambda doc: doc.__setitem__(
        "channels", {"fz": {"name": "fz_n", "unit": "furlong"}}))
    return [], None


def c_unknown_processing_key(d):
    _edit_manifest(d, lambda doc: doc.__setitem__("processing", {"bandpas": {"width_hz": 1}}))
    return [], None


def c_nan(d):
    _edit_csv(_first_file(d), _set("torque_nm", 500, np.nan))
    return [], None


def c_inf(d):
    _edit_csv(_first_file(d), _set("fz_n", 700, np.inf))
    return [], None


def c_nan_time(d):
    _edit_csv(_first_file(d), _set("time_s", 300, np.nan))
    return [], None


def c_time_not_increasing(d):
    def fn(df):
        df.loc[[400, 401], "time_s"] = df.loc[[401, 400], "time_s"].to_numpy()
    _edit_csv(_first_file(d), fn)
    return [], None


def c_time_gap(d):
    _edit_csv(_first_file(d), lambda df: df.drop(index=range(1000, 1200)))
    return [], None


def c_too_short(d):
    _edit_csv(_first_file(d), lambda df: df.iloc[:4000])  # 2 s: fewer than 5 periods
    return [], None


def c_span_shorter_than_revolution(d):
    _spanning_h5(d, n_revolutions=0.8)
    return [], None


def c_one_row(d):
    _edit_csv(_first_file(d), lambda df: df.iloc[:1])
    return [], None


def c_no_modulation(d):
    _replace_cycle_file(d, modulation_amplitude_nm=0.0, wheel_mod_amplitude_rad_s=0.0)
    return [], None


def c_sample_rate_too_low(d):
    _replace_cycle_file(d, fs_hz=40.0, vibration_hz=(15.5,))
    return [], None


def c_empty_csv(d):
    _first_file(d).write_bytes(b"")
    return [], None


def c_header_only(d):
    text = _first_file(d).read_text(encoding="utf-8")
    _first_file(d).write_text(text.splitlines()[0] + "\n", encoding="utf-8")
    return [], None


def c_semicolon_delimiter(d):
    text = _first_file(d).read_text(encoding="utf-8")
    _first_file(d).write_text(text.replace(",", ";"), encoding="utf-8")
    return [], None


def c_text_in_numeric(d):
    _edit_csv(_first_file(d), lambda df: df.astype({"fx_n": object}).assign(
        fx_n=lambda x: x["fx_n"].where(x.index != 50, "abc")))
    return [], None


def c_truncated_line(d):
    with open(_first_file(d), "a", encoding="utf-8") as fh:
        fh.write("99.0,1.0,2.0\n")
    return [], None


def c_hdf5_mismatched_lengths(d):
    path = _spanning_h5(d)
    with h5py.File(path, "a") as fh:
        data = fh["fz_n"][()][:-100]
        del fh["fz_n"]
        fh.create_dataset("fz_n", data=data)
    return [], None


def c_hdf5_garbage(d):
    (d / "span.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + os.urandom(2000))
    _edit_manifest(d, lambda doc: doc.__setitem__(
        "recording", [{"step": 1, "dc_torque_nm": 0.23, "file": "span.h5"}]))
    return [], None


def c_hdf5_missing_group(d):
    _spanning_h5(d)
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("group", "nope"))
    return [], None


def c_zero_normal_force(d):
    _edit_csv(_first_file(d), _set("fz_n", slice(None), 0.0))
    return [], None


def c_negative_normal_force(d):
    _edit_csv(_first_file(d), lambda df: df.assign(fz_n=-df["fz_n"]))
    return [], None


def c_platform_speed_zero(d):
    _edit_csv(_first_file(d), _set("platform_speed_rad_s", slice(None), 0.0))
    return [], None


def c_platform_standing_noisy(d):
    rng = np.random.default_rng(1)
    _edit_csv(_first_file(d), lambda df: df.assign(
        platform_speed_rad_s=1e-3 * rng.standard_normal(len(df))))
    return [], None


def c_wheel_backwards(d):
    _edit_csv(_first_file(d), lambda df: df.assign(wheel_speed_rad_s=-df["wheel_speed_rad_s"]))
    return [], None


def c_all_nan_channel_interpolate(d):
    _edit_csv(_first_file(d), _set("fy_n", slice(None), np.nan))
    return ["--nan-policy", "interpolate"], None


def c_drop_cycle_empties_step(d):
    for cyc in (1, 2):
        _edit_csv(d / f"step1_cycle{cyc}.csv", _set("torque_nm", 100, np.nan))
    return ["--nan-policy", "drop-cycle"], None


def c_drop_cycle_empties_all(d):
    for path in sorted(d.glob("*.csv")):
        _edit_csv(path, _set("wheel_speed_rad_s", 100, np.nan))
    return ["--nan-policy", "drop-cycle"], None


def c_negative_sample_rate(d):
    _edit_manifest(d, lambda doc: doc["recording"][0].__setitem__("sample_rate_hz", -2000.0))
    return [], None


def c_permission_denied(d):
    """Unreadable recording: chmod 000 (root reads anyway, so the open is refused by a
    patched ``os.open``-level check in the in-process runner below)."""
    _first_file(d).chmod(0)
    return [], None


# (id, builder, substrings the message must contain)
CASES: list[tuple[str, Callable, tuple[str, ...]]] = [
    ("manifest_missing", c_manifest_missing, ("experiment.toml", "manifest not found")),
    ("manifest_empty", c_manifest_empty, ("experiment.toml", "missing section [rig]")),
    ("manifest_binary", c_manifest_binary, ("experiment.toml", "cannot read the manifest")),
    ("toml_syntax", c_toml_syntax, ("experiment.toml", "TOML syntax error", "line ")),
    ("toml_duplicate_key", c_toml_duplicate_key, ("experiment.toml", "line ", "twice")),
    ("missing_section", c_missing_section, ("missing section [rig]",)),
    ("negative_radius", c_negative_radius, ("rig.wheel_radius_m", "positive")),
    ("zero_normal_load", c_zero_normal_load, ("test.normal_load_n", "positive")),
    ("empty_experiment", c_empty_experiment, ("experiment.toml", "no [[recording]]")),
    ("step_not_integer", c_step_not_integer, ("recording #1", "'step'", "whole number")),
    ("duplicate_step_cycle", c_duplicate_step_cycle, ("step 1 cycle 1", "listed twice")),
    ("same_file_twice", c_same_file_twice, ("step1_cycle1.csv", "listed twice")),
    ("cycle_overlap", c_cycle_overlap, ("step 1", "more than once")),
    ("step_dc_differs", c_step_dc_differs, ("step 1", "dc_torque_nm")),
    ("file_outside", c_file_outside, ("outside.csv", "outside the experiment folder")),
    ("file_absolute_outside", c_file_absolute_outside, ("outside the experiment folder",)),
    ("symlink_outside", c_symlink_outside, ("link.csv", "outside the experiment folder")),
    ("file_missing", c_file_missing, ("step1_cycle1.csv", "not found", "'file'")),
    ("file_is_directory", c_file_is_directory, ("adir.csv", "folder")),
    ("unknown_suffix", c_unknown_suffix, ("rec.xyz", "unknown recording format")),
    ("missing_column", c_missing_column, ("step1_cycle1.csv", "wheel_speed_rad_s",
                                          "missing column")),
    ("fx_without_fz", c_fx_without_fz, ("step1_cycle1.csv", "channel 'fz_n'",
                                        "Fx and Fz")),
    ("optional_mapped_absent", c_optional_mapped_absent,
     ("step1_cycle1.csv", "channel 'platform_speed_rad_s'", "PlatformSpeed")),
    ("tdms_channel_late", c_tdms_channel_late,
     ("rec.tdms", "channel 'fx_n'", "starts", "at least 90 %", "export all channels")),
    ("wrong_unit", c_wrong_unit, ("channel 'torque_nm'", "unit 'N'", "torque")),
    ("unknown_unit", c_unknown_unit, ("'furlong'",)),
    ("unknown_processing_key", c_unknown_processing_key, ("bandpas", "did you mean 'bandpass'")),
    ("nan", c_nan, ("step1_cycle1.csv", "channel 'torque_nm'", "NaN/inf", "--nan-policy")),
    ("inf", c_inf, ("step1_cycle1.csv", "channel 'fz_n'", "NaN/inf", "--nan-policy")),
    ("nan_time", c_nan_time, ("step1_cycle1.csv", "channel 'time_s'", "non-finite")),
    ("time_not_increasing", c_time_not_increasing,
     ("step1_cycle1.csv", "channel 'time_s'", "not strictly increasing")),
    ("time_gap", c_time_gap, ("step1_cycle1.csv", "channel 'time_s'", "not uniformly")),
    ("too_short", c_too_short, ("step1_cycle1.csv", "too short", "longer")),
    ("span_shorter_than_revolution", c_span_shorter_than_revolution,
     ("span.h5", "less than one platform revolution")),
    ("one_row", c_one_row, ("step1_cycle1.csv", "fewer than two")),
    ("no_modulation", c_no_modulation, ("step1_cycle1.csv", "no modulation found")),
    ("sample_rate_too_low", c_sample_rate_too_low, ("step1_cycle1.csv", "sample rate 40",
                                                    "resampling rate")),
    ("empty_csv", c_empty_csv, ("step1_cycle1.csv", "empty file")),
    ("header_only", c_header_only, ("step1_cycle1.csv", "fewer than two data rows")),
    ("semicolon_delimiter", c_semicolon_delimiter, ("step1_cycle1.csv", "';'", "comma")),
    ("text_in_numeric", c_text_in_numeric, ("step1_cycle1.csv", "fx_n", "non-numeric")),
    ("truncated_line", c_truncated_line, ("step1_cycle1.csv", "cannot parse as CSV")),
    ("hdf5_mismatched_lengths", c_hdf5_mismatched_lengths, ("span.h5", "fz_n", "samples")),
    ("hdf5_garbage", c_hdf5_garbage, ("span.h5", "HDF5")),
    ("hdf5_missing_group", c_hdf5_missing_group, ("span.h5", "nope")),
    ("zero_normal_force", c_zero_normal_force, ("step1_cycle1.csv", "fz_n", "normal force")),
    ("negative_normal_force", c_negative_normal_force,
     ("step1_cycle1.csv", "fz_n", "normal force")),
    ("platform_speed_zero", c_platform_speed_zero,
     ("step1_cycle1.csv", "platform_speed_rad_s", "not turning")),
    ("platform_standing_noisy", c_platform_standing_noisy,
     ("step1_cycle1.csv", "platform_speed_rad_s", "not turning")),
    ("wheel_backwards", c_wheel_backwards, ("step1_cycle1.csv", "opposite")),
    ("all_nan_channel_interpolate", c_all_nan_channel_interpolate,
     ("step1_cycle1.csv", "fy_n", "no finite value")),
    ("drop_cycle_empties_step", c_drop_cycle_empties_step,
     ("step 1", "no cycle left", "drop-cycle")),
    ("drop_cycle_empties_all", c_drop_cycle_empties_all, ("no cycle could be processed",)),
    ("negative_sample_rate", c_negative_sample_rate, ("recording #1", "sample_rate_hz")),
    ("permission_denied", c_permission_denied, ("step1_cycle1.csv", "ermission denied")),
]

#: Cases also run as a subprocess (to prove no traceback and the real exit code).
SUBPROCESS_CASES = ("toml_syntax", "file_outside", "nan", "missing_column", "hdf5_garbage",
                    "drop_cycle_empties_step", "empty_experiment", "time_not_increasing")


@pytest.fixture(scope="session")
def base_experiment(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("base") / "exp"
    write_synthetic_experiment(folder, n_steps=4, n_cycles=2, fmt="csv", seed=3, base=BASE)
    return folder


def _prepare(base: Path, tmp_path: Path, build: Callable) -> tuple[list[str], Path]:
    d = tmp_path / "exp"
    shutil.copytree(base, d)
    extra, target = build(d)
    return extra, target or d


def _assert_no_output(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]


def _assert_one_line(err: str, expected: tuple[str, ...]) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("torquemod: error: "), line
    assert "Traceback" not in err
    for s in expected:
        assert s in line, f"{s!r} not in {line!r}"


@pytest.fixture
def deny_unreadable(monkeypatch):
    """Make ``open`` refuse files without read permission even for root."""
    import builtins
    real_open = builtins.open

    def guarded(file, *args, **kwargs):
        if isinstance(file, str | os.PathLike) and os.path.isfile(file) \
                and not os.stat(file).st_mode & 0o444:
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)
    monkeypatch.setattr(builtins, "open", guarded)


@pytest.mark.parametrize("build,expected", [pytest.param(b, e, id=i) for i, b, e in CASES])
def test_bad_input_exits_2_with_one_line(base_experiment, tmp_path, capsys, build, expected,
                                         request):
    if build is c_permission_denied:
        request.getfixturevalue("deny_unreadable")
    extra, target = _prepare(base_experiment, tmp_path, build)
    rc = main(["process", str(target), "--out", str(tmp_path / "out"), "--quiet", *extra])
    cap = capsys.readouterr()
    assert rc == 2, cap.err
    _assert_one_line(cap.err, expected)
    _assert_no_output(tmp_path)


@pytest.mark.parametrize("case", SUBPROCESS_CASES)
def test_bad_input_subprocess_has_no_traceback(base_experiment, tmp_path, case):
    _, build, expected = next(c for c in CASES if c[0] == case)
    extra, target = _prepare(base_experiment, tmp_path, build)
    proc = subprocess.run([sys.executable, "-m", "torquemod.cli", "process", str(target),
                           "--out", str(tmp_path / "out"), "--quiet", *extra],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    _assert_one_line(proc.stderr, expected)
    assert "Traceback" not in proc.stdout
    _assert_no_output(tmp_path)


def test_existing_results_folder_is_kept_without_force(base_experiment, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("old", encoding="utf-8")
    rc = main(["process", str(base_experiment), "--out", str(out), "--quiet", "--no-fit"])
    cap = capsys.readouterr()
    assert rc == 2
    _assert_one_line(cap.err, ("already exists", "--force"))
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_failure_with_force_leaves_old_results_whole(base_experiment, tmp_path, capsys):
    """A run that fails after --force was given must not touch the existing folder."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("old", encoding="utf-8")
    extra, target = _prepare(base_experiment, tmp_path, c_nan)
    rc = main(["process", str(target), "--out", str(out), "--quiet", "--force", *extra])
    assert rc == 2
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp", "out"]
    capsys.readouterr()


def test_too_few_steps_for_the_fit_never_sink_the_experiment(base_experiment, tmp_path,
                                                              capsys):
    """Two steps are too few for the Polach fit (issue 8): the processed results are written,
    the fit is skipped with one warning line on stderr, and the report says why."""
    d = tmp_path / "exp"
    shutil.copytree(base_experiment, d)
    _edit_manifest(d, lambda doc: doc.__setitem__(
        "recording", [r for r in doc["recording"] if r["step"] <= 2]))
    out = tmp_path / "out"
    rc = main(["process", str(d), "--out", str(out), "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0
    skipped = [line for line in cap.err.splitlines() if "Polach fit skipped" in line]
    assert len(skipped) == 1 and "at least 4 points" in skipped[0]
    for name in ("steps.csv", "cycles.csv", "fit.json", "provenance.json", "report.html"):
        assert (out / name).is_file()
    doc = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    assert doc["mu"] is None and "at least 4 points" in doc["fit_skipped"]
    assert "no force fit" in (out / "report.html").read_text(encoding="utf-8")
    assert main(["report", str(out)]) == 0
    capsys.readouterr()


def test_valid_base_experiment_processes(base_experiment, tmp_path, capsys):
    """The experiment every case corrupts is itself fine (fit and report included)."""
    rc = main(["process", str(base_experiment), "--out", str(tmp_path / "out"), "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert (tmp_path / "out" / "fit.json").is_file()


def test_force_replaces_whole_folder(base_experiment, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "stale.txt").write_text("old", encoding="utf-8")
    (out / ".torquemod-results").write_text('{"format": "torquemod-output"}')  # torquemod's
    rc = main(["process", str(base_experiment), "--out", str(out), "--quiet", "--no-fit",
               "--force"])
    capsys.readouterr()
    assert rc == 0
    assert not (out / "stale.txt").exists()
    assert (out / "steps.csv").is_file()
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


@pytest.mark.parametrize("policy", ["interpolate", "drop-cycle"])
def test_nan_policy_is_recorded_in_provenance(base_experiment, tmp_path, capsys, policy):
    import json
    _, target = _prepare(base_experiment, tmp_path, c_nan)
    out = tmp_path / "out"
    rc = main(["process", str(target), "--out", str(out), "--quiet", "--no-fit",
               "--nan-policy", policy])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    prov = json.loads((out / "provenance.json").read_text(encoding="utf-8"))
    assert prov["parameters"]["nan_policy"] == policy
    assert prov["nan_actions"] and "step1_cycle1.csv" in prov["nan_actions"][0]
    steps = pd.read_csv(out / "steps.csv")
    expect = 2 if policy == "interpolate" else 1
    assert steps.loc[steps.step == 1, "n_cycles"].item() == expect


# --------------------------------------------------------------------------- slip

def test_detect_slip_rules():
    from torquemod.io.config import SlipParams
    from torquemod.processing.pipeline import detect_slip
    p = SlipParams()
    steady = detect_slip([3.0e-3, 3.1e-3, 2.9e-3], [0.15, 0.151, 0.149], [0.0, 1e-4, -1e-4], p)
    assert steady == [None, None, None]
    jump = detect_slip([3.0e-3, 3.1e-3, 9.0e-3], [0.15, 0.15, 0.15], [0, 0, 0], p)
    assert jump[:2] == [None, None] and "above the median" in jump[2]
    # a jump within the scatter of a noisy step is not slip
    noisy = [3e-3, 5.5e-3, 2e-3, 4.5e-3, 6.6e-3]
    assert detect_slip(noisy, [0.15] * 5, [0] * 5, p) == [None] * 5
    coa = detect_slip([3.0e-3, 4.0e-3], [0.15, 0.13], [0, 0], p)
    assert coa[0] is None and "CoA fell by 0.02" in coa[1]
    drift = detect_slip([3e-3], [0.15], [5e-3], p)
    assert "within the cycle" in drift[0]
    off = detect_slip([3.0e-3, 3.1e-3, 9.0e-3], [0.15, 0.15, 0.1], [0, 0, 1], SlipParams(
        enabled=False))
    assert off == [None, None, None]


@pytest.fixture(scope="module")
def slip_experiment(tmp_path_factory) -> Path:
    """Six steps of two cycles; step 4 cycle 2 slips (creepage 2 %, CoA down by 0.03);
    step 2 cycle 1 has a creepage running away within the cycle."""
    d = tmp_path_factory.mktemp("slip") / "exp"
    write_synthetic_experiment(d, n_steps=6, n_cycles=2, fmt="csv", seed=4, base=BASE)
    spec = SyntheticSpec(**{**BASE.__dict__, "creepage": 0.02, "dc_torque_nm": 50.0,
                            "modulation_hz": 2.001, "phase_lag_deg": 30.0, "seed": 77})
    write_recording(d / "step4_cycle2.csv", synthetic_recording(spec))
    spec = SyntheticSpec(**{**BASE.__dict__, "creepage": 3e-3, "dc_torque_nm": 22.84,
                            "modulation_hz": 2.001, "phase_lag_deg": 14.0, "seed": 78})
    rec = synthetic_recording(spec)
    ramp = np.linspace(0.0, 0.006, rec.n_samples)  # creepage +0.6 % over the cycle
    rec.channels["wheel_speed_rad_s"] = rec.channels["wheel_speed_rad_s"] * (1 + ramp)
    write_recording(d / "step2_cycle1.csv", rec)
    return d


def test_slip_is_flagged_per_step_and_left_out_of_the_fit(slip_experiment, tmp_path, capsys):
    import json

    from torquemod.analysis.analyzer import ADDED_STEP_COLUMNS
    from torquemod.processing.pipeline import STEP_COLUMNS
    out = tmp_path / "out"
    rc = main(["process", str(slip_experiment), "--out", str(out), "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    steps = pd.read_csv(out / "steps.csv")
    assert list(steps.columns) == STEP_COLUMNS + list(ADDED_STEP_COLUMNS)
    assert "slip" in STEP_COLUMNS
    assert steps.set_index("step")["slip"].to_dict() == {1: False, 2: True, 3: False, 4: True,
                                                         5: False, 6: False}
    assert "step 4: slip detected in cycle 2" in cap.err
    assert "step 2: slip detected in cycle 1" in cap.err and "within the cycle" in cap.err
    prov = json.loads((out / "provenance.json").read_text(encoding="utf-8"))
    assert prov["parameters"]["slip"]["creepage_jump_abs"] == 2e-3
    assert any("step 4: slip detected" in w for w in prov["warnings"])
    slip_of = {(c["step"], c["cycle"]): c["slip"] for c in prov["cycles"]}
    assert slip_of[4, 2] and slip_of[2, 1] and not slip_of[4, 1] and not slip_of[1, 1]
    fit = json.loads((out / "fit.json").read_text(encoding="utf-8"))
    assert any("[2, 4]" in w and "left out of the Polach fit" in w for w in fit["warnings"])
    assert [s["slip"] for s in fit["steps"]] == [False, True, False, True, False, False]


def test_slip_detection_can_be_switched_off(slip_experiment, tmp_path, capsys):
    d = tmp_path / "exp"
    shutil.copytree(slip_experiment, d)
    _edit_manifest(d, lambda doc: doc.__setitem__("processing", {"slip": {"enabled": False}}))
    rc = main(["process", str(d), "--out", str(tmp_path / "out"), "--quiet", "--no-fit"])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert not pd.read_csv(tmp_path / "out" / "steps.csv")["slip"].any()
    assert "slip" not in cap.err


def test_convert_without_input_is_a_usage_error(tmp_path, capsys):
    rc = main(["convert", "--out", str(tmp_path / "x.h5")])
    cap = capsys.readouterr()
    assert rc == 2
    assert cap.err.strip().splitlines() == [
        "torquemod: error: convert needs an INPUT recording or --manifest EXPERIMENT.toml"]
    assert not (tmp_path / "x.h5").exists()
