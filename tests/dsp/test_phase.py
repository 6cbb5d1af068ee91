"""Step 7 (torquemod.dsp.phase): the phase lag of the wheel speed behind the torque.

References: injected lags on analytic sinusoids, the closed form of parabolic interpolation on
a sampled cosine, and the Cramér-Rao bound (FACTS.md §5) checked by Monte Carlo.
Sign convention: phase > 0 when the wheel signal lags the torque.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from torquemod.dsp.phase import (
    extrema_times,
    local_noise_psd,
    parabolic_vertex,
    peak_valley_phase,
    phase_crb_deg,
    sinefit_phase,
    whole_period_window,
)
from torquemod.errors import ProcessingError

FS = 53.344  # chain rate [Hz]: 26.7 samples per 2 Hz period
N_REC = round(6.5 * FS)
T = np.arange(N_REC) / FS
CENTER_S = T[-1] / 2

LAGS_DEG = (-30.0, 0.0, 5.0, 45.0, 80.0)
# nominal 2 Hz and off it by a few mHz (the modulation is whatever step 1 measured)
FREQS_HZ = (2.0, 2.0037, 1.9968)


def _pair(f_hz: float, lag_deg: float, theta: float, *, a_t: float = 8.0, a_w: float = 0.05,
          dc_w: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Torque A cos(wt + theta) and a wheel speed lagging it by lag_deg."""
    w = 2 * np.pi * f_hz * T
    return (a_t * np.cos(w + theta) + 12.0,
            a_w * np.cos(w + theta - np.radians(lag_deg)) + dc_w)


# --------------------------------------------------------------------------- interpolation


def test_parabolic_vertex_is_exact_for_a_parabola():
    rng = np.random.default_rng(0)
    x0 = rng.uniform(-0.5, 0.5, 200)
    a = rng.choice([-1.0, 1.0], 200) * rng.uniform(0.1, 10.0, 200)
    c = rng.uniform(-5.0, 5.0, 200)

    def y(x):
        return a * (x - x0) ** 2 + c

    d = parabolic_vertex(y(-1.0), y(0.0), y(1.0))
    np.testing.assert_allclose(d, x0, rtol=0, atol=1e-12)  # exact algebra, rounding only


def test_parabolic_vertex_degenerate_and_clipped():
    assert parabolic_vertex(np.array([1.0]), np.array([1.0]), np.array([1.0]))[0] == 0.0
    # vertex at +0.8 (outside the middle cell) is clipped to the documented range
    y = [(x - 0.8) ** 2 for x in (-1.0, 0.0, 1.0)]
    assert parabolic_vertex(*(np.array([v]) for v in y))[0] == 0.5


def test_extrema_times_on_a_sampled_cosine():
    """Parabolic interpolation of cos(w(n - delta)) about its peak sample gives the offset
    d = 0.5*tan(w*delta)*cot(w/2) in closed form (derivation: y(-1) - y(1) = 2 sin(w) sin(w
    delta), y(-1) - 2y(0) + y(1) = 2 cos(w delta)(cos w - 1)). At 26.7 samples per period its
    bias |d - delta| peaks at ~1e-3 sample (FACTS.md: < 0.02 deg), hence the brief's bound of
    0.02 sample periods is 20x the worst case."""
    f = 2.0
    w = 2 * np.pi * f / FS  # rad per sample
    for theta in np.linspace(0.0, 2 * np.pi, 13)[:-1]:
        x = 5.0 * np.cos(2 * np.pi * f * T + theta)
        pk, vl = extrema_times(x, FS)
        for times, offset in ((pk, 0.0), (vl, np.pi)):
            # true extremum times: 2 pi f t + theta = offset + 2 pi k
            k = np.round((2 * np.pi * f * times - offset + theta) / (2 * np.pi))
            truth = (2 * np.pi * k + offset - theta) / (2 * np.pi * f)
            err_samples = (times - truth) * FS
            assert np.max(np.abs(err_samples)) < 0.02
            # and exactly the closed form above (it is the same arithmetic, to rounding)
            n0 = np.round(truth * FS)
            delta = truth * FS - n0
            d = 0.5 * np.tan(w * delta) / np.tan(w / 2)
            np.testing.assert_allclose(times * FS, n0 + d, rtol=0, atol=1e-9)
            # every extremum strictly inside the record is found (none at the end samples)
            n_expected = np.sum((truth * FS > 0.5) & (truth * FS < N_REC - 1.5))
            assert abs(times.size - n_expected) <= 1


