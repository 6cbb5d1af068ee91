"""``tm.load`` reads the analysis back from fit.json instead of fitting again: every field
of the rebuilt :class:`Analysis` (and of its fits) equals the saved one's, ``analyze`` is
not called, and a save of the loaded result writes the same fit.json. A folder whose fit
was written by another version or format is analysed again, with a warning."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

import torquemod as tm
from torquemod.demo import synthetic_result
from torquemod.results import folder as results_folder


def _same(a, b, where: str) -> None:
    """Deep equality (NaN equals NaN; arrays, frames, dataclasses field by field)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, pd.DataFrame):
        pd.testing.assert_frame_equal(a, b, obj=where)
    elif isinstance(a, np.ndarray) and where.endswith(".adhesion.best_s"):
        # the phase fit's curve is rebuilt from its law and parameters, not stored: equal
        # within results.folder.CURVE_RTOL (the mixing fraction comes back a few ulp apart)
        np.testing.assert_allclose(np.asarray(b), a, rtol=results_folder.CURVE_RTOL, atol=0,
                                   equal_nan=True, err_msg=where)
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, np.asarray(b), err_msg=where)
    elif isinstance(a, dict):
        assert sorted(a) == sorted(b), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and np.isnan(a):
        assert b is None or np.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


CASES = {
    "both fits": (dict(seed=3), dict(onset_criterion="either")),
    "velocity dependent": (dict(seed=5), dict(velocity_dependent=True)),
    "both fits skipped": (dict(seed=2, saturation_fractions=(0.003, 0.3, 0.55),
                               include_inertia=False), {}),
    "mu not determined": (dict(seed=4, saturation_fractions=(0.003, 0.1, 0.2, 0.3, 0.4)), {}),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_load_reads_the_saved_fit_without_fitting(case, tmp_path, monkeypatch):
    make, options = CASES[case]
    res = synthetic_result(**make)
    ana = tm.analyze(res, **options)
    tm.save(res, ana, tmp_path / "r", report=False)

    def refuse(*args, **kwargs):
        raise AssertionError("load called analyze")
    monkeypatch.setattr(results_folder, "analyze", refuse)
    res2, ana2 = tm.load(tmp_path / "r")
    _same(ana, ana2, "analysis")
    pd.testing.assert_frame_equal(res2.steps, res.steps)
    assert ana2.report() == ana.report()
    tm.save(res2, ana2, tmp_path / "again", report=False)
    first, second = (json.loads((tmp_path / d / "fit.json").read_text(encoding="utf-8"))
                     for d in ("r", "again"))
    first["source"].pop("results_dir")
    second["source"].pop("results_dir")
    assert second == first


def test_a_fit_of_an_older_format_is_computed_again(tmp_path):
    res = synthetic_result(seed=3)
    ana = tm.analyze(res)
    tm.save(res, ana, tmp_path / "r", report=False)
    state_path = tmp_path / "r" / "result.json"
    state = json.loads(state_path.read_text(encoding="utf-8"))
    del state["analysis"]["saved"], state["analysis"]["saved_with"]  # as written before
    state_path.write_text(json.dumps(state), encoding="utf-8")
    with pytest.warns(UserWarning, match="computed again"):
        _, ana2 = tm.load(tmp_path / "r")
    assert json.dumps(ana2.to_dict()) == json.dumps(ana.to_dict())


def test_a_damaged_fit_document_is_named(tmp_path):
    res = synthetic_result(seed=3)
    tm.save(res, tm.analyze(res), tmp_path / "r", report=False)
    path = tmp_path / "r" / "fit.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    del doc["onset"]
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(tm.InputError, match=r"fit\.json"):
        tm.load(tmp_path / "r")


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_phase_fit_curve_is_rebuilt_not_stored(case, tmp_path):
    """result.json leaves out the phase fit's 2001-point curve, derivable from its law and
    parameters (analysis.creeplaws.mixture_curve); the loaded curve equals the fitted one
    within 1e-12 relative, NaN where it is NaN."""
    make, options = CASES[case]
    res = synthetic_result(**make)
    ana = tm.analyze(res, **options)
    tm.save(res, ana, tmp_path / "r", report=False)
    saved = json.loads((tmp_path / "r" / "result.json").read_text())["analysis"]["saved"]
    if ana.phase_fit is None:
        assert saved["phase_fit"] is None
        return
    assert "best_s" not in saved["phase_fit"]["adhesion"]
    assert saved["phase_fit"]["adhesion"]["best_s_rebuilt"] is True
    fitted = ana.phase_fit.adhesion.best_s
    loaded = tm.load(tmp_path / "r")[1].phase_fit.adhesion.best_s
    assert loaded.shape == fitted.shape
    np.testing.assert_array_equal(np.isnan(loaded), np.isnan(fitted))
    ok = np.isfinite(fitted)
    assert np.max(np.abs(loaded[ok] / fitted[ok] - 1.0)) <= 1e-12


def test_a_curve_that_cannot_be_rebuilt_is_stored(tmp_path, monkeypatch):
    res = synthetic_result(seed=3)
    ana = tm.analyze(res)
    monkeypatch.setattr(results_folder, "mixture_curve", lambda law, params: None)
    tm.save(res, ana, tmp_path / "r", report=False)
    saved = json.loads((tmp_path / "r" / "result.json").read_text())["analysis"]["saved"]
    assert len(saved["phase_fit"]["adhesion"]["best_s"]) == ana.phase_fit.adhesion.best_s.size
    loaded = tm.load(tmp_path / "r")[1].phase_fit.adhesion.best_s
    np.testing.assert_array_equal(loaded, ana.phase_fit.adhesion.best_s)  # bit for bit
