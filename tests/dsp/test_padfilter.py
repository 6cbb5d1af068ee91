"""Steps 3-5 in one compiled call (torquemod.dsp.padfilter) against the tone model's padding
and the zero-phase cascade called one after the other."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from torquemod.dsp import filters, padfilter

FS = 53.344  # the chain's rate [Hz]


def _case(n: int, seed: int):
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    wheel = 2e-3 * np.cos(2 * np.pi * 2.01 * t) + 0.05 * np.cos(2 * np.pi * 4.6 * t) \
        + 0.01 + 1e-3 * t + 1e-4 * rng.standard_normal(n)
    torque = 8 * np.cos(2 * np.pi * 2.01 * t + 0.3) + 0.5 + rng.standard_normal(n)
    hp = filters.design_highpass(0.5, 2, FS)
    bp = filters.design_bandpass(2.01, 0.6, 2, FS)
    notches = [filters.design_notch(f, 30.0, FS) for f in (4.6, 9.2)]
    pad = max(filters.settling_samples(ba) for ba in [hp, bp, *notches])
    return wheel, torque, [2.01, 4.6, 9.2], pad, notches, [hp, bp]


@pytest.mark.parametrize("n,seed", [(323, 0), (322, 1), (690, 2)])
def test_equal_to_the_tone_model_and_the_cascade(n, seed):
    wheel, torque, tones, pad, notches, common = _case(n, seed)
    got = padfilter.padded_and_filtered(wheel, torque, FS, tones, pad, notches, common)
    ref = padfilter.padded_and_filtered_reference(wheel, torque, FS, tones, pad, notches,
                                                  common)
    assert got[1] == ref[1] and got[3] == ref[3]  # the levels: the same solve
    for g, r in ((got[0], ref[0]), (got[2], ref[2]), (got[4], ref[4])):
        # the data: the same operations, bit for bit; the padding: the tones' product by a
        # compiled matrix-vector product, equal here and at most a few ulp of the padding
        np.testing.assert_array_equal(g[..., pad:pad + n], r[..., pad:pad + n])
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-13 * np.abs(r).max())


def test_no_tones_and_no_own_filters():
    wheel, torque, _, pad, _, common = _case(323, 3)
    got = padfilter.padded_and_filtered(wheel, torque, FS, [], pad, [], common)
    ref = padfilter.padded_and_filtered_reference(wheel, torque, FS, [], pad, [], common)
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_array_equal(g, r)


def test_a_filter_of_another_kind_takes_the_reference_route():
    wheel, torque, tones, pad, notches, common = _case(323, 4)
    b, a = common[0]
    scaled = (2.0 * np.asarray(b), 2.0 * np.asarray(a))  # a[0] = 2: lfilter's general case
    got = padfilter.padded_and_filtered(wheel, torque, FS, tones, pad, notches,
                                        [scaled, common[1]])
    ref = padfilter.padded_and_filtered_reference(wheel, torque, FS, tones, pad, notches,
                                                  [scaled, common[1]])
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_array_equal(g, r)


def _old_route(wheel, torque, f_mod, notches_hz, q, hp_cfg, bp_cfg, offsets):
    """The chain's former steps 3-5: designs and settling in Python, then the compiled
    padding and filtering, then the cut."""
    hp = filters.design_highpass(*hp_cfg, FS)
    bp = filters.design_bandpass(f_mod, *bp_cfg, FS)
    notches = [filters.design_notch(f0, q, FS) for f0 in notches_hz]
    pad = max(filters.settling_samples(ba) for ba in [hp, bp, *notches])
    n = wheel.size
    p1, l1, p2, l2, both = padfilter.padded_and_filtered(
        wheel, torque, FS, [f_mod, *notches_hz], pad, notches, [hp, bp])
    return (p1[pad:pad + n] + l1 + offsets[0], p2[pad:pad + n] + l2 + offsets[1],
            both[:, pad:pad + n], pad)


@pytest.mark.parametrize("n,seed,notches_hz", [(323, 5, [4.6, 9.2]), (410, 6, [4.6]),
                                               (323, 7, [])])
def test_chain_filtered_is_the_former_route_bit_for_bit(n, seed, notches_hz):
    wheel, torque, *_ = _case(n, seed)
    args = (2.01, notches_hz, 3.0, (0.1, 2), (0.36, 2), (30.0, -4.0))
    got = padfilter.chain_filtered(wheel, torque, FS, *args)
    old = _old_route(wheel, torque, *args)
    ref = padfilter.chain_filtered_reference(wheel, torque, FS, *args)
    assert got[3] == old[3] == ref[3]  # the padding: the filters' longest settling
    for g, o, r in zip(got[:3], old[:3], ref[:3], strict=True):
        np.testing.assert_array_equal(g, o)
        # numpy's padding product against the compiled one: a few ulp of the padding
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-12 * np.abs(r).max())


def test_chain_filtered_takes_the_reference_route_where_the_fit_needs_the_svd():
    wheel, torque, *_ = _case(3, 8)  # 3 samples, 4 columns: potrf fails, lstsq's SVD
    args = (2.01, [4.6, 9.2], 3.0, (0.1, 2), (0.36, 2), (0.0, 0.0))
    got = padfilter.chain_filtered(wheel, torque, FS, *args)
    ref = padfilter.chain_filtered_reference(wheel, torque, FS, *args)
    for g, r in zip(got, ref, strict=True):
        np.testing.assert_array_equal(g, r)


def test_chain_filtered_refuses_a_band_pass_beyond_nyquist():
    wheel, torque, *_ = _case(323, 9)
    with pytest.raises(ValueError, match="does not fit"):
        padfilter.chain_filtered(wheel, torque, FS, 26.6, [], 3.0, (0.1, 2), (0.36, 2),
                                 (0.0, 0.0))


def test_compiled_bandpass_design_is_the_python_one_bit_for_bit():
    # random band edges and orders 1-4: the compiled design's complex arithmetic against
    # CPython's (design_bandpass's route), and both against scipy to rounding
    rng = np.random.default_rng(11)
    for _ in range(400):
        order = int(rng.integers(1, 5))
        lo = float(rng.uniform(1e-3, 0.2))
        hi = lo + float(rng.uniform(1e-3, 0.25))
        b, a = padfilter._butter_bandpass_compiled(order, lo, hi,
                                                   padfilter.bandpass_gain(order, lo, hi))
        b_ref, a_ref = filters._butter_bandpass(order, lo, hi)
        np.testing.assert_array_equal(b, b_ref)
        np.testing.assert_array_equal(a, a_ref)
    b_sp, a_sp = signal.butter(order, [lo, hi], "bandpass", fs=1.0)
    np.testing.assert_allclose(a, a_sp, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b, b_sp, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("k,start", [(1, 0), (3, -1008), (4, 5), (6, -77)])
def test_tones_filled_together_are_the_tone_models_bit_for_bit(k, start):
    from torquemod.dsp import tonemodel
    omegas = 2 * np.pi * np.linspace(0.13, 9.7, k) / FS
    want = np.empty((2339, 2 * k + 2))
    got = np.empty((2339, 2 * k + 2))
    tonemodel._fill_cos_sin(want, 2, omegas, start)
    padfilter._fill_cos_sin_together(got, 2, omegas, start)
    np.testing.assert_array_equal(got[:, 2:], want[:, 2:])


@pytest.mark.parametrize("read_only", [True, False])
def test_chain_filtered_takes_the_parts_off_as_numpy_does(read_only):
    wheel, torque, *_ = _case(323, 12)
    rng = np.random.default_rng(12)
    parts = [30.0 + rng.standard_normal(323) for _ in range(3)]
    for p in parts:
        p.setflags(write=not read_only)
    args = (2.01, [4.6, 9.2], 3.0, (0.1, 2), (0.36, 2), (30.0, -4.0))
    want = padfilter.chain_filtered(wheel - parts[0] - parts[1] - parts[2],
                                    torque - parts[2], FS, *args)
    got = padfilter.chain_filtered(wheel, torque, FS, *args, first_less=tuple(parts),
                                   second_less=(parts[2],))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    mixed = padfilter.chain_filtered(wheel, torque, FS, *args,  # parts of two kinds
                                     first_less=(parts[0], parts[1].copy(), parts[2]),
                                     second_less=(parts[2],))
    for g, w in zip(mixed, want, strict=True):
        np.testing.assert_array_equal(g, w)
