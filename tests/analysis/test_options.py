"""Options are checked where they are given: wrong types and values raise one clear error
(a TypeError and an InputError at once), analyze() says what it wants, and library messages
speak Python (force=True) while the command line speaks flags (--force)."""

from __future__ import annotations

import pytest

import torquemod as tm
from torquemod._util.fsutil import check_output_dir
from torquemod.analysis.analyzer import FitOptions
from torquemod.demo import synthetic_result
from torquemod.errors import InputError, OptionError, OutputError
from torquemod.report import ReportOptions
from torquemod.testing import write_synthetic_experiment


@pytest.fixture(scope="module")
def result():
    return synthetic_result(seed=0)


@pytest.mark.parametrize(("options", "words"), [
    ({"weighted": "no"}, ("weighted", "True or False")),
    ({"weighted": 0}, ("weighted", "True or False")),
    ({"n_starts": 0}, ("n_starts", "at least one")),
    ({"n_starts": 2.5}, ("n_starts", "whole number")),
    ({"seed": "1"}, ("seed", "whole number")),
    ({"stiffness": "big"}, ("stiffness", "number")),
    ({"stiffness": -1.0}, ("stiffness", "> 0")),
    ({"onset_criterion": "fast"}, ("onset_criterion", "tan_ratio")),
])
def test_bad_fit_options_are_named(result, options, words):
    with pytest.raises(OptionError) as info:
        tm.analyze(result, **options)
    assert all(w in str(info.value) for w in words), str(info.value)
    assert isinstance(info.value, TypeError) and isinstance(info.value, InputError)


def test_good_options_pass_and_numpy_scalars_count():
    import numpy as np
    opts = FitOptions(weighted=np.bool_(False), n_starts=np.int64(3), stiffness=2, seed=1)
    assert opts.n_starts == 3
    with pytest.raises(OptionError, match="dpi"):
        ReportOptions(dpi="high")


def test_analyze_of_an_experiment_says_to_process_first(tmp_path):
    write_synthetic_experiment(tmp_path / "e", n_steps=4, n_cycles=1, seed=1)
    exp = tm.read_experiment(tmp_path / "e" / "experiment.toml")
    for given in (exp, str(tmp_path / "e" / "experiment.toml")):
        with pytest.raises(OptionError, match=r"tm\.process\(exp\) first"):
            tm.analyze(given)


def test_library_says_force_true_and_the_cli_says_force(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "x.txt").write_text("mine", encoding="utf-8")
    with pytest.raises(OutputError) as info:
        check_output_dir(out, force=False)
    assert "force=True" in str(info.value) and "--force" not in str(info.value)
    from torquemod._cli.output import one_line as _one_line
    assert "use --force" in _one_line(info.value) and "force=True" not in _one_line(info.value)


def test_no_message_cites_a_version_that_does_not_exist(tmp_path):
    (tmp_path / "r").mkdir()
    with pytest.raises(InputError) as info:
        tm.load(tmp_path / "r")
    assert "before 0." not in str(info.value) and "tm.save" in str(info.value)
