"""The golden numbers: every numeric field of fit.json, steps.csv, cycles.csv,
track.parquet, a fleet's tables and sweep.parquet on a small fixed experiment equals the
stored one (tests/golden/golden.json, written by tests/golden/regen.py).

Tolerance: relative 1e-9 (absolute 0). On the machine that wrote golden.json the numbers
are bit-for-bit equal; the 1e-9 leaves room for another CPU's BLAS kernels and SIMD paths,
which reorder floating-point sums (a few ulp, amplified by the fits' condition numbers to
well under 1e-9 here). Regenerate with ``python tests/golden/regen.py`` only for a change
meant to move the numbers.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
RTOL = 1e-9


def _regen():
    spec = importlib.util.spec_from_file_location("golden_regen", HERE / "regen.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def computed(tmp_path_factory):
    return _regen().compute(tmp_path_factory.mktemp("golden"))


def _flat(output: dict) -> dict:
    out = {}
    for key, value in output.items():
        if isinstance(value, list):
            out.update({f"{key}[{i}]": v for i, v in enumerate(value)})
        else:
            out[key] = value
    return out


GOLDEN = json.loads((HERE / "golden.json").read_text())


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_numbers_equal_the_golden_ones(computed, name):
    want, got = _flat(GOLDEN[name]), _flat(computed[name])
    assert sorted(got) == sorted(want), f"{name}: fields differ"
    bad = []
    for key, w in want.items():
        g = got[key]
        if w is None or g is None:
            if not (w is None and g is None):
                bad.append((key, w, g))
        elif not math.isclose(g, w, rel_tol=RTOL, abs_tol=0.0):
            bad.append((key, w, g))
    assert not bad, f"{name}: {len(bad)} of {len(want)} numbers moved, e.g. {bad[:5]}"