# --------------------------------------------------------------------------- estimators


@pytest.mark.parametrize("f_hz", FREQS_HZ)
@pytest.mark.parametrize("lag_deg", LAGS_DEG)
def test_peak_valley_phase_recovers_injected_lag(f_hz, lag_deg):
    """Clean sinusoids: the only error is the parabolic bias of each extremum, <= 1e-3 sample
    = 0.014 deg at 26.7 samples per period, partly averaged over 6 pairs (measured <= 2.5e-3
    deg); 0.05 deg is the brief's bound."""
    for theta in (0.0, 1.3, 4.0):
        tq, wh = _pair(f_hz, lag_deg, theta)
        res = peak_valley_phase(tq, wh, FS, f_hz, center_s=CENTER_S, n_periods=3)
        assert res.phase_deg == pytest.approx(lag_deg, abs=0.05)
        assert res.pair_phases_deg.size == 6  # 3 peaks + 3 valleys
        # the torque extrema used are the ones nearest the centre (within 1.5 periods + 1/2)
        assert np.max(np.abs(res.torque_times_s - CENTER_S)) <= 2.0 / f_hz


@pytest.mark.parametrize("f_hz", FREQS_HZ)
@pytest.mark.parametrize("lag_deg", LAGS_DEG)
def test_sinefit_phase_recovers_injected_lag(f_hz, lag_deg):
    """Clean sinusoids at the given frequency: the LS model is exact, the error is rounding
    (measured 1e-12 deg)."""
    for theta in (0.0, 1.3, 4.0):
        tq, wh = _pair(f_hz, lag_deg, theta)
        res = sinefit_phase(tq, wh, FS, f_hz)
        assert res.phase_deg == pytest.approx(lag_deg, abs=0.05)
        assert res.torque_amplitude == pytest.approx(8.0, rel=1e-9)
        assert res.wheel_amplitude == pytest.approx(0.05, rel=1e-9)
        # window = whole periods: n/fs * f within half a sample of an integer
        n_per = res.n_samples / FS * f_hz
        assert abs(n_per - round(n_per)) <= 0.5 * f_hz / FS
        assert res.window_s[1] - res.window_s[0] == pytest.approx(res.n_samples / FS)


@pytest.mark.parametrize("lag_deg", LAGS_DEG)
def test_both_estimators_tolerate_the_step1_frequency_error(lag_deg):
    """f_mod is step 1's estimate: 1e-4 Hz (noise-free bound) off for the paper's method, whose
    error is lag*df/f = 80*5e-5 = 0.004 deg; 1e-3 Hz (noisy bound) for the sine fit, whose
    phase referenced to the window centre does not couple to it to first order (measured
    0.028 deg)."""
    f_true = 2.0037
    for theta in (0.0, 1.3, 4.0):
        tq, wh = _pair(f_true, lag_deg, theta)
        pv = peak_valley_phase(tq, wh, FS, f_true + 1e-4, center_s=CENTER_S)
        assert pv.phase_deg == pytest.approx(lag_deg, abs=0.05)
        sf = sinefit_phase(tq, wh, FS, f_true + 1e-3)
        assert sf.phase_deg == pytest.approx(lag_deg, abs=0.05)


def test_sign_convention_wheel_lagging_is_positive():
    """A wheel signal that is the torque delayed by tau seconds lags by 360*f*tau degrees."""
    f, tau = 2.0037, 0.02  # 14.4 deg
    tq = 8.0 * np.cos(2 * np.pi * f * T) + 0.5 * np.cos(2 * np.pi * 2 * f * T)
    wh = 8.0 * np.cos(2 * np.pi * f * (T - tau)) + 0.5 * np.cos(2 * np.pi * 2 * f * (T - tau))
    expected = 360.0 * f * tau
    sf = sinefit_phase(tq, wh, FS, f, nuisance_hz=(2 * f,))
    assert sf.phase_deg == pytest.approx(expected, abs=0.05)
    pv = peak_valley_phase(tq, wh, FS, f, center_s=CENTER_S)
    assert pv.phase_deg > 0
    # swapping the roles flips the sign
    assert sinefit_phase(wh, tq, FS, f, nuisance_hz=(2 * f,)).phase_deg == pytest.approx(
        -expected, abs=0.05)
    assert peak_valley_phase(wh, tq, FS, f, center_s=CENTER_S).phase_deg < 0


