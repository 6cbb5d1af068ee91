"""Cycles (torquemod.processing.cycles.revolution_bounds) against analytic platform angles, and the
per-cycle creep point (chain.creepage_coa, Eq. 3 and 4 of the V-Track paper)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from torquemod.processing.chain import creepage_coa
from torquemod.processing.cycles import revolution_bounds

FS = 1000.0  # [Hz]


def test_constant_speed_whole_revolutions_and_trailing_part_dropped():
    """2 pi/(Omega dt) = 320 samples exactly: every revolution is 320 samples long, 3.6
    revolutions give three, and the last 0.6 revolution is not returned."""
    n_per_rev = 320
    omega = 2 * np.pi * FS / n_per_rev
    n = round(3.6 * n_per_rev)
    bounds = revolution_bounds(np.full(n, omega), FS)
    assert round(2 * np.pi / (omega / FS)) == n_per_rev
    assert bounds == [(0, 320), (320, 640), (640, 960)]


@pytest.mark.parametrize("samples_per_rev", [320.37, 1234.5678, 97.2])
def test_constant_speed_bounds_are_the_nearest_samples(samples_per_rev):
    """Non-integer period P: revolution k ends at the sample nearest k*P (the angle is exactly
    Omega*n*dt), so the lengths are floor(P) or ceil(P), round(P) on average."""
    omega = 2 * np.pi * FS / samples_per_rev
    n = int(5.5 * samples_per_rev)
    bounds = revolution_bounds(np.full(n, omega), FS)
    ends = [round(k * samples_per_rev) for k in range(1, 6)]
    assert [b for _, b in bounds] == ends
    assert [a for a, _ in bounds] == [0, *ends[:-1]]
    lengths = np.diff([0, *ends])
    assert set(lengths) <= {math.floor(samples_per_rev), math.ceil(samples_per_rev)}


@pytest.mark.parametrize(("e1", "e2"), [(0.05, 0.0), (0.0, 0.03), (0.08, 0.04)])
def test_eccentric_speed_revolutions_within_one_sample(e1, e2):
    """Platform angle theta(t) = W t + e1 sin(W t + 0.4) + e2 sin(2 W t - 1.1) (1x and 2x per
    revolution speed errors of up to 16 % of W). The true end of revolution k is the root of
    theta(t) = 2 pi k (brentq on the analytic angle); the returned bound must be within one
    sample of it (the trapezoid rule's error is O(dt^2 W^3 e) ~ 1e-9 rad here)."""
    w = 2 * np.pi * 0.16  # platform at 0.16 rev/s

    def theta(t):
        return w * t + e1 * np.sin(w * t + 0.4) + e2 * np.sin(2 * w * t - 1.1)

    def speed(t):
        return w * (1 + e1 * np.cos(w * t + 0.4) + 2 * e2 * np.cos(2 * w * t - 1.1))

    n = int(4.3 / 0.16 * FS)
    t = np.arange(n) / FS
    bounds = revolution_bounds(speed(t), FS)
    theta0 = theta(0.0)  # the integral starts at angle 0 at the first sample
    n_rev = int((theta(t[-1]) - theta0) // (2 * np.pi))
    assert len(bounds) == n_rev == 4
    for k, (_, stop) in enumerate(bounds, start=1):
        t_k = optimize.brentq(lambda s, k=k: theta(s) - theta0 - 2 * np.pi * k,
                              (k - 0.5) / 0.16, (k + 0.5) / 0.16, xtol=1e-12)
        assert abs(stop - t_k * FS) < 1.0
        assert abs(stop - t_k * FS) <= 0.5 + 1e-6  # indeed the nearest sample
    assert bounds[0][0] == 0
    assert all(bounds[i][1] == bounds[i + 1][0] for i in range(len(bounds) - 1))


def test_under_one_revolution_gives_no_cycle():
    omega = 2 * np.pi * 0.16
    n = int(0.95 / 0.16 * FS)
    assert revolution_bounds(np.full(n, omega), FS) == []
    assert revolution_bounds(np.zeros(5000), FS) == []


def test_creepage_and_coa_eq3_eq4():
    """xi = (w Rw - W Rp)/(W Rp), CoA = sqrt(Fx^2 + Fy^2)/Fz with hand-computed values."""
    rw, rp = 0.1536, 0.8  # [m]
    big_w = 2.0  # platform [rad/s]: V = 1.6 m/s
    w = 1.6 * 1.004 / rw  # wheel surface 0.4 % faster
    xi, coa = creepage_coa(w, big_w, 300.0, -400.0, 1000.0, wheel_radius_m=rw,
                           platform_radius_m=rp)
    assert xi == pytest.approx(0.004, rel=1e-12)
    assert coa == pytest.approx(0.5, rel=1e-15)  # 3-4-5 triangle
    xi, coa = creepage_coa(1.6 * 0.99 / rw, big_w, -250.0, 0.0, 4200.0, wheel_radius_m=rw,
                           platform_radius_m=rp)
    assert xi == pytest.approx(-0.01, rel=1e-12)  # braking: negative creepage
    assert coa == pytest.approx(250.0 / 4200.0, rel=1e-15)
