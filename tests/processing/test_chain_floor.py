"""The chain's fast paths against straightforward references: the frequency search's
explained power by one compiled call on an orthonormal basis (dsp.projection) against a
least-squares fit per trial frequency, the per-length caches against fresh designs, the
noise statistic against an SVD, and whole cycles, with a speed wobble and without, against
the per-frequency route the chain used before."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import basis, filters, projection, tonesearch
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain, speedmodel, trackedorders
from torquemod.testing import SyntheticSpec, synthetic_recording

FS = 53.344


def _records(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two records (a torque and a wobbling wheel speed with a modulation near 2 Hz), the
    slow basis and tracked-order-like columns for ``n`` samples."""
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * t * (1 + 0.01 * t), [1, 2])
    y = np.column_stack([30 + 0.3 * t + 8 * np.cos(2 * np.pi * 2.013 * t + 0.3)
                         + 0.4 * np.cos(2 * np.pi * 4.026 * t) + rng.standard_normal(n),
                         30 * (1 + 0.002 * np.sin(2 * np.pi * 0.3 * t)) + 0.05 * np.cos(
                             2 * np.pi * 4.6 * t) + 2e-3 * np.cos(2 * np.pi * 2.013 * t - 0.1)
                         + 2e-3 * rng.standard_normal(n)])
    return y, slow, orders


def _explained_reference(y: np.ndarray, b: np.ndarray, m: np.ndarray) -> float:
    """The power the columns m explain beyond b: the drop of the residual sum of squares
    from the fit on b to the fit on [b, m], both by numpy's SVD least squares."""
    rss = []
    for design in (b, np.hstack([b, m])):
        scale = np.linalg.norm(design, axis=0)
        coef = np.linalg.lstsq(design / scale, y, rcond=None)[0]
        r = y - (design / scale) @ coef
        rss.append(float(r @ r))
    return rss[0] - rss[1]


@pytest.mark.parametrize("n,harmonics", [(323, ()), (323, (2, 3)), (690, (2,))])
def test_explained_power_is_the_drop_of_the_residual(n, harmonics):
    y, slow, orders = _records(n, n)
    removal = speedmodel._SlowOrdersRemoval(y, slow, orders, FS, harmonics)
    assert removal.qt is not None
    freqs = [1.97, 2.0, 2.013, 2.05]
    got = removal.explained_many([0, 1, 0, 1], freqs)
    for col, f, g in zip([0, 1, 0, 1], freqs, got, strict=True):
        m = speedmodel.modulation_columns(n, FS, f, harmonics)
        ref = _explained_reference(y[:, col], removal.b, m)
        # the residual sums of squares are ~1e3 (torque) and their difference ~1e4: SVD
        # least squares gives each to ~1e-13 relative; bound 1e-9 relative
        assert g == pytest.approx(ref, rel=1e-9)


def test_tone_columns_are_the_modulation_columns():
    for n in (7, 64, 323, 1001):
        got = tonesearch.tone_columns(n, FS, [1.9, 2.0137], (1, 2, 3))
        ref = np.hstack([speedmodel.modulation_columns(n, FS, f, (2, 3)) for f in (1.9, 2.0137)])
        # exact every 32 samples, rotated by one sample between (31 rotations of ~1 ulp, and
        # powers up to the 3rd); the direct evaluation rounds its own argument k*w*t, up to
        # 340 rad at 1001 samples (ulp 5.7e-14): 1.0e-13 measured there; bound 5e-13
        np.testing.assert_allclose(got, ref, rtol=0, atol=5e-13)


@pytest.mark.parametrize("compiled", [False, True])
def test_orthonormal_basis_spans_the_design(compiled):
    _, slow, orders = _records(323, 4)
    b = np.hstack([slow, orders])
    qt = projection.orthonormal_basis_t(filters.LstsqFactor.of(b), compiled=compiled)
    # CholeskyQR2 on a design of condition number ~1e6: orthonormal to rounding
    np.testing.assert_allclose(qt @ qt.T, np.eye(qt.shape[0]), rtol=0, atol=1e-13)
    bn = b / np.linalg.norm(b, axis=0)  # every column of the design lies in Q's span
    np.testing.assert_allclose(qt.T @ (qt @ bn), bn, rtol=0, atol=1e-13)


def test_compiled_orthonormal_basis_has_the_lapack_routes_span():
    _, slow, orders = _records(331, 5)
    fac = filters.LstsqFactor.of(np.hstack([slow, orders]))
    q_lapack = projection.orthonormal_basis_t(fac)
    q_compiled = projection.orthonormal_basis_t(fac, compiled=True)
    # the two bases differ by rounding times the condition number (~1e6); their
    # projections differ from an SVD's by ~3e-11 and from each other by 1.3-2e-12 here and
    # at 323 and 646 samples (measured): the bound 1e-11
    np.testing.assert_allclose(q_compiled.T @ q_compiled, q_lapack.T @ q_lapack, rtol=0,
                               atol=1e-11)
    singular = filters.LstsqFactor(fac.dn, fac.scale, np.zeros_like(fac.factor))
    assert projection.orthonormal_basis_t(singular, compiled=True) is None


