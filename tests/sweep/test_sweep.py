"""torquemod sweep (issue 12): the sweep file, theory and full sweeps, resuming, failures,
the recommendation, and the twin against the large-signal theory."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from torquemod import __version__
from torquemod.errors import InputError
from torquemod.sweep.run import run_sweep
from torquemod.sweep.spec import RecommendOptions, SweepSpec, load_sweep, parse_sweep
from torquemod.sweep.summary import recommend

# A short procedure for the full chain: three steps, one revolution each, 1.5 s run-in.
SHORT = """
[fixed]
procedure.cycles_per_step = 1
procedure.settle_s = 1.5
[steps]
fractions_of_peak = [0.0, 0.4, 0.7]
"""


# ------------------------------------------------------------------------------ the file

def test_grid_points_and_seeds():
    spec = parse_sweep("""
mode = "theory"
seeds = [3, 4]
[fixed]
"procedure.cycles_per_step" = 2
[grid]
contact.condition = ["dry", "wet"]
"modulation.frequency_hz" = [1.0, 2.0, 4.0]
[[point]]
rig.speed_km_h = 5.0
[[point]]
rig.speed_km_h = 9.0
""")
    # 2 listed points x 2 conditions x 3 frequencies x 2 seeds
    assert len(spec.points) == 24
    assert spec.swept == ("rig.speed_km_h", "contact.condition", "modulation.frequency_hz")
    assert {p.seed for p in spec.points} == {3, 4}
    p = spec.points[0]
    assert p.params == {"procedure.cycles_per_step": 2, "rig.speed_km_h": 5.0,
                        "contact.condition": "dry", "modulation.frequency_hz": 1.0}
    assert len({q.point_id for q in spec.points}) == 24
    # the id depends on the parameters and the seed, not on the order in the file
    again = parse_sweep("""
mode = "theory"
seeds = [4, 3]
[fixed]
procedure.cycles_per_step = 2
[grid]
modulation.frequency_hz = [4.0, 2.0, 1.0]
contact.condition = ["wet", "dry"]
[[point]]
rig.speed_km_h = 9.0
[[point]]
rig.speed_km_h = 5.0
""")
    assert {q.point_id for q in again.points} == {q.point_id for q in spec.points}


def test_condition_overrides_and_explicit_polach_key_wins():
    spec = parse_sweep("""
