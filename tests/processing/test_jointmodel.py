"""The speed model's one-call fit (:mod:`torquemod.processing.jointmodel`,
:mod:`torquemod.dsp.jointfit`) against the numpy routes it replaces: bit for bit, since the
kernel repeats their arithmetic (the same library ``cos``/``sin``, the same BLAS calls, numpy's
pairwise sums)."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod._util.blas import one_blas_thread
from torquemod.dsp import filters
from torquemod.processing import chain, jointmodel

FS = 53.344


@pytest.mark.parametrize("seed", range(6))
def test_modulation_columns_are_numpys_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):  # odd and even lengths (a middle sample or none), any frequency
        n = int(rng.integers(2, 900))
        fs = float(rng.uniform(5.0, 5000.0))
        f = float(rng.uniform(1e-3, 0.5 * fs))
        harmonics = tuple(int(k) for k in rng.choice([2, 3, 4, 7], size=int(rng.integers(0, 3)),
                                                     replace=False))
        np.testing.assert_array_equal(
            jointmodel.modulation_columns(n, fs, f, harmonics),
            jointmodel.modulation_columns_reference(n, fs, f, harmonics))


def _channels(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    out = {}
    for name, level in (("torque_nm", 40.0), ("wheel_speed_rad_s", 30.0),
                        ("platform_speed_rad_s", 1.0), ("fz_n", 4000.0)):
        out[name] = (level + 0.01 * level * np.sin(2 * np.pi * 2.01 * t + rng.uniform(0, 6))
                     + 0.002 * level * np.sin(2 * np.pi * 0.3 * t)
                     + 1e-3 * level * rng.standard_normal(n))
    return out


@pytest.mark.parametrize("n", [323, 330])
def test_fit_with_the_step1_basis_has_the_numbers_of_the_methods(n):
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    ch = _channels(n, n)
    harmonics = (2, 3)
    with one_blas_thread():
        removal = chain._SlowOrdersRemoval(
            np.column_stack([ch["torque_nm"], ch["wheel_speed_rad_s"]]), slow, orders, FS,
            harmonics)
        assert removal.qt is not None
        fused = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, harmonics,
                                           basis_t=removal.qt)
        plain = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, harmonics)
        assert "noise_kept" in fused._parts and "noise_kept" not in plain._parts
        np.testing.assert_array_equal(fused.design, plain.design)
        np.testing.assert_array_equal(fused.coef, plain.coef)
        for name in ch:
            assert fused.mean(name) == float(plain.part(name, "slow").sum()) / n
            for which in ("modulation", "slow", "orders", "harmonics"):
                np.testing.assert_array_equal(fused.part(name, which),
                                              plain.part(name, which))
        kept = plain.noise_depletion(basis_t=removal.qt)
        assert 0.05 <= kept < 1.0
        assert fused.noise_depletion(basis_t=removal.qt) == kept
        # another basis object, or another half-width: computed by the method afresh
        assert fused.noise_depletion(basis_t=removal.qt.copy()) == kept
        assert fused.noise_depletion(half_width_hz=1.0, basis_t=removal.qt) == \
            plain.noise_depletion(half_width_hz=1.0, basis_t=removal.qt)
        # the variance ratio from the tone's residuals on the basis (a Schur complement)
        # against the refined fit on the whole design, and both against the SVD's residual:
        # the refined fit agrees with the SVD to ~1e-11 (SpeedModel.variance_factor), the
        # chain's cycles moved by at most 5e-12 (benchmarks/chain_numbers.py)
        assert fused.variance_factor() == pytest.approx(plain.variance_factor(), rel=1e-10)
        d = plain.design
        m, other = d[:, :2], d[:, 2:]
        r = m - other @ np.linalg.lstsq(other, m, rcond=None)[0]
        svd = np.trace(np.linalg.inv(r.T @ r)) / np.trace(np.linalg.inv(m.T @ m))
        assert fused.variance_factor() == pytest.approx(svd, rel=1e-10)
        assert fused.variance_factor() > 1.0  # the slow basis overlaps the modulation


def test_a_basis_of_another_shape_is_not_used():
    n = 323
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    ch = _channels(n, 5)
    with one_blas_thread():
        qt = chain._SlowOrdersRemoval(ch["torque_nm"][:, None], slow, orders[:, :2],
                                           FS).qt
        model = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, basis_t=qt)
        assert "noise_kept" not in model._parts
        assert model.noise_depletion(basis_t=qt) == \
            jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders).noise_depletion()


@pytest.mark.parametrize("seed", range(4))
def test_residual_powers_are_powers_in_span_bit_for_bit(seed):
    from torquemod.dsp import jointfit, projection
    rng = np.random.default_rng(seed)
    n, p, k, j = 200 + seed, 12, 2 + 2 * seed % 6, 10
    qt_b = np.linalg.qr(rng.standard_normal((n, p)))[0].T.copy()
    mt = rng.standard_normal((k, n))
    v = rng.standard_normal((n, j))
    got, made, g = jointfit._residual_powers(qt_b, mt, v)
    assert made
    np.testing.assert_array_equal(got, projection.powers_in_span(qt_b, mt.T, v))
    r = mt - (mt @ qt_b.T) @ qt_b
    np.testing.assert_allclose(g, r @ r.T, rtol=1e-13)
    # rows in the basis's span: declined, as powers_in_span
    inside = (qt_b.T @ rng.standard_normal((p, k))).T.copy()
    assert not jointfit._residual_powers(qt_b, inside, v)[1]
    assert projection.powers_in_span(qt_b, inside.T, v) is None


def test_a_basis_spanning_a_harmonic_falls_back_to_the_refined_ratio():
    # a basis that holds a harmonic's column: its residual on it is ~0, the Schur route and
    # the noise statistic decline, and the ratio is the refined fit's (bit for bit)
    n = 323
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    ch = _channels(n, 9)
    harm = jointmodel.modulation_columns(n, FS, 2.013, (2,))[:, 2:3]
    other = np.column_stack([slow, orders[:, :-1], harm])
    qt = np.ascontiguousarray(np.linalg.qr(other)[0].T)
    with one_blas_thread():
        model = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, (2,), basis_t=qt)
        plain = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, (2,))
    assert "noise_kept" not in model._parts
    assert model.variance_factor() == plain.variance_factor()


def test_modulation_harmonics_and_bins_near_by_their_conditions():
    # every harmonic k kept iff above the slow band, below 0.45 fs and clear of each
    # avoided frequency by more than two resolutions; every bin kept iff off the centre
    # by more than 1.5 bins and within the half-width (brute force over all k)
    fs, n = 53.344, 320
    res = fs / n
    for f_mod, above, avoid in ((2.0, 1.2, ()), (2.0, 1.2, (4.0 + res, 6.3)),
                                (0.9, 1.2, (2.7,)), (7.0, 0.2, (14.0,))):
        want = tuple(k for k in range(2, 6) if above < k * f_mod < 0.45 * fs
                     and all(abs(k * f_mod - g) > 2 * res for g in avoid))
        got = jointmodel.modulation_harmonics(f_mod, fs, n, 5, above_hz=above,
                                              avoid_hz=avoid)
        assert got == want
    for f_hz in (0.3, 2.0, 2.0137, 26.0):
        df = fs / n
        want = tuple(k for k in range(n // 2 + 1) if 1.5 * df < abs(k * df - f_hz) <= 0.5)
        assert jointmodel._bins_near(n, fs, f_hz, 0.5) == want


def test_hypot_is_numpys_bit_for_bit():
    # the C library's hypot behind np.hypot on float64, over magnitudes that over- and
    # underflow the plain formula and near-equal arguments
    rng = np.random.default_rng(7)
    x = rng.standard_normal(4000) * 10.0 ** rng.uniform(-200, 200, 4000)
    y = rng.standard_normal(4000) * 10.0 ** rng.uniform(-200, 200, 4000)
    y[::4] = x[::4] * rng.uniform(0.99, 1.01, 1000)
    for a, b in zip(x.tolist(), y.tolist(), strict=True):
        got = jointmodel.hypot(a, b)
        assert type(got) is float and got == float(np.hypot(a, b))
    assert jointmodel.hypot(0.0, 0.0) == 0.0
    assert jointmodel.hypot(float("inf"), float("nan")) == np.hypot(np.inf, np.nan)


def test_fit_given_stacked_columns_is_the_fit_of_the_dict():
    n = 327
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    ch = _channels(n, 5)
    with one_blas_thread():
        plain = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, (2, 3))
        stacked = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, (2, 3),
                                             columns=np.column_stack(list(ch.values())))
        # a stack of another shape is not taken: the dict decides
        wrong = jointmodel.fit_speed_model(ch, FS, 2.013, slow, orders, (2, 3),
                                           columns=np.zeros((n, 2)))
    for model in (stacked, wrong):
        np.testing.assert_array_equal(model.coef, plain.coef)
        for name in ch:
            assert model.mean(name) == plain.mean(name)
            c, s = plain.coef[:2, plain.names.index(name)]
            assert model.amplitude(name) == float(np.hypot(c, s))
