"""The ``Examples`` sections of the docstrings run and give what they show (pytest does not
collect doctests here: ``--doctest-modules`` is not in the configuration).

Every module of the packages whose docstrings hold examples is collected; the
modules listed in :data:`MUST_HAVE` must keep theirs (so that the collection cannot go
silently empty). Examples are meant to be cheap (well under 0.2 s each): nothing here
compiles a numba kernel or reads a file.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

#: packages whose modules are searched for examples
PACKAGES = ("torquemod.analysis", "torquemod.dsp", "torquemod.fleet", "torquemod.io",
            "torquemod.ontrain", "torquemod.processing", "torquemod.report",
            "torquemod.results", "torquemod.sweep", "torquemod.twins", "torquemod._util")
#: modules that must hold examples: the equation modules and the ones each stage leans on
MUST_HAVE = ("torquemod.analysis.contact.polach", "torquemod.analysis.contact.kalker",
             "torquemod.analysis.contact.hertz", "torquemod.analysis.creep",
             "torquemod.analysis.polachcurve", "torquemod.analysis.polachshape",
             "torquemod.dsp.phase", "torquemod.dsp.filters", "torquemod.io.channels",
             "torquemod.ontrain.window", "torquemod.ontrain.quality",
             "torquemod.sweep.evaluate", "torquemod.processing.chain")


def _modules_with_examples() -> list[str]:
    names = []
    for top in PACKAGES:
        pkg = importlib.import_module(top)
        for info in pkgutil.walk_packages(pkg.__path__, top + "."):
            module = importlib.import_module(info.name)
            if any(t.examples for t in doctest.DocTestFinder().find(module)):
                names.append(info.name)
    return names


MODULES = _modules_with_examples()


def test_collection_holds_the_required_modules():
    missing = sorted(set(MUST_HAVE) - set(MODULES))
    assert not missing, f"these modules lost their examples: {missing}"


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    failed, attempted = doctest.testmod(module, optionflags=doctest.ELLIPSIS, verbose=False)
    assert attempted > 0, f"{name} has no examples"
    assert failed == 0, f"{failed} of {attempted} examples in {name} failed"