[[point]]
contact.condition = "leaves"
[[point]]
contact.condition = "leaves"
contact.mu0 = 0.2
""")
    a, b = (p.overrides()["contact"] for p in spec.points)
    assert a["mu0"] == 0.12 and a["k_a"] == 0.30  # train.params.CONDITIONS["leaves"]
    assert b["mu0"] == 0.2 and b["k_a"] == 0.30
    assert "condition" not in a


@pytest.mark.parametrize("text, words", [
    ("[grid]\nmodulation.frequncy_hz = [1.0]\n",
     ["sweep.toml", "modulation.frequncy_hz", "did you mean 'modulation.frequency_hz'"]),
    ("mdoe = 'theory'\n", ["sweep.toml", "'mdoe'", "did you mean 'mode'"]),
    ("[[point]]\nrig.wheel_radius = 0.07\n", ["point]] #1", "'rig.wheel_radius_m'"]),
    ("[grid]\ncontact.condition = ['icy']\n", ["'contact.condition' must be one of", "'icy'"]),
    ("mode = 'fast'\n", ["unknown mode 'fast'"]),
    ("[grid]\nmodulation.frequency_hz = 2.0\n", ["must be a non-empty list"]),
    ("base = 'missing.toml'\n", ["base config 'missing.toml' not found"]),
    ("[steps]\nfractions_of_peak = [0.5, 1.2]\n", ["fractions_of_peak"]),
    ("seeds = [1]\nrepeats = 2\n", ["not both"]),
    ("[recommend]\nmax_swing = 1\n", ["did you mean 'max_creepage_swing'"]),
    ("[grid\n", ["TOML syntax error"]),
    ("[processing.phase]\nmethd = 'sinefit'\n", ["sweep.toml [processing]", "methd"]),
])
def test_bad_sweep_files(tmp_path, text, words):
    path = tmp_path / "sweep.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError) as err:
        load_sweep(path)
    for w in words:
        assert w in str(err.value)


def test_base_config_relative_to_the_sweep_file(tmp_path):
    (tmp_path / "twin.toml").write_text("[rig]\nnormal_load_n = 3000.0\n", encoding="utf-8")
    (tmp_path / "s.toml").write_text("base = 'twin.toml'\n[grid]\nrig.speed_km_h = [5.0]\n",
                                     encoding="utf-8")
    spec = load_sweep(tmp_path / "s.toml")
    assert spec.base == tmp_path / "twin.toml"
    assert spec.mode == "full" and spec.seeds == (0,)


# ----------------------------------------------------------------------- theory sweeps

THEORY = """
name = "tiny"
mode = "theory"
seeds = [5]
[steps]
fractions_of_peak = [0.0, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9]
[grid]
contact.condition = ["vtrack", "wet"]
modulation.frequency_hz = [2.0, 3.0]
"""


@pytest.fixture(scope="module")
def theory_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sw") / "theory"
    spec = parse_sweep(THEORY)
    return out, spec, run_sweep(spec, out, in_process=True)


def test_theory_sweep_table(theory_sweep):
    out, _, res = theory_sweep
    assert res.count("done") == 4 and res.failures.empty
    tab = pd.read_parquet(out / "sweep.parquet")
    assert len(tab) == 4 * 7  # one row per point and step
    for col in ("contact.condition", "modulation.frequency_hz", "seed", "dc_torque_nm",
                "utilisation", "phase_theory_deg", "creep_coefficient", "mu_true",
                "mu_phase", "mu_phase_lo", "mu_phase_hi", "creepage_swing",
                "torque_ripple_pct", "phase_deg", "phase_se_deg"):
        assert col in tab, col
    assert set(tab["seed"]) == {5}
    # DC torques are the fractions of each point's own creep-curve peak
    assert np.allclose(tab["dc_torque_nm"] / tab["peak_torque_nm"], tab["utilisation"])
    # the phase rises with the utilisation at every point (towards 90 deg at saturation)
    for _, g in tab.groupby("point_id"):
        assert np.all(np.diff(g["phase_theory_deg"].to_numpy()) > 0)
    meta = pq.read_schema(out / "sweep.parquet").metadata
    assert meta[b"torquemod_version"].decode() == __version__
    assert meta[b"sweep_toml"].decode() == THEORY
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["version"] == __version__ and doc["seeds"] == [5]
    assert doc["points"] == {"done": 4, "skipped": 0, "failed": 0} and doc["wall_s"] > 0
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "Recommendation" in html and html.count("data:image/png;base64,") >= 5
    assert doc["recommendation"]["setting"]["modulation_amplitude_nm"] == 8.0


def test_mu_from_phase_judged_against_the_available_adhesion(theory_sweep):
    """mu_friction is Polach's Eq. 9 friction at the creepage x speed of the highest step at
    or below the utilisation limit (recomputed here from the table and the condition's
    parameters); on these falling-friction conditions it lies between the creep curve's
    peak (mu_true, the available adhesion) and mu0. The errors in the summary are taken
    against the available adhesion, the one truth the report names."""
    from torquemod.sweep.conditions import conditions
    from torquemod.sweep.summary import point_summary
    out, spec, _ = theory_sweep
    tab = pd.read_parquet(out / "sweep.parquet")
    for _, g in tab.groupby("point_id"):
        used = g[(~g["slipped"].astype(bool)) & (g["utilisation"] <= 0.8 + 1e-9)]
        c = conditions()[g["contact.condition"].iloc[0]]
        w = used["creepage_true"].iloc[-1] * g["speed_m_s"].iloc[0]
        expect = c.mu0 * ((1 - c.a_ratio) * np.exp(-c.b_s_m * w) + c.a_ratio)
        assert g["mu_friction"].iloc[0] == pytest.approx(expect, rel=1e-12)
        assert g["mu_true"].iloc[0] < expect <= c.mu0
    summ = point_summary(tab, spec)
    det = summ[summ["mu_phase_determined"]]
    np.testing.assert_allclose(det["mu_phase_error_pct"],
                               100 * (det["mu_phase"] / det["mu_true"] - 1), rtol=1e-12)


def test_mu_from_phase_leaves_out_steps_that_reverse_the_torque(theory_sweep):
    """Steps whose DC torque does not exceed the modulation amplitude (the torque changes
    sign each period; at zero DC torque the large-signal phase lies 1-2 deg below the
    linearised model) are not given to the mu-from-phase fit: the count of steps it used
    is that of the others at or below the utilisation limit."""
    out, _, _ = theory_sweep
    tab = pd.read_parquet(out / "sweep.parquet")
    for _, g in tab.groupby("point_id"):
        assert (g["dc_torque_nm"] <= g["modulation_amplitude_nm"]).any()  # a zero step
        ok = (~g["slipped"].astype(bool)) & (g["utilisation"] <= 0.8 + 1e-9) \
            & (g["dc_torque_nm"].abs() > g["modulation_amplitude_nm"])
        assert g["mu_phase_n_steps"].iloc[0] == int(ok.sum())


def test_resume_skips_finished_points_and_force_reruns(theory_sweep):
    out, spec, first = theory_sweep
    again = run_sweep(spec, out, in_process=True, report=False)
    assert again.count("skipped") == 4 and again.count("done") == 0
    pd.testing.assert_frame_equal(again.table, first.table)
    # a changed parameter is a new point; the old ones stay skipped
    more = parse_sweep(THEORY.replace("[2.0, 3.0]", "[2.0, 3.0, 2.5]"))
    res = run_sweep(more, out, in_process=True, report=False)
    assert res.count("skipped") == 4 and res.count("done") == 2
    forced = run_sweep(spec, out, in_process=True, report=False, force=True)
    assert forced.count("done") == 4
    cols = [c for c in first.table if c != "point_wall_s"]
    pd.testing.assert_frame_equal(forced.table[cols], first.table[cols])


def test_dask_local_cluster_gives_the_in_process_rows(tmp_path, theory_sweep):
    """Two points as tasks on a LocalCluster of 2 worker processes: the same rows as the
    in-process run of the same points (same ids: same parameters and seed). Run again,
    both are skipped without a cluster (the command decides them)."""
    _, _, inproc = theory_sweep
    spec = parse_sweep(THEORY.replace("[2.0, 3.0]", "[3.0]"))
    links = []
    res = run_sweep(spec, tmp_path / "dask", n_workers=2, report=False,
                    on_dashboard=links.append)
    assert res.count("done") == 2 and links and res.dashboard == links[0]
    ref = inproc.table[inproc.table["point_id"].isin(res.table["point_id"])]
    cols = [c for c in ref if c not in ("point_wall_s", "point_index")]
    pd.testing.assert_frame_equal(res.table[cols].reset_index(drop=True),
                                  ref[cols].reset_index(drop=True))
    seen = []
    again = run_sweep(spec, tmp_path / "dask", n_workers=2, report=False,
                      on_dashboard=seen.append)
    assert again.count("skipped") == 2 and again.dashboard is None and seen == []
    pd.testing.assert_frame_equal(again.table, res.table)


def test_the_report_imports_run_beside_the_last_batch(tmp_path, monkeypatch):
    """Once fewer batches are left than worker slots, the command imports what the report
    needs in a thread (on the core a worker no longer uses), once, and waits for it before
    the table is assembled; without a report nothing is started."""
    import threading

    import torquemod.sweep.finish as finish_mod
    import torquemod.sweep.report as report_mod
    calls = []
    monkeypatch.setattr(finish_mod, "import_report_modules",
                        lambda kind, drawing=True: calls.append(
                            (kind, threading.current_thread().name)))
    monkeypatch.setattr(report_mod, "write_report", lambda *a, **k: calls.append("report"))
    spec = parse_sweep(THEORY.replace("[2.0, 3.0]", "[3.0]"))  # 2 points: 2 batches
    run_sweep(spec, tmp_path / "a", n_workers=2, report=True)
    assert calls == [("rig", "torquemod-sweep-tail"), "report"]
    calls.clear()
    run_sweep(spec, tmp_path / "b", n_workers=2, report=False)
    assert calls == []


def test_the_figures_drawn_on_the_workers_are_those_drawn_here(tmp_path, theory_sweep,
                                                                monkeypatch):
    """On a local cluster the report's figures are drawn as tasks on its workers (after
    the workers imported the drawing code, once their points were done; those drawn from
    the table alone submitted first): the same PNG files, byte for byte, and the same page
    but its run time as the in-process sweep's."""
    import re

    import torquemod.sweep.finish as finish_mod
    out0, spec, _ = theory_sweep
    drawn, early, warmed, states = [], [], [], []
    warm = finish_mod.warm_workers

    class Counted(finish_mod.FigureDrawer):
        def submit(self, jobs):
            early.extend(j.stem for j in jobs)
            return super().submit(jobs)

        def __call__(self, jobs):
            drawn.extend(j.stem for j in jobs)
            pngs = super().__call__(jobs)
            states.extend(f.status for f in warmed)  # the imports: none failed
            return pngs

    monkeypatch.setattr(finish_mod, "draw_on", Counted)
    monkeypatch.setattr(finish_mod, "warm_workers",
                        lambda client: warmed.extend(warm(client)) or list(warmed))
    out = tmp_path / "dask"
    res = run_sweep(spec, out, n_workers=2)
    assert res.count("done") == 4 and res.report is not None
    assert len(warmed) == 2 and set(states) <= {"pending", "finished"} and states
    files = sorted(p.name for p in (out0 / "figures").glob("*.png"))
    assert sorted(f"{s}.png" for s in drawn) == files and len(files) >= 4
    # those of the table alone were handed out before the summary was worked out
    assert early[:3] == ["phase_by_condition", "phase_by_frequency", "creep_curves"]
    for name in files:
        assert (out / "figures" / name).read_bytes() == (out0 / "figures" / name).read_bytes()

    def page(folder):
        text = (folder / "report.html").read_text(encoding="utf-8")
        return re.sub(r"this run took [0-9.]+ s", "", text)
    assert page(out) == page(out0)