def _old_explained_many(self, columns, frequencies_hz):
    """The route before dsp.projection: one refined least-squares solve on B per frequency."""
    out = []
    for col, f in zip(columns, frequencies_hz, strict=True):
        m = speedmodel.modulation_columns(self.y.shape[0], self.fs_hz, f, self.harmonics)
        r_m = m - self.b @ self.fac.solve(m)
        b = r_m.T @ self.r_y[:, col]
        out.append(float(b @ np.linalg.solve(r_m.T @ r_m, b)))
    return out


def test_refine_many_is_refine_per_record_and_the_solve_route():
    y, slow, orders = _records(323, 9)
    removal = speedmodel._SlowOrdersRemoval(y, slow, orders, FS, (2,))
    both = removal.refine_many([0, 1], [2.009, 2.02], tol_hz=1e-6)
    assert both == [removal.refine(0, 2.009), removal.refine(1, 2.02)]
    old = speedmodel._SlowOrdersRemoval(y, slow, orders, FS, (2,))
    old.explained_many = _old_explained_many.__get__(old)
    ref = old.refine_many([0, 1], [2.009, 2.02], tol_hz=1e-6)
    # the same search; the explained powers agree to ~1e-12 relative, which moves the last
    # parabolic step by ~1e-11 Hz (measured up to 1.2e-10 Hz on the chain's cycles)
    np.testing.assert_allclose(both, ref, rtol=0, atol=1e-9)
    assert abs(both[0] - 2.013) < 2e-3  # and it is the modulation's frequency


def test_per_length_designs_are_the_fresh_ones_read_only():
    n, f = 323, 2.0
    slow, base, fac = trackedorders._slow_and_base(n, FS, 1.2, f, 2, 5)
    np.testing.assert_array_equal(slow, filters.slow_basis(n, FS, 1.2, extra=2, degree=5))
    np.testing.assert_array_equal(base, trackedorders._order_base(n, FS, slow, f))
    fresh = filters.LstsqFactor.of(trackedorders._order_base(n, FS, slow, f))
    np.testing.assert_array_equal(fac.factor, fresh.factor)
    design, fac_w = basis._wide_band_design(n, FS, f, 0.8, 0, 5)
    for a in (slow, base, fac.factor, design, fac_w.factor):
        assert not a.flags.writeable
    assert trackedorders._slow_and_base(n, FS, 1.2, f, 2, 5)[1] is base  # cached


@pytest.mark.parametrize("spec", [SyntheticSpec(seed=5, speed_wobble=(), speed_wobble_rev=()),
                                  SyntheticSpec(seed=6, speed_wobble=((6e-3, 0.9, 0.1),
                                                                      (3e-3, 1.1, 1.0)))],
                         ids=["no-wobble", "wobble"])
def test_noise_kept_is_the_svds(spec):
    c = chain.process_cycle(synthetic_recording(spec), Rig(0.0675, 2.0), ProcessingConfig(),
                            where="t", nominal_hz=2.0)
    m = c.extra["speed_model"]
    d, n = m.design, m.design.shape[0]
    k = np.arange(n // 2 + 1)
    off = np.abs(k * m.fs_hz / n - m.modulation_hz)
    sel = k[(off <= 0.75) & (off > 1.5 * m.fs_hz / n)]
    v, power = speedmodel._hann_fourier(n, tuple(int(b) for b in sel))
    u = np.linalg.svd(d / np.linalg.norm(d, axis=0), full_matrices=False)[0]
    ref = float(np.mean(1 - ((u.T @ v) ** 2).sum(axis=0).reshape(2, -1).sum(axis=0) / power))
    # measured within 1e-12 relative of the SVD on the chain's cycles (condition ~1e6);
    # the normal equations' route was 2-6e-5 off. Bound 1e-10
    assert m.noise_depletion() == pytest.approx(ref, rel=1e-10)
    # the chain's value, from step 1's basis of the slow part and orders
    # (dsp.projection.powers_in_span): measured within 2e-12 of the route above
    assert c.extra["noise_kept"] == pytest.approx(ref, rel=1e-10)


@pytest.mark.parametrize("spec", [SyntheticSpec(seed=5, speed_wobble=(), speed_wobble_rev=()),
                                  SyntheticSpec(seed=6, speed_wobble=((6e-3, 0.9, 0.1),
                                                                      (3e-3, 1.1, 1.0))),
                                  SyntheticSpec(seed=8, n_revolutions=2.0)],
                         ids=["no-wobble", "wobble", "two-revolutions"])
@pytest.mark.parametrize("method", ["paper", "sinefit"])
def test_cycle_phase_is_the_solve_routes(spec, method, monkeypatch):
    rec, rig = synthetic_recording(spec), Rig(0.0675, 2.0)
    cfg = ProcessingConfig().with_phase_method(method)

    def run():
        c = chain.process_cycle(rec, rig, cfg, where="t", nominal_hz=2.0)
        return c, chain.cycle_phase(c, cfg, center_index=c.torque_filtered.size / 2)

    fast, (phase, se, _) = run()
    monkeypatch.setattr(speedmodel._SlowOrdersRemoval, "explained_many", _old_explained_many)
    ref, (phase_ref, se_ref, _) = run()
    # the bound: the phase within 1e-9 deg of the solve route (measured <= 2.3e-10)
    assert abs(phase - phase_ref) < 1e-9
    assert se == pytest.approx(se_ref, rel=1e-9)
    assert fast.modulation_hz == pytest.approx(ref.modulation_hz, rel=1e-10)
    assert fast.extra["slow_band_hz"] == ref.extra["slow_band_hz"]
