"""`torquemod onboard` under a bad [onboard] table, runs without the method's premise and
faults.

The run is the independent generator's (torquemod.twins.independent.train, written apart from the
estimator) put into a CSV at the axle; each case changes its manifest or its signals. A bad
setting or a run without any measurable window: exit 2, one line naming the file and the key
or the reason, nothing at --out. A run measurable in parts: exit 0, a warning naming the
stretch of track, the ``quality`` column saying which windows carry no numbers.
"""

from __future__ import annotations

import errno
import shutil

import numpy as np
import pandas as pd
import pytest

from test_outputs_safety import no_leftovers, one_error_line, raise_in, readonly  # noqa: F401
from torquemod.cli import main
from torquemod.twins.independent.train import simulate_independent
from torquemod.twins.independent.vehicle import IndependentRunSpec

SPEC = IndependentRunSpec(length_m=320.0, sample_rate_hz=1000.0, seed=5)
F_HZ = SPEC.modulation_frequency_hz


def _manifest(spec: IndependentRunSpec, *, frequency_hz=None, onboard: str = "") -> str:
    return (f"[vehicle]\nwheel_radius_m = {spec.wheel_radius_m}\n"
            f"normal_load_n = {spec.normal_load_n}\ninertia_kg_m2 = {spec.inertia_kg_m2}\n"
            f"[test]\nmodulation_frequency_hz = {frequency_hz or spec.modulation_frequency_hz}\n"
            f"modulation_amplitude_nm = {spec.modulation_amplitude_nm}\n"
            f"[[recording]]\nfile = \"run.csv\"\n{onboard}")


@pytest.fixture(scope="module")
def signals() -> pd.DataFrame:
    """The recorded signals at the axle (torque, axle speed, radar speed put on the logger's
    times by linear interpolation)."""
    run = simulate_independent(SPEC)
    g = SPEC.gear_ratio
    return pd.DataFrame({"time_s": run.t_s, "torque_nm": run.motor_torque_nm * g,
                         "wheel_speed_rad_s": run.motor_speed_rpm * np.pi / 30 / g,
                         "vehicle_speed_m_s": np.interp(run.t_s, run.radar_t_s,
                                                        run.radar_km_h / 3.6)})


def _write(folder, df: pd.DataFrame, **kw):
    folder.mkdir()
    df.to_csv(folder / "run.csv", index=False, float_format="%.10g")
    (folder / "run.toml").write_text(_manifest(SPEC, **kw), encoding="utf-8")
    return folder / "run.toml"


def _onboard(run, out, capsys) -> tuple[int, str]:
    rc = main(["onboard", str(run), "--out", str(out), "--quiet"])
    return rc, capsys.readouterr().err


def _without_line(df: pd.DataFrame, after_s: float | None = None) -> pd.DataFrame:
    """The torque with the modulation line removed (a moving mean over one period nulls
    it), from ``after_s`` [s] on (None: all of it)."""
    n = round(SPEC.sample_rate_hz / F_HZ)
    flat = df["torque_nm"].rolling(n, center=True, min_periods=1).mean()
    sel = df["time_s"] >= (df["time_s"].iloc[0] if after_s is None else after_s)
    return df.assign(torque_nm=df["torque_nm"].where(~sel, flat))


# ------------------------------------------------------------------------- [onboard] table

ONBOARD = [
    ("inf_hop", "hop_s = inf", ("onboard.hop_s", "finite")),
    ("string_bounds", 'ratio_bounds = ["one", "seven"]', ("onboard.ratio_bounds[0]", "'one'")),
    ("typo", "hopp_s = 0.5", ("onboard.hopp_s", "did you mean 'hop_s'")),
    ("fraction_periods", "window_periods = 5.5", ("onboard.window_periods", "whole number")),
    ("reversed_bounds", "ratio_bounds = [7.0, 1.0]", ("onboard.ratio_bounds", "low < high")),
    ("three_bounds", "ratio_bounds = [1.0, 3.0, 7.0]", ("onboard.ratio_bounds", "2 numbers")),
    ("flag_not_0_1", "power_shapes = 2", ("onboard.power_shapes", "one of 0, 1")),
    ("negative_memory", "memory_m = -100.0", ("onboard.memory_m", "> 0")),
    ("ratio_above_one", "min_modulation_ratio = 1.5", ("onboard.min_modulation_ratio",)),
    ("bool_for_int", "n_bins = true", ("onboard.n_bins",)),
]