def test_failed_points_become_rows_and_the_sweep_goes_on(tmp_path):
    spec = parse_sweep("""
mode = "theory"
[[point]]
procedure.dc_torques_nm = [10.0, 30.0]
[[point]]
procedure.dc_torques_nm = [100.0]
[[point]]
modulation.frequency_hz = 9000.0
""")  # each value is in range (checked when the sweep is read); above Nyquist together
    res = run_sweep(spec, tmp_path / "out", in_process=True, report=False)
    assert res.count("done") == 1 and res.count("failed") == 2
    fails = pd.read_csv(tmp_path / "out" / "failures.csv")
    assert list(fails["point_index"]) == [1, 2]
    assert "slips at the first step" in fails["message"][0]
    assert "Nyquist" in fails["message"][1]
    assert all("\n" not in m for m in fails["message"])
    assert len(res.table) == 2 and set(res.table["point_index"]) == {0}


def _fake_table(errors, ripples, swings) -> tuple[pd.DataFrame, SweepSpec]:
    """A sweep table of three settings x two conditions with given mu errors [%] per
    setting (determined), torque ripple [%] and creepage swing: the recommendation's
    inputs, known by construction."""
    rows = []
    for s, (err, rip, sw) in enumerate(zip(errors, ripples, swings, strict=True)):
        for c, cond in enumerate(("dry", "wet")):
            mu = 0.4
            e = err * (1 if c else -1) / 100.0  # +-err: RMS err
            for step, u in enumerate((0.3, 0.5, 0.7, 0.8), start=1):
                rows.append({"point_id": f"p{s}{c}", "point_index": 2 * s + c,
                             "contact.condition": cond, "modulation.frequency_hz": 1.0 + s,
                             "seed": 0, "step": step, "utilisation": u, "slipped": False,
                             "phase_theory_deg": 10 + 20 * u, "phase_deg": np.nan,
                             "phase_se_deg": np.nan, "phase_crlb_deg": 0.1,
                             "phase_twin_minus_theory_deg": np.nan,
                             "creepage_swing": sw, "torque_ripple_pct": rip,
                             "modulation_frequency_hz": 1.0 + s,
                             "modulation_frequency_nominal_hz": 1.0 + s,
                             "modulation_amplitude_nm": 8.0, "mu_true": mu,
                             "mu_phase": mu * (1 + e), "mu_phase_lo": mu * (1 + e - 0.01),
                             "mu_phase_hi": mu * (1 + e + 0.01),
                             "mu_phase_determined": True})
    spec = SweepSpec(path=None, text="", name="fake", description="", base=None,
                     mode="theory", seeds=(0,), points=(),
                     swept=("contact.condition", "modulation.frequency_hz"),
                     recommend=RecommendOptions(max_creepage_swing=2e-3,
                                                max_torque_ripple_pct=15.0))
    return pd.DataFrame(rows), spec


