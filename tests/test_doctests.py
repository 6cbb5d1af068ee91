"""The ``Examples`` sections of the equation modules' docstrings run and give what they show
(pytest does not collect doctests here: ``--doctest-modules`` is not in the configuration)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ("torquemod.analysis.contact.polach", "torquemod.analysis.contact.kalker",
           "torquemod.analysis.contact.hertz",
           "torquemod.analysis.creep", "torquemod.analysis.polachcurve",
           "torquemod.dsp.phase")


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    failed, attempted = doctest.testmod(module, optionflags=doctest.ELLIPSIS, verbose=False)
    assert attempted > 0, f"{name} has no examples"
    assert failed == 0, f"{failed} of {attempted} examples in {name} failed"