@pytest.mark.parametrize("lag_deg", LAGS_DEG)
def test_sinefit_phase_with_a_100x_nuisance_tone(lag_deg):
    """Wheel rotation line at 4.6 Hz, 100x the modulation, plus platform 1x/2x lines and a
    drift, given as nuisance: the model is exact again (0.05 deg is the brief's bound)."""
    f = 2.0037
    tq, wh = _pair(f, lag_deg, 0.7)
    wh = wh + 100 * 0.05 * np.cos(2 * np.pi * 4.6 * T + 0.3) + 0.01 * T
    wh = wh + 0.2 * np.cos(2 * np.pi * 0.16 * T) + 0.1 * np.sin(2 * np.pi * 0.32 * T)
    nuisance = (4.6, 0.16, 0.32, f + 0.05)  # the last is within 1/T of f_mod: must be dropped
    res = sinefit_phase(tq, wh, FS, f, nuisance_hz=nuisance)
    assert res.phase_deg == pytest.approx(lag_deg, abs=0.05)
    # without the nuisance model the 4.6 Hz leakage over a 12-period window is visible
    bare = sinefit_phase(tq, wh, FS, f)
    assert abs(bare.phase_deg - lag_deg) > 0.05


def test_sinefit_phase_monte_carlo_reaches_the_crb():
    """1000 fixed-seed trials, torque at eta1 = 100 (20 dB), wheel at eta2 = 30 (14.8 dB).
    The estimated std of 1000 draws has a relative standard error 1/sqrt(2*999) = 2.2 %, so
    10 % is 4.5 standard errors; the LS fit is efficient (FACTS.md §5: 0.447 vs 0.454 deg).
    The reported standard error (one-sided PSD of the residual near f_mod) scatters per trial
    (~10 periodogram bins); its RMS over trials must be within 20 % of the empirical std."""
    rng = np.random.default_rng(20240611)
    f, lag = 2.0037, 40.0
    a1, a2, eta1, eta2 = 8.0, 0.05, 100.0, 30.0
    s1, s2 = a1 / math.sqrt(2 * eta1), a2 / math.sqrt(2 * eta2)
    phases, stderrs = [], []
    for _ in range(1000):
        tq, wh = _pair(f, lag, rng.uniform(0, 2 * np.pi), a_t=a1, a_w=a2)
        tq = tq + s1 * rng.standard_normal(N_REC)
        wh = wh + s2 * rng.standard_normal(N_REC)
        res = sinefit_phase(tq, wh, FS, f)
        phases.append(res.phase_deg)
        stderrs.append(res.phase_stderr_deg)
    emp = np.std(phases, ddof=1)
    crb = phase_crb_deg(a1, a2, s1, s2, res.n_samples)
    assert np.mean(phases) == pytest.approx(lag, abs=4 * emp / math.sqrt(1000))  # unbiased
    assert emp == pytest.approx(crb, rel=0.10)
    assert math.sqrt(np.mean(np.square(stderrs))) == pytest.approx(emp, rel=0.20)


def test_phase_crb_deg_matches_the_formula():
    a1, a2, s1, s2, n = 8.0, 0.05, 0.4, 0.006, 320
    eta1, eta2 = a1**2 / (2 * s1**2), a2**2 / (2 * s2**2)  # 200, 34.7
    var = (1 / n) * (1 / eta1 + 1 / eta2)
    assert phase_crb_deg(a1, a2, s1, s2, n) == pytest.approx(math.degrees(math.sqrt(var)),
                                                             rel=1e-12)
    # hand value: A = 1, sigma = 0.1 -> eta = 50; N = 100: var = 0.04/100, std 0.02 rad
    assert phase_crb_deg(1.0, 1.0, 0.1, 0.1, 100) == pytest.approx(math.degrees(0.02),
                                                                   rel=1e-12)
    # continuous form S1/(A1^2 T) + S2/(A2^2 T), S = 2 sigma^2/fs: the same number, and the
    # same at any sample rate for the same noise density and window
    t_win = n / FS
    cont = 2 * s1**2 / FS / (a1**2 * t_win) + 2 * s2**2 / FS / (a2**2 * t_win)
    assert math.sqrt(cont) == pytest.approx(math.sqrt(var), rel=1e-12)
    k = 312.5  # 16 670 Hz / 53.344 Hz
    assert phase_crb_deg(a1, a2, s1 * math.sqrt(k), s2 * math.sqrt(k), round(n * k)) == (
        pytest.approx(phase_crb_deg(a1, a2, s1, s2, n), rel=1e-12))