def test_recommendation_is_the_most_accurate_setting_within_the_limits():
    # 1 Hz: most accurate but its ripple is too large; 2 Hz: within limits, 3 % error;
    # 3 Hz: within limits, 5 % error -> 2 Hz
    tab, spec = _fake_table(errors=[1.0, 3.0, 5.0], ripples=[20.0, 10.0, 10.0],
                            swings=[1e-3, 1e-3, 1.5e-3])
    rec = recommend(tab, spec)
    assert rec["setting"] == {"modulation_frequency_nominal_hz": 2.0,
                              "modulation_amplitude_nm": 8.0}
    assert "excluded 1 Hz" in rec["reasoning"] and "3 Hz" in rec["reasoning"]
    best = next(s for s in rec["settings"] if s["modulation_frequency_nominal_hz"] == 2.0)
    assert best["rms_error_pct"] == pytest.approx(3.0)
    assert best["bias_pct"] == pytest.approx(0.0, abs=1e-9)  # -3 % and +3 %
    assert best["n_covered"] == 0  # +-3 % with a +-1 % interval: the truth is outside
    # with no setting within the limits, the most accurate one, said so
    tab, spec = _fake_table(errors=[4.0, 3.0, 5.0], ripples=[20.0, 20.0, 20.0],
                            swings=[1e-3, 1e-3, 1e-3])
    rec = recommend(tab, spec)
    assert rec["setting"]["modulation_frequency_nominal_hz"] == 2.0
    assert rec["within_limits"] is False and "No setting" in rec["reasoning"]


