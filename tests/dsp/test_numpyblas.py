"""numpy's own BLAS called from compiled code (torquemod.dsp.numpyblas) against numpy's
``matmul`` bit for bit, and the compiled factorisation and speed-model fit that use it
against their numpy routes bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import lstsq, numpyblas
from torquemod.processing import speedmodel

BLAS = numpyblas.addresses()
needs_blas = pytest.mark.skipif(BLAS is None, reason="numpy's BLAS exports no CBLAS64 symbols")


def _design(rng, n, m):
    # columns of very different scales and a large common level: the chain's designs
    return rng.standard_normal((n, m)) * np.logspace(0, rng.uniform(0, 5), m) \
        + rng.uniform(-30, 30)


@needs_blas
@pytest.mark.parametrize("seed", range(4))
def test_products_equal_numpys_matmul_bit_for_bit(seed):
    syrk, gemm, gemv = BLAS
    rng = np.random.default_rng(seed)
    for _ in range(25):
        n, m, p = int(rng.integers(2, 700)), int(rng.integers(2, 45)), int(rng.integers(2, 9))
        a = _design(rng, n, m)
        if rng.integers(2):  # a buffer not aligned to 16 bytes
            a = _shifted(a)
        b = rng.standard_normal((n, p))
        c = np.asfortranarray(rng.standard_normal((m, p)))  # columns of stride 1
        d = rng.standard_normal((m, p))  # columns of stride p
        x, v = rng.standard_normal(m), rng.standard_normal(n)
        pairs = [(numpyblas.gram_t(a, syrk), a.T @ a),
                 (numpyblas.matmul_tn(a, b, gemm), a.T @ b),
                 (numpyblas.matmul(a, d, gemm), a @ d),
                 (numpyblas.matvec(a, x, gemv), a @ x),
                 (numpyblas.matvec_t(a, v, gemv), a.T @ v)]
        for k0, k1 in ((1, m), (0, 1), (1, 1), (m - 2, m)):  # column blocks (numpy: gemv
            # for two or more columns, its own loop for one, zeros for none)
            pairs.append((numpyblas.matvec(a[:, k0:k1], c[k0:k1, 1], gemv),
                          a[:, k0:k1] @ c[k0:k1, 1]))
            pairs.append((numpyblas.matvec(a[:, k0:k1], d[k0:k1, 1], gemv),
                          a[:, k0:k1] @ d[k0:k1, 1]))
        for got, want in pairs:
            np.testing.assert_array_equal(got, want)


def _shifted(a):
    """``a`` copied into a buffer 8 bytes off its allocation."""
    buf = np.empty(a.size + 1)
    out = buf[1:].reshape(a.shape)
    out[:] = a
    return out


@needs_blas
@pytest.mark.parametrize("seed", range(3))
def test_factor_equals_the_numpy_route(seed, monkeypatch):
    rng = np.random.default_rng(10 + seed)
    designs = [_design(rng, int(rng.integers(60, 500)), int(rng.integers(2, 35)))
               for _ in range(10)]
    fast = [lstsq.LstsqFactor.of(d, keep_gram=True) for d in designs]
    monkeypatch.setattr(numpyblas, "addresses", lambda: None)
    for d, f in zip(designs, fast, strict=True):
        ref = lstsq.LstsqFactor.of(d, keep_gram=True)
        for a, b in ((f.dn, ref.dn), (f.scale, ref.scale), (f.gram, ref.gram),
                     (np.triu(f.factor), np.triu(ref.factor))):
            np.testing.assert_array_equal(a, b)


@needs_blas
@pytest.mark.parametrize("seed", range(3))
def test_speed_model_fit_equals_the_numpy_route(seed, monkeypatch):
    rng = np.random.default_rng(20 + seed)
    n, fs = 323 + 17 * seed, 53.344
    t = np.arange(n) / fs
    slow = np.column_stack([np.ones(n)] + [np.cos(np.pi * k * t / t[-1]) for k in range(1, 9)])
    orders = np.column_stack([f(2 * np.pi * r * t) for r in (0.31, 0.62) for f in (np.cos, np.sin)])
    chans = {"torque_nm": 40 + np.cos(2 * np.pi * 2 * t) + 0.1 * rng.standard_normal(n),
             "wheel_speed_rad_s": 30 + 2e-3 * np.sin(2 * np.pi * 2 * t + 0.3)
             + 1e-3 * np.cos(0.4 * t) + 1e-5 * rng.standard_normal(n),
             "platform_speed_rad_s": 12 + 1e-4 * rng.standard_normal(n)}
    harmonics = (2, 3) if seed else ()
    fast = speedmodel.fit_speed_model(chans, fs, 2.0, slow, orders, harmonics)
    stats = fast.variance_factor(), fast.noise_depletion()
    monkeypatch.setattr(numpyblas, "addresses", lambda: None)
    ref = speedmodel.fit_speed_model(chans, fs, 2.0, slow, orders, harmonics)
    np.testing.assert_array_equal(fast.coef, ref.coef)
    for name in chans:
        for which in ("slow", "orders", "harmonics"):
            np.testing.assert_array_equal(fast.part(name, which), ref.part(name, which))
    assert stats == (ref.variance_factor(), ref.noise_depletion())
    assert stats[0] > 1.0  # (not the floor)


@needs_blas
def test_matmul_any_and_matvec_follow_numpys_layout_rules():
    _, gemm, gemv = BLAS
    rng = np.random.default_rng(30)
    for _ in range(20):
        n, m, p = int(rng.integers(2, 500)), int(rng.integers(2, 30)), int(rng.integers(2, 9))
        for a in (_design(rng, n, m), np.asfortranarray(_design(rng, n, m))):
            for b in (rng.standard_normal((m, p)), np.asfortranarray(rng.standard_normal((m, p)))):
                np.testing.assert_array_equal(numpyblas.matmul_any(a, b, gemm), a @ b)
            x = rng.standard_normal((m, 3))[:, 1]  # a strided vector
            np.testing.assert_array_equal(numpyblas.matvec(a, x, gemv), a @ x)


def test_vector_sum_is_numpys_pairwise_sum():
    rng = np.random.default_rng(31)
    for n in [*range(1, 300), 511, 1024, 1029, 4097, 20011]:
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3, n) + rng.uniform(-50, 50)
        assert numpyblas.vector_sum(a) == a.sum()
