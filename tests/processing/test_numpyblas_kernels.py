"""The chain's kernels built on numpy's own BLAS (torquemod.dsp.numpyblas) against the
numpy routes they replace, bit for bit: the tracked rotation orders, step 1's removal of the
slow part and orders, and whole cycles."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import blockbasis, modsearch, numpyblas, projection
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain, speedmodel, trackedorders
from torquemod.testing import SyntheticSpec, synthetic_recording

needs_blas = pytest.mark.skipif(numpyblas.addresses() is None,
                                reason="numpy's BLAS exports no CBLAS64 symbols")
SPECS = [SyntheticSpec(seed=5, speed_wobble=(), speed_wobble_rev=()),
         SyntheticSpec(seed=6, speed_wobble=((6e-3, 0.9, 0.1), (3e-3, 1.1, 1.0))),
         SyntheticSpec(seed=7, creepage_rate_per_s=2e-4),
         SyntheticSpec(seed=8, n_revolutions=2.0)]


@needs_blas
@pytest.mark.parametrize("spec", SPECS, ids=["no-wobble", "wobble", "ramp", "two-revolutions"])
def test_cycle_is_the_numpy_routes_bit_for_bit(spec, monkeypatch):
    rec, rig = synthetic_recording(spec), Rig(0.0675, 2.0)
    cfg = ProcessingConfig().with_phase_method("sinefit")
    used = []
    kernel = trackedorders._both_orders_fwl  # (the tracked orders by the slow design's
    # orthonormal basis: no numpy BLAS of its own, the same numbers either way)

    def spy(*args):
        out = kernel(*args)
        used.append(out[3])
        return out

    monkeypatch.setattr(trackedorders, "_both_orders_fwl", spy)
    removed = []

    def spy_on(module, name, made):
        routine = getattr(module, name)

        def spy_at(*args):
            out = routine(*args)
            removed.append((name, made(out)))
            return out

        monkeypatch.setattr(module, name, spy_at)

    # at the nominal frequency (with the basis), then at the frequency of the first peaks:
    # within step 1's search in one compiled call (dsp.modsearch; removal_at_tone called
    # from Python only where that search hands over)
    spy_on(blockbasis, "removal_basis_at", lambda out: out is not None and out[3] is not None)
    spy_on(projection, "removal_at_tone", lambda out: out is not None)
    spy_on(modsearch, "_search_kernel", lambda out: out[0] == 0)

    def run():
        c = chain.process_cycle(rec, rig, cfg, where="t", nominal_hz=2.0)
        return c, chain.cycle_phase(c, cfg, center_index=c.torque_filtered.size / 2)

    fast, (phase, se, _) = run()
    assert used and all(s == 0 for s in used)  # the kernels ran, and decided
    assert removed == [("removal_basis_at", True), ("_search_kernel", True)]
    monkeypatch.setattr(numpyblas, "addresses", lambda: None)
    ref, (phase_ref, se_ref, _) = run()
    assert phase == phase_ref
    # the variance factor under the standard error: with step 1's basis, from a Schur
    # complement of the modulation's residuals on it (dsp.jointfit), not the refined fit of
    # the numpy route; variance factors <= 5e-12 relative apart on benchmarks/
    # chain_numbers.py's cycles, the standard error (its square root) half that
    assert se == pytest.approx(se_ref, rel=1e-11)
    assert fast.modulation_hz == ref.modulation_hz
    m, m_ref = fast.extra["speed_model"], ref.extra["speed_model"]
    np.testing.assert_array_equal(m.design, m_ref.design)
    np.testing.assert_array_equal(m.coef, m_ref.coef)


@needs_blas
@pytest.mark.parametrize("seed", range(3))
def test_removal_is_the_numpy_route(seed, monkeypatch):
    rng = np.random.default_rng(40 + seed)
    n, fs = 323 + 29 * seed, 53.344
    t = np.arange(n) / fs
    slow = np.asfortranarray(np.column_stack([np.cos(np.pi * k * t / t[-1]) for k in range(12)]))
    orders = np.column_stack([f(2 * np.pi * r * t + 0.1 * np.sin(0.3 * t))
                              for r in (0.3, 0.6) for f in (np.cos, np.sin)])
    y = np.column_stack([40 + np.cos(2 * np.pi * 2.1 * t) + 0.3 * rng.standard_normal(n),
                         30 + 1e-3 * np.sin(2 * np.pi * 2.1 * t) + 1e-4 * rng.standard_normal(n)])
    harmonics = (2,) if seed else ()
    fast = speedmodel._SlowOrdersRemoval(y, slow, orders, fs, harmonics)
    assert projection.removal_at(speedmodel.modulation_columns(n, fs, 2.0, harmonics),
                                 fast.qt, fast.r_y, fast.qy) is not None
    got = [fast.at(f) for f in (2.0, 2.1)]
    # at the start frequency: made with the basis in one compiled call, handed over once,
    # then by removal_at; the same numbers every time
    fused = speedmodel._SlowOrdersRemoval(y, slow, orders, fs, harmonics, start_hz=2.0)
    assert fused._at_start is not None
    for _ in range(2):
        np.testing.assert_array_equal(fused.at(2.0), got[0])
    assert fused._at_start is None
    monkeypatch.setattr(numpyblas, "addresses", lambda: None)
    ref = speedmodel._SlowOrdersRemoval(y, slow, orders, fs, harmonics)
    for a, b in ((fast.qt, ref.qt), (fast.r_y, ref.r_y), (fast.qy, ref.qy)):
        np.testing.assert_array_equal(a, b)
    for g, f in zip(got, (2.0, 2.1), strict=True):
        np.testing.assert_array_equal(g, ref.at(f))
    # the refinement in one compiled call against its steps one call each
    peaks = [2.1 + 0.004 * (seed - 1), 2.1 - 0.003]
    duration = n / fs
    for tol in (1e-6, 1e-9):
        assert fast.refine_many([0, 1], peaks, tol_hz=tol) == \
            fast._refine_steps([0, 1], peaks, duration, tol)


def test_gesv_is_numpys_solve():
    gesv = numpyblas.gesv_address()
    if gesv is None:
        pytest.skip("numpy's LAPACK exports no dgesv64")
    rng = np.random.default_rng(41)
    for k2 in (2, 4, 6, 8):
        a = rng.standard_normal((k2, k2)) + k2 * np.eye(k2)
        b = rng.standard_normal((k2, 2))
        ints = np.array([k2, 2, k2, k2, 0], dtype=np.int64)
        af, bf, ipiv = np.asfortranarray(a), np.asfortranarray(b), np.zeros(k2, dtype=np.int64)
        import ctypes
        p = ints.ctypes.data
        ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * 8)(gesv)(
            p, p + 8, af.ctypes.data, p + 16, ipiv.ctypes.data, bf.ctypes.data, p + 24, p + 32)
        np.testing.assert_array_equal(bf, np.linalg.solve(a, b))