def test_one_recommendation_per_noise_level():
    tab, spec = _fake_table(errors=[1.0, 3.0, 5.0], ripples=[10.0, 10.0, 10.0],
                            swings=[1e-3, 1e-3, 1e-3])
    noisy = tab.copy()
    noisy["sensors.torque_noise_nm"] = 1.0
    noisy["point_id"] += "n"
    # at the higher noise the 1 Hz setting loses its accuracy (20 %): 2 Hz is then the best
    noisy.loc[noisy["modulation.frequency_hz"] == 1.0, "mu_phase"] *= 1.2
    tab["sensors.torque_noise_nm"] = 0.2
    both = pd.concat([tab, noisy], ignore_index=True)
    both["modulation_frequency_nominal_hz"] = both["modulation_frequency_hz"]
    spec = dataclasses.replace(spec, swept=(*spec.swept, "sensors.torque_noise_nm"))
    rec = recommend(both, spec)
    assert [g["noise"] for g in rec["by_noise"]] == [{"sensors.torque_noise_nm": 0.2},
                                                     {"sensors.torque_noise_nm": 1.0}]
    assert [g["setting"]["modulation_frequency_nominal_hz"] for g in rec["by_noise"]] == \
        [1.0, 2.0]
    assert rec["setting"] == rec["by_noise"][0]["setting"]
    assert rec["reasoning"].startswith("At sensors.torque_noise_nm = 0.2:")


# -------------------------------------------------------------------------- full sweeps

def test_chain_config_scales_with_the_frequency_and_takes_the_processing_table():
    from torquemod.io.config import ProcessingConfig
    from torquemod.sweep.evaluate import chain_config
    assert chain_config(2.0) == ProcessingConfig()  # the defaults are the 2 Hz ones
    c = chain_config(4.0, {"phase": {"method": "sinefit"}, "slow": {"max_hz": 1.0}})
    assert c.frequency.band_hz == (3.0, 5.0) and c.bandpass.width_hz == pytest.approx(0.72)
    assert c.highpass.cutoff_hz == 1.0 and c.phase.method == "sinefit"
    assert c.slow.max_hz == 1.0  # given: wins over the scaled 2.4 Hz
    assert c.phase.n_periods == ProcessingConfig().phase.n_periods


