"""The public API (issue 9): read_experiment/process/analyze/save/load, the manifest's
[processing] honoured by the library as by the CLI, the results folder's layout and its one
reader, and the newcomer fixes of the process/fit/report/demo commands."""

from __future__ import annotations

import ast
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import torquemod as tm
from torquemod.cli import main
from torquemod.demo import synthetic_result
from torquemod.errors import InputError
from torquemod.testing import write_synthetic_experiment

SRC = Path(tm.__file__).parent
ROOT = SRC.parent.parent


@pytest.fixture(scope="module")
def experiment(tmp_path_factory) -> Path:
    """Four steps of two cycles (synthetic recordings); returns the manifest."""
    d = tmp_path_factory.mktemp("api") / "exp"
    write_synthetic_experiment(d, n_steps=4, n_cycles=2, seed=5)
    return d / "experiment.toml"


@pytest.fixture(scope="module")
def processed(experiment, tmp_path_factory):
    """`torquemod process` run once (stage lines on), its output and the results folder."""
    import contextlib
    import io
    out = tmp_path_factory.mktemp("processed") / "out"
    err, std = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        rc = main(["process", str(experiment), "--out", str(out)])
    assert rc == 0, err.getvalue()
    return out, std.getvalue(), err.getvalue()


def _with_processing(manifest: Path, dest: Path, table: str) -> Path:
    shutil.copytree(manifest.parent, dest)
    path = dest / "experiment.toml"
    path.write_text(path.read_text(encoding="utf-8") + "\n" + table, encoding="utf-8")
    return path


# --------------------------------------------------------------------------- the API

def test_process_honours_the_manifests_processing_table(experiment, tmp_path, capsys):
    """The library used to run 'paper' where the manifest (and the CLI) said 'sinefit'."""
    manifest = _with_processing(experiment, tmp_path / "exp",
                                '[processing.phase]\nmethod = "sinefit"\n')
    exp = tm.read_experiment(manifest)
    assert exp.processing.phase.method == "sinefit"
    res = tm.process(exp)
    assert res.config.phase.method == "sinefit"
    from torquemod.processing.pipeline import process_experiment
    assert process_experiment(manifest).config.phase.method == "sinefit"
    # the CLI gives the same numbers
    assert main(["process", str(manifest), "--out", str(tmp_path / "out"), "--quiet",
                 "--no-fit"]) == 0
    capsys.readouterr()
    cli_res, cli_ana = tm.load(tmp_path / "out")
    assert cli_ana is None and cli_res.config.phase.method == "sinefit"
    np.testing.assert_array_equal(cli_res.cycles["phase_deg"], res.cycles["phase_deg"])
    # a keyword overrides the table, and the two methods differ, so the check above bites
    paper = tm.process(exp, phase_method="paper")
    assert paper.config.phase.method == "paper"
    assert np.abs(paper.cycles["phase_deg"] - res.cycles["phase_deg"]).max() > 1e-6


def test_read_experiment_reports_a_bad_processing_table(experiment, tmp_path):
    manifest = _with_processing(experiment, tmp_path / "exp", "[processing]\nnotch = 3\n")
    with pytest.raises(InputError, match=r"experiment\.toml"):
        tm.read_experiment(manifest)


def test_public_names():
    for name in tm.__all__:
        assert getattr(tm, name) is not None, name
    assert {"read_experiment", "process", "analyze", "save", "load", "twin"} <= set(tm.__all__)
    assert callable(tm.twin.run_simulation) and tm.twin.SimConfig