# --------------------------------------------------------------------------- helpers


def test_whole_period_window():
    start, stop = whole_period_window(N_REC, FS, 2.0)
    # 347 samples = 6.505 s = 13.01 periods -> 13 periods = round(13*26.672) = 347 samples
    assert (start, stop) == (0, 347)
    start, stop = whole_period_window(N_REC, FS, 1.9)
    n_per = math.floor(N_REC / FS * 1.9)
    assert stop - start == round(n_per * FS / 1.9)
    assert abs((start + stop) / 2 - N_REC / 2) <= 0.5  # centred
    start, stop = whole_period_window(N_REC, FS, 2.0, center_s=1.0)  # too near the start
    assert start == 0
    with pytest.raises(ProcessingError):
        whole_period_window(20, FS, 2.0)  # 0.37 s < one period


def test_local_noise_psd_of_white_noise_and_a_far_line():
    """White noise sigma: one-sided PSD 2 sigma^2/fs. 20 000 samples give ~560 bins in
    +-0.75 Hz (Hann halves the independent ones): ~6 % standard error, bound 20 %."""
    rng = np.random.default_rng(11)
    sigma, n = 0.3, 20_000
    t = np.arange(n) / FS
    x = sigma * rng.standard_normal(n) + 50.0 * np.cos(2 * np.pi * 10.0 * t)  # 8 Hz away
    assert local_noise_psd(x, FS, 2.0) == pytest.approx(2 * sigma**2 / FS, rel=0.20)


def test_sine_fit_design_matches_direct_trigonometry():
    """The sine fit's design (fixed columns cached per window, nuisance tones by rotation
    between exact anchors every 64 samples) equals cos/sin evaluated directly: the fixed
    columns exactly, the tones to 1e-12 (the argument 2*pi*f*t itself is only defined to
    |2*pi*f*t|*eps ~ 2e-13 at 500 Hz over 1.25 s)."""
    from torquemod.dsp.phase import _design
    from torquemod.dsp.tonemodel import tone_design
    for n, fs, f, tones, trend in ((2500, 2000.0, 4.0, (7.9, 15.8, 41.2, 82.4, 499.0), True),
                                   (1001, 1000.0, 5.0, (6.9,), False), (345, 53.344, 2.0, (),
                                                                        True)):
        t = (np.arange(n) - (n - 1) / 2) / fs
        ref = np.column_stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t),
                               tone_design(t, tones, line=trend)])
        got = _design(n, fs, f, tones, trend)
        fixed = 4 if trend else 3
        assert got.shape == ref.shape
        assert np.array_equal(got[:, :fixed], ref[:, :fixed])
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_wrapped_angle_is_the_angle_of_exp_bit_for_bit():
    from torquemod.dsp.phase import wrapped_angle
    rng = np.random.default_rng(4)
    for a in [*rng.uniform(-7.0, 7.0, 2000), *(rng.standard_normal(500) * 1e-6), 0.0, -0.0,
              np.pi, -np.pi, 2 * np.pi]:
        assert wrapped_angle(a) == float(np.angle(np.exp(1j * a)))


def test_deg_per_rad_gives_np_degrees_bit_for_bit():
    from torquemod.dsp.phase import DEG_PER_RAD
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(-7.0, 7.0, 20000), rng.standard_normal(2000) * 1e-6])
    np.testing.assert_array_equal(x * DEG_PER_RAD, np.degrees(x))
    assert all(v * DEG_PER_RAD == float(np.degrees(v)) for v in x[:500].tolist())