def test_full_sweep_on_the_chain(tmp_path):
    spec = parse_sweep('mode = "full"\nseeds = [2]\n' + SHORT
                       + "[grid]\nmodulation.amplitude_nm = [6.0, 8.0]\n")
    res = run_sweep(spec, tmp_path / "full", in_process=True, report=False)
    assert res.count("done") == 2, res.failures
    tab = res.table
    assert len(tab) == 6 and set(tab["seed"]) == {2}
    # the chain measured every step; its phase agrees with the theory within its own error
    # (5 standard errors, the chain's per-step SE; the theory is exact to ~1e-3 deg)
    assert tab["phase_deg"].notna().all() and (tab["phase_se_deg"] > 0).all()
    assert np.all(np.abs(tab["phase_deg"] - tab["phase_theory_deg"])
                  <= 5 * tab["phase_se_deg"] + 0.05)
    for col in ("mu_forces", "mu_forces_lo", "mu_forces_hi", "mu_phase_lo", "coa",
                "creepage", "creep_coefficient_fit"):
        assert col in tab
    # three steps up to 70 % do not determine mu from the forces: the lower bound they give
    # (the highest CoA measured, ~0.7*mu) lies below the true mu
    lb = tab["mu_forces_lower_bound"].to_numpy(float)
    assert np.all((lb > 0.6 * tab["mu_true"]) & (lb < tab["mu_true"]))
    # the experiment folders the twin wrote are gone
    assert not (tmp_path / "full" / "_work").exists()


def test_a_full_point_in_memory_gives_the_rows_of_the_point_through_files(tmp_path):
    """A full-mode point runs twin -> recordings -> chain -> fits in memory; through an HDF5
    experiment folder written and read back it gives the same rows, bit for bit (five
    steps: both fits run)."""
    from torquemod.sweep.evaluate import evaluate_point, tasks
    spec = parse_sweep('mode = "full"\nseeds = [4]\n' + SHORT.replace(
        "[0.0, 0.4, 0.7]", "[0.0, 0.3, 0.5, 0.7, 0.85]"))
    task = tasks(spec)[0]
    mem = evaluate_point(task)
    files = evaluate_point(task, workdir=tmp_path, through_files=True)
    assert list(tmp_path.iterdir()) == []  # the experiment folder is removed
    assert mem["phase_deg"].notna().sum() == 5 and np.isfinite(mem["mu_forces_lower_bound"]).all()
    pd.testing.assert_frame_equal(mem.drop(columns="point_wall_s"),
                                  files.drop(columns="point_wall_s"), check_exact=True)


def test_points_go_to_the_cluster_in_batches(tmp_path):
    """Batches: every point once, dealt with a stride, largest first down to single points
    (each takes 1/(2*slots) of the points left); a batch whose worker died reports the
    points it finished as done and the others as failed."""
    from dataclasses import replace

    from torquemod.sweep.evaluate import tasks
    from torquemod.sweep.run import _lost, point_batches, run_point
    todo = tasks(parse_sweep(THEORY))
    assert len(todo) == 4
    for slots, sizes in ((1, [2, 1, 1]), (2, [1, 1, 1, 1]), (8, [1, 1, 1, 1])):
        b = point_batches(todo, slots)
        assert [len(x) for x in b] == sizes
        assert sorted(t.index for batch in b for t in batch) == [0, 1, 2, 3]
    assert [t.index for t in point_batches(todo, 1)[0]] == [0, 2]
    many = [replace(todo[0], index=i) for i in range(54)]
    sizes = [len(x) for x in point_batches(many, 2)]
    assert sizes == [14, 10, 8, 6, 4, 3, 3, 2, 1, 1, 1, 1]  # ceil(left / 4)
    assert sorted(t.index for x in point_batches(many, 2) for t in x) == list(range(54))
    out = tmp_path / "out"
    before = time.time() - 1.0
    assert run_point(todo[0], str(out))["status"] == "done"
    rows = _lost(todo[:2], out, "killed", before)
    assert [r["status"] for r in rows] == ["done", "failed"]
    assert rows[0]["n_rows"] > 0 and rows[1]["message"] == "worker lost: killed"
    # a point finished by an earlier run was skipped, or, when forced, not rerun: failed
    later = time.time() + 10.0
    assert [r["status"] for r in _lost(todo[:1], out, "killed", later)] == ["skipped"]
    assert [r["status"] for r in _lost(todo[:1], out, "killed", later, True)] == ["failed"]


