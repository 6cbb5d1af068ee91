"""The train side in memory (tm.read_run, tm.onboard -> OnboardResult, save/load), the
along-track summary, the exports and the plot convention of the on-board figures."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure

import torquemod as tm
from torquemod.errors import InputError
from torquemod.onboard import TRACK_COLUMNS
from torquemod.onboard.alongtrack import (
    DRY_MIN,
    WET_MIN,
    along_track,
    guess_condition,
    run_mu_summary,
)


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    from torquemod.testing import write_short_train_run
    return write_short_train_run(tmp_path_factory.mktemp("train") / "run", length_m=400.0,
                                 seed=5)


@pytest.fixture(scope="module")
def result(twin):
    return tm.onboard(tm.read_run(twin / "run.toml"))


def test_cli_is_the_api_and_the_folder_reads_back(twin, result, tmp_path):
    """`torquemod onboard` writes what the API computes; tm.load_onboard gives it back."""
    from torquemod.cli import main
    out = tmp_path / "cli"
    assert main(["onboard", str(twin / "run.toml"), "--out", str(out), "--quiet",
                 "--export", "csv,mat"]) == 0
    written = pd.read_parquet(out / "track.parquet")
    pd.testing.assert_frame_equal(written, result.to_frame())
    assert list(written.columns) == list(TRACK_COLUMNS)
    back = tm.load_onboard(out)
    pd.testing.assert_frame_equal(back.to_frame(), written)
    assert back.changes_m == result.changes_m and back.config == result.config
    assert back.notes == result.notes and back.axle == result.axle
    assert back.warnings == result.warnings
    assert back.summary()["measurable_share"] == result.summary()["measurable_share"]
    assert back.run.vehicle == result.run.vehicle
    assert back.truth is not None  # the run's [truth] file is still there
    pd.testing.assert_frame_equal(back.along_track(), result.along_track())
    pd.testing.assert_frame_equal(pd.read_csv(out / "along_track.csv"),
                                  result.along_track(), check_dtype=False)
    # the per-segment fit: one row per segment between detected changes, written and read
    # back; the available adhesion given only where determined, never below the lower bound
    segs = result.segment_table()
    assert len(segs) == len(result.changes_m) + 1
    pd.testing.assert_frame_equal(back.segment_table(), segs)
    pd.testing.assert_frame_equal(pd.read_csv(out / "segments.csv", keep_default_na=False,
                                              na_values=[""]).astype(segs.dtypes.to_dict()),
                                  segs, check_dtype=False)
    assert (segs["adhesion_available"].notna() == segs["determined"]).all()
    fitted = segs["adhesion_available_best_fit"].notna()
    assert (segs.loc[fitted, "adhesion_available_lower_bound"]
            >= segs.loc[fitted, "coa_reached"] - 1e-12).all()
    assert repr(back) == repr(result)
    # the exports: the same numbers in CSV (exact floats) and MATLAB
    from scipy.io import loadmat
    np.testing.assert_array_equal(pd.read_csv(out / "track.csv")["mu_low_95"],
                                  written["mu_low_95"])
    mat = loadmat(out / "track.mat", simplify_cells=True)["track"]
    assert set(mat) == set(TRACK_COLUMNS)
    np.testing.assert_array_equal(mat["phase_deg"], written["phase_deg"])
    np.testing.assert_array_equal(mat["low_adhesion"].astype(bool), written["low_adhesion"])
    # OnboardResult.save writes the same folder
    result.save(tmp_path / "api")
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "api" / "track.parquet"), written)


def test_result_is_typed_and_frozen(result, twin):
    assert isinstance(result, tm.OnboardResult)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.axle = 2
    text = repr(result)
    assert text.startswith("<OnboardResult run.toml axle 1:") and len(text) < 200
    report = result.report()
    assert "Along the track" in report and "windows over" in report
    # options over the run's [onboard]: a hop twice as long gives about half the windows
    coarse = tm.onboard(twin / "run.toml", hop_s=2 * result.config.hop_s)
    assert coarse.config.hop_s == 2 * result.config.hop_s
    assert abs(len(coarse.track) - len(result.track) / 2) <= 2
    with pytest.raises(InputError, match="no axle 7"):
        tm.onboard(result.run, axle=7)
    with pytest.raises(InputError, match="hop_s"):
        tm.onboard(result.run, hop_s=-1.0)


def test_plots_follow_the_notebook_convention(result):
    """Given an ax, a plot returns that Axes; without one, the Axes of a new Figure that
    pyplot does not hold (a notebook cell shows each figure once)."""
    import matplotlib.pyplot as plt
    plt.close("all")
    axes = Figure().subplots(3, 1)
    for ax, plot in zip(axes, (result.plot_mu, result.plot_phase, result.plot_utilisation),
                        strict=True):
        assert plot(ax=ax) is ax
        assert ax.lines
        made = plot()
        assert isinstance(made, Axes) and isinstance(made.figure, Figure)
        assert made.get_legend() is not None
    assert plt.get_fignums() == []


def test_utilisation_truth_is_coa_over_available_adhesion(result):
    """The report's truth line is the truth table's utilisation (what simulate --train
    prints as max utilisation), CoA over the available adhesion, not over the friction."""
    ax = result.plot_utilisation()
    line = next(ln for ln in ax.lines if ln.get_label().startswith("truth"))
    tr = result.truth
    np.testing.assert_allclose(line.get_ydata(), tr["coa"] / tr["adhesion_peak"])
    np.testing.assert_allclose(line.get_ydata(), tr["utilisation"])
    assert not np.allclose(line.get_ydata(), tr["coa"] / tr["mu"])


def test_report_without_truth_shows_the_friction_along_the_track(twin, tmp_path):
    """A real run (no [truth]): the report still has the along-track tables and a
    utilisation panel with data (CoA over the segment's lower bound)."""
    import shutil
    folder = tmp_path / "real"
    folder.mkdir()
    shutil.copy(twin / "run.mf4", folder / "run.mf4")
    text = (twin / "run.toml").read_text()
    head, _, tail = text.partition("[truth]")
    tail = tail.split("\n[", 1)
    (folder / "run.toml").write_text(head + ("[" + tail[1] if len(tail) > 1 else ""))
    res = tm.onboard(folder / "run.toml")
    assert res.truth is None
    ax = res.plot_utilisation()
    bound_line = next(ln for ln in ax.lines if ln.get_label().startswith("CoA / lower"))
    assert np.isfinite(bound_line.get_ydata()).mean() > 0.5
    res.save(tmp_path / "out")
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Per segment between detected friction changes" in html
    assert "Per kilometre" in html and "simulated truth" not in html
    assert "Figure 1: Friction along the track" in html and "mu_along_track.png<" not in html
    assert (tmp_path / "out" / "along_track_km.csv").exists()


def _track(position, mu, low, high, coa, flags=None):
    n = len(position)
    return pd.DataFrame({"position_m": position, "mu": mu, "mu_low_95": low,
                         "mu_high_95": high, "coa": coa,
                         "low_adhesion": flags if flags is not None else np.zeros(n, bool),
                         "slip": np.zeros(n, bool)})


def test_along_track_segments_and_kilometres():
    x = np.arange(0.0, 2500.0, 5.0)
    dry = x < 1200
    nan = np.full(x.size, np.nan)
    coa = np.where(dry, 0.33, 0.09)
    low = coa - 0.01
    mu, hi = nan.copy(), nan.copy()
    wet_mu = x >= 1500  # mu determined on the last kilometre
    mu[wet_mu], low[wet_mu], hi[wet_mu] = 0.11, 0.10, 0.115
    t = _track(x, mu, low, hi, coa)
    seg = along_track(t, changes_m=[1200.0])
    assert seg["start_m"].tolist() == [0.0, 1200.0] and seg["end_m"].tolist() == [1200.0,
                                                                                 2495.0]
    assert seg["windows"].sum() == x.size
    assert seg.loc[0, "condition"] == "dry" and math.isnan(seg.loc[0, "mu"])
    assert seg.loc[0, "mu_lower_bound"] == pytest.approx(0.32)
    assert seg.loc[1, "mu"] == pytest.approx(0.11)
    assert seg.loc[1, "condition"] == "low adhesion"  # 0.08 .. 0.115: below WET_MIN
    assert seg.loc[1, "probe_depth"] == pytest.approx(0.09 / 0.11)
    km = along_track(t, by="km")
    assert km["start_m"].tolist() == [0.0, 1000.0, 2000.0]
    assert km.loc[1, "condition"] == "mixed"  # dry bound, low-adhesion mu in one km
    assert math.isnan(km.loc[1, "probe_depth"])
    assert km.loc[2, "condition"] == "low adhesion" and km.loc[2, "mu_given_share"] == 1.0


def test_condition_guess_and_a_single_straddling_window():
    assert guess_condition(DRY_MIN + 0.01, None) == "dry"
    assert guess_condition(WET_MIN + 0.01, None) == "wet or dry"
    assert guess_condition(0.05, None) == "not probed"
    assert guess_condition(0.05, WET_MIN - 0.01) == "low adhesion"
    assert guess_condition(0.2, 0.1) == "mixed"
    # one window straddling a change far above the rest moves the bound not at all
    x = np.arange(100.0)
    low = np.full(100, 0.08)
    low[50] = 0.30
    t = _track(x, np.nan, low, np.nan, low + 0.01)
    assert along_track(t).loc[0, "mu_lower_bound"] == pytest.approx(0.08)


def test_run_summary_never_puts_mu_below_its_bound():
    """A run with mu determined on a low-friction stretch and bounds from a dry one: the
    summary's bound belongs to the same windows as its mu."""
    x = np.arange(200.0)
    given = x >= 180
    mu = np.where(given, 0.12, np.nan)
    low = np.where(given, 0.10, 0.31)
    t = _track(x, mu, low, np.where(given, 0.14, np.nan), np.full(200, 0.3))
    m, b = run_mu_summary(t)
    assert m == pytest.approx(0.12) and b == pytest.approx(0.10) and b <= m
    m, b = run_mu_summary(t[~given])
    assert m is None and b == pytest.approx(0.31)


def test_export_formats_and_mat_tables(tmp_path):
    from scipy.io import loadmat

    from torquemod.export import check_formats, write_table
    assert check_formats("csv, MAT,csv") == ("csv", "mat")
    with pytest.raises(InputError, match="unknown export format 'xlsx'"):
        check_formats("xlsx")
    frame = pd.DataFrame({"a m": [1.0, np.nan], "flag": [True, False], "name": ["dry", None],
                          "2x": [1, 2]})
    write_table(frame, tmp_path / "t", "mat")
    got = loadmat(tmp_path / "t.mat", simplify_cells=True)["t"]
    assert set(got) == {"a_m", "flag", "name", "x2x"}
    assert np.isnan(got["a_m"][1]) and got["flag"].tolist() == [1, 0]
    assert got["name"][0] == "dry" and len(got["name"][1]) == 0  # a cell array of char


def test_cli_refuses_a_bad_export_before_any_work(twin, tmp_path, capsys):
    from torquemod.cli import main
    assert main(["onboard", str(twin / "run.toml"), "--out", str(tmp_path / "o"),
                 "--export", "xls"]) == 2
    assert "unknown export format" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("suffix", [".parquet", ".mat", ".csv"])
def test_convert_to_parquet_mat_csv(tmp_path, suffix):
    from torquemod.convert import convert_file
    from torquemod.data import Recording
    from torquemod.io.recording import read_recording, write_recording
    rng = np.random.default_rng(1)
    rec = Recording({"torque_nm": rng.normal(size=3000),
                     "wheel_speed_rad_s": 30 + rng.normal(size=3000),
                     "fx_n": rng.normal(size=3000), "fz_n": 4000 + rng.normal(size=3000)},
                    fs_hz=1000.0, t0_s=0.25)
    src = write_recording(tmp_path / "r.h5", rec, fmt="hdf5")
    back = read_recording(convert_file(src, tmp_path / f"out{suffix}"))
    assert sorted(back.channels) == sorted(rec.channels)
    # Parquet and .mat keep every bit; CSV writes 9 significant digits
    rtol = 5e-9 if suffix == ".csv" else 0.0
    assert back.fs_hz == pytest.approx(1000.0, rel=rtol)
    for k, v in rec.channels.items():
        np.testing.assert_allclose(back.channels[k], v, rtol=rtol, atol=rtol * 4000)


def test_rig_load_points_an_onboard_folder_to_load_onboard(result, tmp_path):
    result.save(tmp_path / "ob")
    with pytest.raises(InputError, match="load_onboard"):
        tm.load(tmp_path / "ob")


def test_two_axles_saved_and_each_read_back(twin, result, tmp_path):
    """A run of two axles: tm.onboard asks which; the CLI's folder holds both and
    tm.load_onboard reads either."""
    import shutil

    from torquemod.cli import main
    folder = tmp_path / "two"
    folder.mkdir()
    shutil.copy(twin / "run.mf4", folder / "run.mf4")
    shutil.copy(twin / "truth.parquet", folder / "truth.parquet")
    text = (twin / "run.toml").read_text().replace(
        '{ file = "run.mf4", axle = 1 },',
        '{ file = "run.mf4", axle = 1 },\n    { file = "run.mf4", axle = 2 },')
    (folder / "run.toml").write_text(text)
    with pytest.raises(InputError, match=r"axles \[1, 2\].*axle="):
        tm.onboard(folder / "run.toml")
    assert main(["onboard", str(folder / "run.toml"), "--out", str(tmp_path / "o"),
                 "--quiet"]) == 0
    second = tm.load_onboard(tmp_path / "o", axle=2)
    assert second.axle == 2
    pd.testing.assert_frame_equal(second.to_frame(), result.to_frame())  # the same file
    assert (tmp_path / "o" / "along_track_axle2.csv").exists()
    with pytest.raises(InputError, match="no axle 3"):
        tm.load_onboard(tmp_path / "o", axle=3)
