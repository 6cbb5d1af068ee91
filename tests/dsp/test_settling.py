"""The settling of several filters searched together against one filter at a time."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import filters, settling

FS = 53.344


def _designs(rng, count):
    """Notches at random frequencies and quality factors, band-passes of orders 1-3 and
    Butterworth high-passes of orders 1-2 (coefficient counts 2, 3, 5 and 7), shuffled."""
    out = []
    for i in range(count):
        kind = i % 4
        if kind == 0:
            out.append(filters.design_notch(rng.uniform(0.5, 20.0), rng.uniform(1.0, 30.0), FS))
        elif kind == 1:
            center = rng.uniform(1.0, 10.0)
            out.append(filters.design_bandpass(center, rng.uniform(0.1, 1.0), 1 + i % 3, FS))
        elif kind == 2:
            out.append(filters.design_bandpass(rng.uniform(1.0, 10.0), 0.3, 2, FS))
        else:
            b, a = filters.design_highpass(rng.uniform(0.05, 1.0), 1 + i % 2, FS)
            out.append((np.array(b), np.array(a)))
    return [out[j] for j in rng.permutation(count)]


@pytest.mark.parametrize("count", [1, 2, 3, 4, 7])
def test_longest_settling_is_the_largest_of_one_at_a_time(count):
    rng = np.random.default_rng(count)
    for _ in range(5):
        designs = _designs(rng, count)
        width = max(len(b) for b, _ in designs)
        bs = np.zeros((count, width))
        as_ = np.zeros((count, width))
        lengths = np.array([len(b) for b, _ in designs], dtype=np.int64)
        for f, (b, a) in enumerate(designs):
            bs[f, :len(b)] = b
            as_[f, :len(a)] = a
        want = [int(filters._settling_kernel(np.array(b, dtype=float), np.array(a, dtype=float),
                                             1e-6, 1_000_000)) for b, a in designs]
        assert settling.longest_settling(bs, as_, lengths, 1e-6, 1_000_000) == max(want)
        # a search cut short ends at its limit as the single search does
        short = [int(filters._settling_kernel(np.array(b, dtype=float),
                                              np.array(a, dtype=float), 1e-6, 300))
                 for b, a in designs]
        assert settling.longest_settling(bs, as_, lengths, 1e-6, 300) == max(short)


def test_three_responses_are_the_single_recurrences():
    """The three responses advancing together: each filter's samples bit for bit those of
    the single recurrence, also across a restart from the kept state."""
    rng = np.random.default_rng(0)
    designs = [filters.design_notch(4.6, 3.0, FS), filters.design_bandpass(2.0, 0.4, 2, FS),
               filters.design_notch(9.2, 3.0, FS)]
    b = np.zeros((3, 5))
    a = np.zeros((3, 5))
    fourth = np.zeros(3, dtype=bool)
    for s, (bb, aa) in enumerate(designs):
        b[s, :len(bb)] = bb
        a[s, :len(aa)] = aa
        fourth[s] = len(bb) == 5
    z = np.zeros((3, 4))
    h = np.full((3, 700), np.nan)
    cut = int(rng.integers(1, 699))
    settling._three_responses(b, a, fourth, z, h, 0, cut)
    settling._three_responses(b, a, fourth, z, h, cut, 700)
    for s, (bb, aa) in enumerate(designs):
        zs = np.zeros(len(bb) - 1)
        want = np.full(700, np.nan)
        filters._response_samples(np.array(bb), np.array(aa), zs, want, 0, 700)
        np.testing.assert_array_equal(h[s], want)
