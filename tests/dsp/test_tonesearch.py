"""The tone search's compiled kernels against plain Python written sample by sample."""

from __future__ import annotations

import math

import numpy as np
import pytest

from torquemod.dsp import numpyblas, projection, tonesearch

FS = 53.344


def _tones_one_sample_at_a_time(n, fs_hz, freqs_hz, orders):
    """The recurrence of :func:`tonesearch.tone_columns` one sample at a time: the phasor
    exact every 32 samples, rotated by one sample's angle between, its powers up to the
    highest order."""
    out = np.empty((n, 2 * len(freqs_hz) * len(orders)))
    half = (n - 1) / 2.0
    for f, freq in enumerate(freqs_hz):
        w = 2 * np.pi * freq
        cd, sd = math.cos(w / fs_hz), math.sin(w / fs_hz)
        c1 = s1 = 0.0
        for i in range(n):
            if i % 32 == 0:
                a = w * ((i - half) / fs_hz)
                c1, s1 = math.cos(a), math.sin(a)
            else:
                c1, s1 = c1 * cd - s1 * sd, s1 * cd + c1 * sd
            c, s = 1.0, 0.0
            for k in range(1, max(orders) + 1):
                c, s = c * c1 - s * s1, s * c1 + c * s1
                for j, order in enumerate(orders):
                    if order == k:
                        col = 2 * (f * len(orders) + j)
                        out[i, col], out[i, col + 1] = c, s
    return out


@pytest.mark.parametrize("n", [5, 32, 33, 323, 700])
@pytest.mark.parametrize("orders", [(1,), (1, 2, 3), (1, 3), (2,)])
def test_tone_columns_are_the_recurrence_bit_for_bit(n, orders):
    freqs = [1.93, 2.0, 2.0137]
    got = tonesearch.tone_columns(n, FS, freqs, orders)
    # the blocks of 32 samples rotated side by side: each sample by the same operations
    np.testing.assert_array_equal(got, _tones_one_sample_at_a_time(n, FS, freqs, orders))


@pytest.mark.skipif(numpyblas.addresses() is None or numpyblas.gesv_address() is None,
                    reason="numpy's BLAS or LAPACK is not reachable from compiled code")
@pytest.mark.parametrize("n", [322, 323])
@pytest.mark.parametrize("harmonics", [(), (2, 3)])
def test_removal_at_tone_is_removal_at_with_the_modulation_columns(n, harmonics):
    rng = np.random.default_rng(7)
    t = (np.arange(n) - (n - 1) / 2) / FS
    qt = np.linalg.qr(np.column_stack([t ** k for k in range(6)]))[0].T.copy()
    y = np.column_stack([np.cos(2 * np.pi * 2.01 * t) + 0.1 * rng.standard_normal(n),
                         np.sin(2 * np.pi * 2.01 * t) + 0.1 * rng.standard_normal(n)])
    r_y = y - qt.T @ (qt @ y)
    qy = qt @ r_y
    f = 2.0137
    # the columns as modulation_columns makes them: cos and sin of (k*w)*t, w = 2*pi*f
    m = np.column_stack([g(k * (2 * np.pi * f) * t) for k in (1, *harmonics)
                         for g in (np.cos, np.sin)])
    want = projection.removal_at(np.ascontiguousarray(m), qt, r_y, qy)
    got = projection.removal_at_tone(FS, f, (1, *harmonics), qt, r_y, qy)
    # libm's cos and sin in both (numpy's are libm's on x86-64 Linux), the second half of
    # the samples mirrored from the first: the same numbers
    np.testing.assert_array_equal(got, want)


def _job_sums_in_order(rows, k2):
    """:func:`tonesearch._explained`'s products of one frequency in plain Python: for each
    tone row a, its product with the residual (the last row), then with rows 0..a, each
    summed over the samples in order."""
    y = rows[k2].tolist()
    out = []
    for a in range(k2):
        xa = rows[a].tolist()
        for other in [y] + [rows[d].tolist() for d in range(a + 1)]:
            s = 0.0
            for u, v in zip(xa, other, strict=True):
                s += u * v
            out.append(s)
    return np.array(out)


@pytest.mark.parametrize("k2", [2, 4, 6])
def test_tone_dots_are_the_sums_in_sample_order(k2):
    rng = np.random.default_rng(k2)
    rows = rng.standard_normal((k2 + 1, 97)) * rng.uniform(0.1, 10.0, (k2 + 1, 1))
    n_jobs = k2 + k2 * (k2 + 1) // 2
    got = np.full(n_jobs, np.nan)
    tonesearch._tone_dots(rows, 0, k2, k2, got)
    want = _job_sums_in_order(rows, k2)
    assert np.array_equal(got, want)  # bit for bit: the same operations in the same order
    # and the eight-at-a-time route the other tone sizes take gives the same numbers
    job_a = np.array([a for a in range(k2) for _ in range(a + 2)], dtype=np.int64)
    job_d = np.array([d for a in range(k2) for d in [k2, *range(a + 1)]], dtype=np.int64)
    old = np.full(n_jobs, np.nan)
    for start in range(0, n_jobs, 8):
        if n_jobs - start > 4:
            tonesearch._dots8(rows, job_a, job_d, start, min(start + 8, n_jobs), old)
        else:
            tonesearch._dots4(rows, job_a, job_d, start, n_jobs, old)
    assert np.array_equal(got, old)
