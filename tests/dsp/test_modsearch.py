"""The modulation search in one compiled call (:mod:`torquemod.dsp.modsearch`) against the
calls it replaces one after the other: bit for bit, and None where one of them would go
another way."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod._util.blas import one_blas_thread
from torquemod.dsp import filters, modsearch, numpyblas
from torquemod.processing import speedmodel

FS = 53.344
KW = dict(band_hz=(1.5, 2.5), window="hann", detrend="linear", zero_pad=8)

pytestmark = pytest.mark.skipif(
    numpyblas.addresses() is None or numpyblas.gesv_address() is None,
    reason="numpy's BLAS or LAPACK is not reachable from compiled code")


def _removal(n: int, seed: int, f_hz: float, start_hz: float, harmonics=(2, 3)):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * t, [1, 2])
    wobble = 0.002 * np.sin(2 * np.pi * 0.3 * t + rng.uniform(0, 6))
    y = np.column_stack([
        40.0 + 0.4 * np.sin(2 * np.pi * f_hz * t + rng.uniform(0, 6)) + 0.05 * wobble
        + 0.01 * rng.standard_normal(n),
        30.0 + 0.3 * np.sin(2 * np.pi * f_hz * t + rng.uniform(0, 6)) + 30 * wobble
        + 0.01 * rng.standard_normal(n)])
    return speedmodel._SlowOrdersRemoval(y, slow, orders, FS, harmonics, start_hz=start_hz)


def _step_by_step(removal, start_hz: float, refine: bool):
    from torquemod.dsp.spectrum import peak_frequencies
    first = peak_frequencies(removal.at(start_hz), FS, **KW)
    f_mod = 0.5 * (first[0] + first[1])
    second = peak_frequencies(removal.at(f_mod), FS, **KW)
    refined = removal.refine_many([0, 1], second, tol_hz=1e-6) if refine else second
    return first, second, refined


@pytest.mark.parametrize("n", [322, 345])
@pytest.mark.parametrize("refine", [True, False])
@pytest.mark.parametrize("seed", range(3))
def test_search_is_the_calls_one_after_the_other_bit_for_bit(n, refine, seed):
    f_hz = 1.9 + 0.1 * seed + 0.0013 * n / 345
    with one_blas_thread():
        fused = _removal(n, seed, f_hz, 2.0).search(**KW, refine=refine, tol_hz=1e-6)
        plain = _step_by_step(_removal(n, seed, f_hz, 2.0), 2.0, refine)
    assert fused is not None
    for got, want in zip(fused, plain, strict=True):
        assert got == list(want)  # the same Python floats
    assert abs(fused[2][0] - f_hz) < 0.01  # and a search that found the tone


def test_search_hands_over_where_a_step_goes_another_way():
    with one_blas_thread():
        removal = _removal(345, 1, 2.0, 2.0)
        # another window than a name: peak_frequencies' route column by column
        assert removal.search(**{**KW, "window": ("tukey", 0.3)}, refine=True,
                              tol_hz=1e-6) is None
        # records of another layout
        first = np.asfortranarray(removal._at_start)
        assert modsearch.search_modulation(first, 2.0, removal.qt, removal.r_y, removal.qy,
                                           FS, np.array([1, 2, 3]), **KW, refine=True,
                                           tol_hz=1e-6) is None
        # no peak in the band: the step-by-step route raises its error
        assert removal.search(band_hz=(5.0, 6.0), window="hann", detrend="linear",
                              zero_pad=8, refine=True, tol_hz=1e-6) is None
        # once the search is made, the removal at the start was handed over
        assert removal.search(**KW, refine=True, tol_hz=1e-6) is not None
        assert removal._at_start is None
        assert removal.search(**KW, refine=True, tol_hz=1e-6) is None