def test_save_load_round_trip_is_exact(tmp_path):
    res = synthetic_result(seed=3)
    ana = tm.analyze(res, onset_criterion="either")
    tm.save(res, ana, tmp_path / "r", report=False)
    res2, ana2 = tm.load(tmp_path / "r")
    pd.testing.assert_frame_equal(res2.steps, res.steps)
    pd.testing.assert_frame_equal(res2.cycles, res.cycles)
    assert res2.cycle_details == json.loads(json.dumps(list(res.cycle_details)))
    assert sorted(res2.traces) == sorted(res.traces)
    np.testing.assert_array_equal(res2.traces[(2, 3)]["torque_filtered_nm"],
                                  res.traces[(2, 3)]["torque_filtered_nm"])
    assert ana2.options.onset_criterion == "either"
    assert json.dumps(ana2.to_dict()) == json.dumps(ana.to_dict())
    saved = json.loads((tmp_path / "r" / "fit.json").read_text(encoding="utf-8"))
    assert saved == ana.to_dict(results_dir=str(tmp_path / "r"))


def test_fit_json_keys_and_compact_reprs():
    res = synthetic_result(seed=1)
    ana = tm.analyze(res)
    doc = ana.to_dict()
    for key in ("mu", "mu_stderr", "mu_determined", "mu_lower_bound", "fit_skipped",
                "mu_from_phase", "mu_from_phase_stderr", "mu_from_phase_interval_95",
                "mu_from_phase_determined", "saturation_torque_nm", "theory", "onset",
                "steps", "warnings", "fit_options", "converged", "parameters"):
        assert key in doc, key
    assert doc["mu"] == pytest.approx(0.24, rel=0.02)  # the synthetic truth
    assert ana.mu == doc["mu"] and ana.onset.step == doc["onset"]["step"] == 3
    json.dumps(doc, allow_nan=False)
    for text in (repr(res), repr(ana)):
        assert len(text) < 200 and "\n" not in text
    assert "<table" in res._repr_html_() and "mu" in ana._repr_html_()
    assert "[[Analysis]] synthetic" in ana.report()


def test_analyze_uses_the_rig_of_the_experiment_not_provenance():
    """The inertia comes from the experiment object: without it C is fitted."""
    with_j = tm.analyze(synthetic_result(seed=2))
    without = tm.analyze(synthetic_result(seed=2, include_inertia=False))
    assert with_j.theory.mode == "rig" and without.theory.mode == "fitted"
    assert tm.analyze(synthetic_result(seed=2, include_inertia=False),
                      inertia_kg_m2=4.0).theory.mode == "rig"


# --------------------------------------------------------------------------- the folder

def _damage(folder: Path, case: str) -> Path:
    """Damage one file; returns the path the error must name."""
    steps = folder / "steps.csv"
    if case == "no result.json":
        (folder / "result.json").unlink()
        return folder / "result.json"
    if case == "result.json garbage":
        (folder / "result.json").write_text("{not json", encoding="utf-8")
        return folder / "result.json"
    if case == "result.json wrong shape":
        doc = json.loads((folder / "result.json").read_text(encoding="utf-8"))
        del doc["experiment"]["rig"]
        (folder / "result.json").write_text(json.dumps(doc), encoding="utf-8")
        return folder / "result.json"
    if case == "text in a number column":
        df = pd.read_csv(steps, dtype=str)
        df.loc[2, "coa"] = "oops"
        df.to_csv(steps, index=False)
        return steps
    if case == "truncated row":
        lines = steps.read_text(encoding="utf-8").splitlines()
        steps.write_text("\n".join(lines[:-1]) + "\n", encoding="utf-8")
        return steps
    if case == "slip not a boolean":
        df = pd.read_csv(steps, dtype=str)
        df.loc[0, "slip"] = "maybe"
        df.to_csv(steps, index=False)
        return steps
    if case in ("radius as text", "fit option garbage"):
        doc = json.loads((folder / "result.json").read_text(encoding="utf-8"))
        if case == "radius as text":
            doc["experiment"]["rig"]["wheel_radius_m"] = "0.075 m"
        else:
            doc["analysis"] = {"options": {"n_starts": "many"}}
        (folder / "result.json").write_text(json.dumps(doc), encoding="utf-8")
        return folder / "result.json"
    if case == "fractional cycle count":
        df = pd.read_csv(steps, dtype=str)
        df.loc[1, "n_cycles"] = "2.5"
        df.to_csv(steps, index=False)
        return steps
    if case == "tables disagree":
        df = pd.read_csv(steps, dtype=str)
        df.loc[1, "step"] = "12"
        df.to_csv(steps, index=False)
        return folder
    if case == "no cycles.csv":
        (folder / "cycles.csv").unlink()
        return folder / "cycles.csv"
    if case == "traces garbage":
        (folder / "traces.npz").write_bytes(b"PK\x03\x04 not a zip")
        return folder / "traces.npz"
    raise AssertionError(case)