@pytest.mark.parametrize("line,words", [pytest.param(c[1], c[2], id=c[0]) for c in ONBOARD])
def test_onboard_setting_refused_with_file_and_key(signals, tmp_path, capsys, line, words):
    run = _write(tmp_path / "run", signals.iloc[:2000], onboard=f"[onboard]\n{line}\n")
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2
    one_error_line(err, str(run), *words)
    no_leftovers(tmp_path, "run")


def test_onboard_not_a_table(signals, tmp_path, capsys):
    run = _write(tmp_path / "run", signals.iloc[:2000])
    run.write_text("onboard = 3\n" + run.read_text(encoding="utf-8"), encoding="utf-8")
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2
    one_error_line(err, str(run), "[onboard] must be a table")


# ------------------------------------------------------------------------- the premise

PREMISE = [
    ("no_modulation", lambda d: _without_line(d), {}, ("no window", "no modulation line at 4 Hz")),
    ("wrong_frequency", lambda d: d, {"frequency_hz": 5.0},
     ("modulation line is at 4 Hz", "test.modulation_frequency_hz = 5")),
    ("slightly_wrong_frequency", lambda d: d, {"frequency_hz": 4.3},
     ("modulation line is at 4 Hz",)),
    ("backwards", lambda d: d.assign(wheel_speed_rad_s=-d.wheel_speed_rad_s,
                                     vehicle_speed_m_s=-d.vehicle_speed_m_s),
     {}, ("no window", "backwards")),
    ("standstill", lambda d: d.assign(wheel_speed_rad_s=0.005 * d.wheel_speed_rad_s,
                                      vehicle_speed_m_s=0.005 * d.vehicle_speed_m_s),
     {}, ("no window", "standstill")),
]


@pytest.mark.parametrize("edit,kw,words", [pytest.param(*c[1:], id=c[0]) for c in PREMISE])
def test_run_without_the_premise_is_refused(signals, tmp_path, capsys, edit, kw, words):
    run = _write(tmp_path / "run", edit(signals), **kw)
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2, err
    one_error_line(err, *words)
    no_leftovers(tmp_path, "run")