def test_twin_agrees_with_large_signal_theory_over_a_small_grid(tmp_path):
    """The twin's simulated phase (truth.json 'simulated', wobble fitted out) and the
    large-signal theory within 0.1 deg at every step below slip, 2 conditions x 2
    frequencies (the issue's tolerance; the theory resolves the periodic state to 1e-9 deg,
    the RK4 twin to ~1e-6 deg, so what is left is the settling of each step)."""
    spec = parse_sweep("""
mode = "full"
[fixed]
procedure.cycles_per_step = 1
procedure.settle_s = 3.0
disturbances.enabled = false
[steps]
fractions_of_peak = [0.0, 0.3, 0.6, 0.8]
[grid]
contact.condition = ["vtrack", "wet"]
modulation.frequency_hz = [2.0, 4.0]
""")
    res = run_sweep(spec, tmp_path / "tw", in_process=True, report=False)
    assert res.count("done") == 4, res.failures
    tab = res.table[~res.table["slipped"]]
    diff = tab["phase_twin_minus_theory_deg"].to_numpy(float)
    assert np.isfinite(diff).all() and len(diff) == 16
    assert np.max(np.abs(diff)) < 0.1, np.max(np.abs(diff))
    # measured 0.0023 deg (wet, near 80 %): the undisturbed twin is far inside the issue's
    # bound; 0.01 deg still leaves 4x margin for the settling of the steps
    assert np.max(np.abs(diff)) < 0.01, np.max(np.abs(diff))
    agr = json.loads((tmp_path / "tw" / "sweep.json").read_text())["agreement"]
    assert agr["twin_minus_theory_max_deg"] == pytest.approx(np.max(np.abs(diff)))


def test_cli_reports_a_bad_sweep_file_before_starting_a_cluster(tmp_path, capsys):
    from torquemod.cli import main
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid]\nrig.sped_km_h = [5.0]\n", encoding="utf-8")
    assert main(["sweep", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "did you mean 'rig.speed_km_h'" in err


def test_a_full_point_skips_analyze_probe_depth_without_changing_its_rows(monkeypatch):
    """The sweep's analyze leaves out the probe depth of the fit from the phase
    (``FitOptions.probe``): no column of sweep.parquet depends on it, so the point's rows
    are bit for bit those of a point that computes it. The probe must actually run in the
    second point (more probe searches than in the first), or the test proves nothing."""
    import torquemod.api
    from torquemod.analysis import analyzer, friction
    from torquemod.sweep.evaluate import evaluate_point, tasks
    spec = parse_sweep('mode = "full"\nseeds = [4]\n' + SHORT.replace(
        "[0.0, 0.4, 0.7]", "[0.0, 0.3, 0.5, 0.7, 0.85]"))
    task = tasks(spec)[0]
    calls = []
    real_probe = friction._probe_depth

    def counted(*args, **kwargs):
        calls.append(1)
        return real_probe(*args, **kwargs)

    monkeypatch.setattr(friction, "_probe_depth", counted)
    skipped = evaluate_point(task)
    n_skipped = len(calls)
    seen = []

    def with_probe(result, options=None, **fit_options):
        ana = analyzer.analyze(result, options, **{**fit_options, "probe": True})
        seen.append(ana.options.probe)
        return ana

    monkeypatch.setattr(torquemod.api, "analyze", with_probe, raising=False)
    probed = evaluate_point(task)
    assert seen == [True] and len(calls) - n_skipped > n_skipped
    pd.testing.assert_frame_equal(skipped.drop(columns="point_wall_s"),
                                  probed.drop(columns="point_wall_s"), check_exact=True)