DAMAGE = ("no result.json", "result.json garbage", "result.json wrong shape",
          "text in a number column", "truncated row", "slip not a boolean", "no cycles.csv",
          "traces garbage", "radius as text", "fit option garbage", "fractional cycle count",
          "tables disagree")


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("saved") / "r"
    tm.save(synthetic_result(seed=0), None, d, report=False)
    return d


@pytest.mark.parametrize("case", DAMAGE)
def test_load_names_the_damaged_file(saved, tmp_path, case):
    d = tmp_path / "r"
    shutil.copytree(saved, d)
    where = _damage(d, case)
    with pytest.raises(InputError) as info:
        tm.load(d)
    assert str(where) in str(info.value)


@pytest.mark.parametrize("command", ["fit", "report"])
def test_fit_and_report_on_a_damaged_folder_exit_2_and_change_nothing(saved, tmp_path, capsys,
                                                                       command):
    d = tmp_path / "r"
    shutil.copytree(saved, d)
    where = _damage(d, "text in a number column")
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    assert main([command, str(d), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(where) in err[0] and "'coa'" in err[0]
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_fit_on_a_missing_folder_says_so_with_debug_after_the_subcommand(tmp_path, capsys):
    missing = tmp_path / "nonexistent"
    assert main(["fit", str(missing), "--debug"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"torquemod: error: {missing}: results folder does not exist; give the "
                   "--out folder of 'torquemod process'"]


# --------------------------------------------------------------------------- the commands

def test_process_names_the_report_and_times_its_stages(processed):
    out, stdout, stderr = processed
    lines = stdout.splitlines()
    assert f"report:  {out / 'report.html'}" in lines
    timing = [line for line in lines if line.startswith("done in ")]
    assert len(timing) == 1 and "processing 8 cycles" in timing[0] and "fit" in timing[0]
    assert "fitting the creep curve" in stderr and "writing the results folder" in stderr
    # the undetermined mu reaches stderr as a warning
    assert "warning: the creep points do not determine the friction coefficient" in stderr
    assert not re.search(r"\d\.\d{7,}", stdout)  # formatted numbers, not raw floats


def test_fit_takes_options_updates_the_report_and_prints_formatted(processed, tmp_path,
                                                                   capsys):
    d = tmp_path / "out"
    shutil.copytree(processed[0], d)
    old_report = (d / "report.html").read_text(encoding="utf-8")
    command = json.loads((d / "provenance.json").read_text(encoding="utf-8"))["command"]
    assert command
    assert "phase rise over the previous step" not in old_report
    assert main(["fit", str(d), "--onset-criterion", "phase"]) == 0
    cap = capsys.readouterr()
    doc = json.loads((d / "fit.json").read_text(encoding="utf-8"))
    assert doc["fit_options"]["onset_criterion"] == "phase"
    assert "phase rise over the previous step" in (d / "report.html").read_text(
        encoding="utf-8")  # the report is regenerated, not left stale
    assert "fitting the creep curve" in cap.err
    assert "warning: the creep points do not determine" in cap.err
    assert not re.search(r"\d\.\d{7,}", cap.out)
    assert f"updated {d}" in cap.out
    # provenance keeps the command that processed the data
    assert json.loads((d / "provenance.json").read_text(encoding="utf-8"))["command"] == command
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    _, ana = tm.load(d)
    assert ana.options.onset_criterion == "phase"


def test_error_line_is_not_written_on_the_progress_bar(experiment, tmp_path, capsys):
    d = tmp_path / "exp"
    shutil.copytree(experiment.parent, d)
    (d / "step3_cycle2.csv").write_text("time_s,torque_nm\n0,oops\n", encoding="utf-8")
    assert main(["process", str(d), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    last = err.rstrip("\n").split("\n")[-1]
    # the bar is cleared (carriage return) before the error line starts
    assert last.split("\r")[-1].startswith("torquemod: error: ")
    assert "step3_cycle2.csv" in last


@pytest.mark.parametrize("where", ["folder", "parent"])
def test_process_refuses_an_out_holding_its_inputs(experiment, tmp_path, capsys, where):
    d = tmp_path / "exp"
    shutil.copytree(experiment.parent, d)
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    out = d if where == "folder" else tmp_path
    assert main(["process", str(d / "experiment.toml"), "--out", str(out), "--force",
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "would replace the experiment's own file" in err[0]
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before


def test_interrupted_demo_leaves_nothing_behind(tmp_path, monkeypatch):
    from torquemod.demo import run_demo
    from torquemod.twins.vtrack import simulate

    def interrupted(config, out_dir, **kwargs):
        Path(out_dir).mkdir(parents=True)
        (Path(out_dir) / "experiment.toml").write_text("half", encoding="utf-8")
        raise KeyboardInterrupt

    monkeypatch.setattr(simulate, "run_simulation", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_demo(tmp_path / "demo", progress=False, quick=True)
    assert list(tmp_path.iterdir()) == []  # no half folder that blocks the rerun


def test_demo_says_why_mu_differs_from_the_peak():
    from torquemod._cli.output import why_they_differ as _why_they_differ
    truth = {"peak_coa": 0.2451, "mu0": 0.30, "mu_at_top_step": 0.262}
    text = _why_they_differ({"mu": 0.2563}, truth)
    assert "0.2563" in text and "0.2451" in text and "0.2620" in text
    assert "falls with the slip" in text and "peaks" in text


# --------------------------------------------------------------------------- the layout

def _module_imports(path: Path) -> set[str]:
    """torquemod modules imported at module level, TYPE_CHECKING blocks included (imports
    inside functions are not counted)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    rel = path.relative_to(SRC.parent).with_suffix("")
    package = list(rel.parts[:-1])  # a module's package; for __init__ the package itself
    out = set()
    body = [n for top in tree.body for n in (top.body if isinstance(top, ast.If) else [top])]
    for node in body:
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package[: len(package) - node.level + 1]
            mod = ".".join(base + ([node.module] if node.module else []))
            names = [f"{mod}.{a.name}" for a in node.names] if not node.module else [mod]
            out.update(names)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("torquemod"):
            out.add(node.module)
    return out


def test_import_graph_of_the_stages_has_no_cycles():
    """Module-level imports follow the data flow (pipeline -> analysis -> report -> layout ->
    api -> cli): no module imports one that imports it back."""
    modules = {}
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC.parent).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        modules[name] = path
    graph = {m: {i for i in _module_imports(p) if i in modules and i != m}
             for m, p in modules.items()}
    cycles = []

    def visit(m, stack):
        if m in stack:
            cycles.append([*stack[stack.index(m):], m])
            return
        for n in graph[m]:
            if n != "torquemod":  # the package itself re-exports only
                visit(n, [*stack, m])

    for m in ("torquemod.processing.pipeline", "torquemod.analysis.analyzer",
              "torquemod.results.folder",
              "torquemod.api", "torquemod.report", "torquemod.cli", "torquemod.demo"):
        visit(m, [])
    assert not cycles, cycles
    assert "torquemod.results.folder" not in graph["torquemod.processing.pipeline"]
    assert not {"torquemod.results.folder", "torquemod.api"} & graph["torquemod.analysis.analyzer"]


def test_trace_key_strings_live_only_in_the_results_folder_module():
    users = [p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py")
             if re.search(r"""["']s\{[a-z_.\[\]0-9]+\}c\{""", p.read_text(encoding="utf-8"))]
    assert users == ["results/folder.py"]


def _readme_block(heading: str) -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(rf"## {heading}.*?```python\n(.*?)```", text, re.S)
    assert block, f"README has a Python example under '{heading}'"
    return block[1]


def test_readme_python_api_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "readme"}
    exec(compile(_readme_block("The rig in Python"), "README.md", "exec"), namespace)
    assert (tmp_path / "my-results" / "report.html").is_file()
    ana, truth = namespace["ana"], namespace["truth"]
    # believable: both estimates of mu hold the truth the recordings were made with
    assert abs(ana.mu - truth["mu"]) < 3 * ana.mu_stderr + 1e-3
    lo, hi = ana.phase_fit.mu_interval_95
    assert lo - 1e-3 <= truth["mu"] <= hi + 1e-3
    assert "WARNING" not in capsys.readouterr().out  # nothing to warn about
    # the README's text quotes this run's numbers as they are
    steps = ana.steps
    quoted = [f"{steps['phase_deg'].iloc[0]:.1f}° to {steps['phase_deg'].iloc[-1]:.1f}°",
              f"μ = {ana.mu:.4f} ± {ana.mu_stderr:.4f}", f"{ana.mu_from_phase:.4f} (95 %",
              f"interval {lo:.4f}–{hi:.4f}", f"χ²/dof is {ana.polach.reduced_chi2:.2f}",
              f"Ts = μ·N·Rw = {ana.saturation_torque_nm:.2f} N·m",
              f"onset is step {ana.onset.step}", f"RMS of {ana.theory_difference[0]:.2f}°"]
    text = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    assert [q for q in quoted if q not in text] == []


def test_readme_train_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(_readme_block("The train in Python"), "README.md", "exec"),
         {"__name__": "readme"})
    assert (tmp_path / "my-onboard").is_dir()


def test_measurement_path_does_not_import_the_twin():
    """The measurement (read, process, analyze, save, report) never loads the twin's modules:
    torquemod.twins.vtrack.rig, torquemod.twins.vtrack.simulate and the rig-based
    torquemod.twins.vtrack.theory."""
    import subprocess
    import sys

    code = ("import sys, torquemod, torquemod.api, torquemod.analysis.analyzer, "
            "torquemod.processing.pipeline, torquemod.results.folder, torquemod.report, "
            "torquemod.analysis.phasefit, torquemod.analysis.fit\n"
            "print(sorted(m for m in sys.modules if m.startswith('torquemod.twins') or m in "
            "('torquemod.twins.vtrack.simulate', 'torquemod.twins.vtrack.theory')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_rig_tables_exported_as_mat_and_parquet_and_kept_current(tmp_path):
    """save(export=...) writes cycles/steps as .mat and .parquet beside the CSV; an update
    (torquemod fit) rewrites them with the new steps table."""
    from scipy.io import loadmat

    from torquemod.results.folder import update
    res = synthetic_result(seed=0)
    d = tmp_path / "r"
    tm.save(res, None, d, report=False, export="mat,parquet")
    steps_csv = pd.read_csv(d / "steps.csv")
    mat = loadmat(d / "steps.mat", simplify_cells=True)["steps"]
    np.testing.assert_array_equal(mat["phase_deg"], steps_csv["phase_deg"])
    pd.testing.assert_frame_equal(pd.read_parquet(d / "cycles.parquet"),
                                  pd.read_csv(d / "cycles.csv"), check_dtype=False)
    ana = tm.analyze(res)
    update(d, res, ana, report=False)
    from torquemod.results.export import mat_name
    mat = loadmat(d / "steps.mat", simplify_cells=True)["steps"]
    assert len(ana.steps.columns) > len(res.steps.columns)  # the analysis added columns
    assert set(mat) == {mat_name(c) for c in ana.steps.columns}
    assert list(pd.read_parquet(d / "steps.parquet").columns) == list(ana.steps.columns)
    with pytest.raises(InputError, match="unknown export format"):
        tm.save(res, None, tmp_path / "bad", export="xlsx")
    assert not (tmp_path / "bad").exists()