def test_stretch_without_modulation_is_flagged_and_named(signals, tmp_path, capsys):
    """The modulation switched off halfway: exit 0; the windows after it carry the flag and
    no phase, creep coefficient or mu; a warning names where along the track; the summary
    says how much was measurable."""
    half = float(signals["time_s"].iloc[len(signals) // 2])
    run = _write(tmp_path / "run", _without_line(signals, after_s=half))
    out = tmp_path / "out"
    rc, err = _onboard(run, out, capsys)
    assert rc == 0, err
    warnings = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "no modulation line at 4 Hz" in warnings[0], err
    track = pd.read_parquet(out / "track.parquet")
    bad = track["quality"] == "no_modulation"
    late = track["time_s"] > half + 2.0  # a window and its neighbours past the switch
    early = track["time_s"] < half - 2.0
    assert bad[late].all() and not bad[early].any()
    assert track.loc[bad, ["phase_deg", "creep_coefficient", "mu"]].isna().all().all()
    first = track.loc[bad, "position_m"].min()
    assert f"{first:.0f}-" in warnings[0]  # the stretch starts where the flags start
    import json
    share = json.loads((out / "onboard.json").read_text())["axles"][0]["measurable_share"]
    assert share == pytest.approx((~bad).mean())
    assert 0.3 < share < 0.7


def test_too_short_a_run_says_so(signals, tmp_path, capsys):
    """3 s: a few windows, fewer than the friction fit needs."""
    run = _write(tmp_path / "run", signals.iloc[:3000])
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 0, err
    assert "too short for a friction estimate" in err


def test_a_one_hertz_reference_is_named(signals, tmp_path, capsys):
    """The radar held between updates once a second: the windows' speeds are coarse."""
    t = signals["time_s"].to_numpy()
    held = signals["vehicle_speed_m_s"].to_numpy()[np.searchsorted(t, np.floor(t), "left")]
    run = _write(tmp_path / "run", signals.assign(vehicle_speed_m_s=held))
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 0, err
    rate = float(err.split("updated only about ")[1].split()[0])
    assert rate == pytest.approx(1.0, abs=0.1), err


def test_the_unchanged_run_has_no_warning_and_every_window_ok(signals, tmp_path, capsys):
    run = _write(tmp_path / "run", signals)
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 0 and "warning" not in err, err
    assert (pd.read_parquet(tmp_path / "out" / "track.parquet")["quality"] == "ok").all()


# ------------------------------------------------------------------------- faults

@pytest.fixture
def good_run(signals, tmp_path):
    return _write(tmp_path / "run", signals.iloc[:4000])


def test_disk_full_while_writing_leaves_nothing(good_run, tmp_path, capsys, monkeypatch):
    import pyarrow.parquet as pq
    raise_in(monkeypatch, pq, "write_table", errno.ENOSPC)
    out = tmp_path / "out"
    rc, err = _onboard(good_run, out, capsys)
    assert rc == 2
    one_error_line(err, str(out), "No space left on device")
    no_leftovers(tmp_path, "run")


def test_interrupt_while_writing_leaves_nothing(good_run, tmp_path, capsys, monkeypatch):
    import torquemod.ontrain.report as report

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt
    monkeypatch.setattr(report, "write_report", interrupted)
    rc, err = _onboard(good_run, tmp_path / "out", capsys)
    assert rc == 130 and err.strip() == "torquemod: interrupted"
    no_leftovers(tmp_path, "run")


def test_read_only_target(good_run, tmp_path, capsys, readonly):  # noqa: F811
    (tmp_path / "ro").mkdir()
    parent = readonly(tmp_path / "ro")
    rc, err = _onboard(good_run, parent / "out", capsys)
    assert rc == 2
    one_error_line(err, str(parent / "out"), "Permission denied")
    assert list(parent.iterdir()) == []


def test_the_inputs_are_untouched(good_run, tmp_path, capsys):
    before = {p.name: p.read_bytes() for p in good_run.parent.iterdir()}
    shutil.rmtree(tmp_path / "out", ignore_errors=True)
    rc, _ = _onboard(good_run, good_run.parent, capsys)  # --out onto the run's folder
    assert rc == 2
    assert {p.name: p.read_bytes() for p in good_run.parent.iterdir()} == before


def test_recording_sample_rate_clash_names_the_recording_and_key(signals, tmp_path, capsys):
    run = _write(tmp_path / "run", signals.iloc[:2000])
    text = run.read_text(encoding="utf-8").replace(
        'file = "run.csv"', 'file = "run.csv"\nsample_rate_hz = 1000.0')
    run.write_text(text + '[channels]\ntime = "time_s"\n', encoding="utf-8")
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2
    one_error_line(err, str(run), "recording #1", "'sample_rate_hz'", "time channel")


def test_modulation_above_the_recordings_nyquist_is_refused(signals, tmp_path, capsys):
    run = _write(tmp_path / "run", signals.iloc[:2000], frequency_hz=600.0)
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2
    one_error_line(err, str(run), "test.modulation_frequency_hz", "Nyquist")


def test_too_few_samples_a_window_names_the_recording(signals, tmp_path, capsys):
    run = _write(tmp_path / "run", signals.iloc[::100])  # 10 Hz: 2 samples a 4 Hz period
    run.write_text(run.read_text(encoding="utf-8").replace("[[recording]]", (
        "[onboard]\nwindow_periods = 1\n[[recording]]")), encoding="utf-8")
    rc, err = _onboard(run, tmp_path / "out", capsys)
    assert rc == 2
    one_error_line(err, "run.csv", "samples at 10 Hz")
