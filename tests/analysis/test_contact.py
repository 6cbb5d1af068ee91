"""Contact models: Polach creep force, Kalker coefficients, Hertz ellipse, presets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from torquemod.analysis.contact.hertz import contact_modulus, hertz_ellipse
from torquemod.analysis.contact.kalker import (
    A_OVER_B_NODES,
    C11_TABLE,
    C22_TABLE,
    C23_TABLE,
    POISSON_NODES,
    kalker_coefficients,
)
from torquemod.analysis.contact.polach import creep_force, creep_force_kernel, creep_force_scalar
from torquemod.analysis.contact.presets import POLACH_PRESETS, polach_preset
from torquemod.errors import InputError

G = 82e9
GEOM = dict(normal_load_n=4200.0, speed_m_s=7 / 3.6, a_m=1.2e-3, b_m=1.3e-3, c11=4.17,
            c22=3.60, shear_modulus_pa=G)


def polach(**kw):
    base = dict(mu0=0.3, a_ratio=1.0, b_s_m=0.0, k_a=1.0, k_s=1.0)
    base.update(kw)
    return base


def test_initial_slope_is_kalker_linear_theory():
    xi = 1e-8
    fx, fy = creep_force(xi, 0.0, **GEOM, **polach())
    kalker = G * GEOM["a_m"] * GEOM["b_m"] * GEOM["c11"]
    assert fx / xi == pytest.approx(kalker, rel=1e-6)
    assert fy == 0.0
    # lateral direction uses c22
    _, fy = creep_force(0.0, xi, **GEOM, **polach())
    assert fy / xi == pytest.approx(G * GEOM["a_m"] * GEOM["b_m"] * GEOM["c22"], rel=1e-6)


def test_initial_slope_with_reduction_factors():
    xi = 1e-8
    fx, _ = creep_force(xi, 0.0, **GEOM, **polach(k_a=0.3, k_s=0.1))
    kalker = G * GEOM["a_m"] * GEOM["b_m"] * GEOM["c11"]
    assert fx / xi == pytest.approx((0.3 + 0.1) / 2 * kalker, rel=1e-6)


def test_saturates_at_mu_without_velocity_dependence():
    xi = np.array([0.05, 1.0, 100.0])
    fx, _ = creep_force(xi, 0.0, **GEOM, **polach())
    coa = fx / GEOM["normal_load_n"]
    assert np.all(coa <= 0.3 + 1e-12)
    assert coa[-1] == pytest.approx(0.3, rel=1e-4)
    assert np.all(np.diff(coa) > 0)


def test_falling_branch_with_velocity_dependent_friction():
    p = polach(mu0=0.4, a_ratio=0.4, b_s_m=0.6, k_a=1.0, k_s=0.4)
    xi = np.geomspace(1e-5, 5.0, 2000)
    fx, _ = creep_force(xi, 0.0, **GEOM, **p)
    i = int(np.argmax(fx))
    assert 0 < i < xi.size - 1          # an interior maximum ...
    assert fx[-1] < 0.9 * fx[i]         # ... and a falling branch behind it
    # at large slip velocity the friction tends to mu0*A
    fx_big, _ = creep_force(1e3, 0.0, **GEOM, **p)
    assert fx_big / GEOM["normal_load_n"] == pytest.approx(0.4 * 0.4, rel=1e-3)
    # a faster rolling speed lowers the force at the same creepage (higher slip velocity)
    fast = dict(GEOM, speed_m_s=20.0)
    assert creep_force(0.05, 0.0, **fast, **p)[0] < creep_force(0.05, 0.0, **GEOM, **p)[0]


@pytest.mark.parametrize("xy", [(0.003, 0.0), (0.002, 0.001), (0.0, 0.004), (0.3, -0.01)])
def test_odd_symmetry(xy):
    p = polach(mu0=0.4, a_ratio=0.4, b_s_m=0.6, k_a=1.0, k_s=0.4)
    fx, fy = creep_force(*xy, **GEOM, **p)
    fxm, fym = creep_force(-xy[0], -xy[1], **GEOM, **p)
    assert fxm == pytest.approx(-fx, abs=1e-12) and fym == pytest.approx(-fy, abs=1e-12)
    fxx, fyy = creep_force(-xy[0], xy[1], **GEOM, **p)
    assert fxx == pytest.approx(-fx, abs=1e-12) and fyy == pytest.approx(fy, abs=1e-12)


def test_vectorised_and_scalar_kernels_agree():
    p = POLACH_PRESETS["vtrack"].as_dict()
    xi_x = np.linspace(-0.03, 0.03, 60).reshape(3, 20)
    xi_y = 2e-4
    fx, fy = creep_force(xi_x, xi_y, **GEOM, **p)
    assert fx.shape == xi_x.shape == fy.shape
    sx = math.pi * G * GEOM["a_m"] * GEOM["b_m"] * GEOM["c11"] / 4
    sy = math.pi * G * GEOM["a_m"] * GEOM["b_m"] * GEOM["c22"] / 4
    args = (GEOM["normal_load_n"], GEOM["speed_m_s"], sx, sy, p["mu0"], p["a_ratio"],
            p["b_s_m"], p["k_a"], p["k_s"])
    for (i, j), x in np.ndenumerate(xi_x):
        ref = (fx[i, j], fy[i, j])
        assert creep_force_scalar(x, xi_y, *args) == pytest.approx(ref, rel=1e-12, abs=1e-9)
        assert creep_force_kernel(x, xi_y, *args) == pytest.approx(ref, rel=1e-12, abs=1e-9)
    assert creep_force_scalar(0.0, 0.0, *args) == (0.0, 0.0)


# Kalker (1990) Table E.3 as printed in FACTS.md §3, typed here independently of the module:
# (shape, c11 at nu = 0/0.25/0.5, c22, c23); "a0.3" is a/b = 0.3, "b0.3" is b/a = 0.3
KALKER_ROWS = """
a0.1 2.51 3.31 4.85 2.51 2.52 2.53 0.334 0.473 0.731
a0.2 2.59 3.37 4.81 2.59 2.63 2.66 0.483 0.603 0.809
a0.3 2.68 3.44 4.80 2.68 2.75 2.81 0.607 0.715 0.889
a0.4 2.78 3.53 4.82 2.78 2.88 2.98 0.720 0.823 0.977
a0.5 2.88 3.62 4.83 2.88 3.01 3.14 0.827 0.929 1.07
a0.6 2.98 3.72 4.91 2.98 3.14 3.31 0.930 1.03 1.18
a0.7 3.09 3.81 4.97 3.09 3.28 3.48 1.03 1.14 1.29
a0.8 3.19 3.91 5.05 3.19 3.41 3.65 1.13 1.25 1.40
a0.9 3.29 4.01 5.12 3.29 3.54 3.82 1.23 1.36 1.51
a1.0 3.40 4.12 5.20 3.40 3.67 3.98 1.33 1.47 1.63
b0.9 3.51 4.22 5.30 3.51 3.81 4.16 1.44 1.59 1.77
b0.8 3.65 4.36 5.42 3.65 3.99 4.39 1.58 1.75 1.94
b0.7 3.82 4.54 5.58 3.82 4.21 4.67 1.76 1.95 2.18
b0.6 4.06 4.78 5.80 4.06 4.50 5.04 2.01 2.23 2.50
b0.5 4.37 5.10 6.11 4.37 4.90 5.56 2.35 2.62 2.96
b0.4 4.84 5.57 6.57 4.84 5.48 6.31 2.88 3.24 3.70
b0.3 5.57 6.34 7.34 5.57 6.40 7.51 3.79 4.32 5.01
b0.2 6.96 7.78 8.82 6.96 8.14 9.79 5.72 6.63 7.89
b0.1 10.7 11.7 12.9 10.7 12.8 16.0 12.2 14.6 18.0
"""


def _kalker_rows():
    for line in KALKER_ROWS.split("\n"):
        if line.strip():
            name, *vals = line.split()
            g = float(name[1:])
            yield (g if name[0] == "a" else 1.0 / g), np.array(vals, float).reshape(3, 3)


def test_kalker_full_table_at_every_row_and_poisson_ratio():
    rows = list(_kalker_rows())
    assert len(rows) == 19 and len(A_OVER_B_NODES) == 19
    for a_over_b, ref in rows:
        for j, nu in enumerate((0.0, 0.25, 0.5)):
            k = kalker_coefficients(a_over_b, nu)
            assert (k.c11, k.c22, k.c23) == pytest.approx(tuple(ref[:, j]), rel=1e-12), \
                (a_over_b, nu)
    # the module's own arrays hold the same table
    np.testing.assert_allclose(C11_TABLE, [r[0] for _, r in rows])
    np.testing.assert_allclose(C22_TABLE, [r[1] for _, r in rows])
    np.testing.assert_allclose(C23_TABLE, [r[2] for _, r in rows])
    assert POISSON_NODES == (0.0, 0.25, 0.5)


def test_kalker_between_rows_by_hand():
    # linear in g within a half: a/b = 0.85 at nu = 0.25 is halfway between rows 0.8 and 0.9
    k = kalker_coefficients(0.85, 0.25)
    assert k.c11 == pytest.approx((3.91 + 4.01) / 2, rel=1e-12)
    assert k.c23 == pytest.approx((1.25 + 1.36) / 2, rel=1e-12)
    # b/a = 0.25 (a/b = 4), nu = 0: halfway between the b/a = 0.3 and 0.2 rows
    k = kalker_coefficients(4.0, 0.0)
    assert k.c22 == pytest.approx((5.57 + 6.96) / 2, rel=1e-12)
    # quadratic through the three nu columns: at nu = 0.125 the Lagrange weights are
    # 3/8, 3/4, -1/8 (by hand: (nu-.25)(nu-.5)/((0-.25)(0-.5)) = 0.375, ...)
    k = kalker_coefficients(1.0, 0.125)
    assert k.c11 == pytest.approx(0.375 * 3.40 + 0.75 * 4.12 - 0.125 * 5.20, rel=1e-12)
    arr = kalker_coefficients(np.array([0.1, 1.0, 10.0]), 0.25)
    np.testing.assert_allclose(arr.c11, [3.31, 4.12, 11.7])
    # the coefficients rise with a/b across both halves (all but c11 at nu = 0.5, which the
    # table itself has dipping from 4.85 to 4.80 over a/b = 0.1-0.3)
    g = np.geomspace(0.1, 10, 200)
    for nu in (0.0, 0.25, 0.5):
        kc = kalker_coefficients(g, nu)
        for c in ((kc.c22, kc.c23) if nu == 0.5 else (kc.c11, kc.c22, kc.c23)):
            assert np.all(np.diff(c) >= 0)


@pytest.mark.parametrize("bad", [(0.05, 0.25), (20.0, 0.25), (1.0, -0.1), (1.0, 0.6)])
def test_kalker_outside_table_raises(bad):
    with pytest.raises(InputError):
        kalker_coefficients(*bad)


def test_hertz_sphere_on_flat_is_exact():
    e, nu, n, r = 210e9, 0.3, 1000.0, 0.05
    el = hertz_ellipse(n, curvature_x_1_m=1 / r, curvature_y_1_m=1 / r, youngs_modulus_pa=e,
                       poisson_ratio=nu)
    a = (3 * n * r / (4 * contact_modulus(e, nu))) ** (1 / 3)
    assert el.a_m == pytest.approx(a, rel=1e-9) and el.b_m == pytest.approx(a, rel=1e-9)
    assert el.p0_pa == pytest.approx(3 * n / (2 * math.pi * a * a))


@pytest.mark.parametrize("ratio", [1.5, 3.0])
def test_hertz_ellipse_against_approximations(ratio):
    """Johnson (1985) Eq. 3.70: b/a ~ (A/B)^(2/3); c = sqrt(ab) ~ (3*N*Re/(4E*))^(1/3)
    with Re = 1/(2*sqrt(A*B)) -- good to a few per cent for moderate ellipticity."""
    e, nu, n = 210e9, 0.28, 4200.0
    kx, ky = 10.0, 10.0 * ratio  # A = kx/2 <= B = ky/2: long axis in the rolling direction
    el = hertz_ellipse(n, curvature_x_1_m=kx, curvature_y_1_m=ky, youngs_modulus_pa=e,
                       poisson_ratio=nu)
    assert el.a_m > el.b_m
    assert el.b_m / el.a_m == pytest.approx((1 / ratio) ** (2 / 3), rel=0.06)
    re = 1 / (2 * math.sqrt(kx / 2 * ky / 2))
    c = (3 * n * re / (4 * contact_modulus(e, nu))) ** (1 / 3)
    assert math.sqrt(el.a_m * el.b_m) == pytest.approx(c, rel=0.05)
    # swapping the curvatures swaps the axes
    sw = hertz_ellipse(n, curvature_x_1_m=ky, curvature_y_1_m=kx, youngs_modulus_pa=e,
                       poisson_ratio=nu)
    assert (sw.a_m, sw.b_m) == pytest.approx((el.b_m, el.a_m), rel=1e-9)


@pytest.mark.parametrize("ratio", [1.0, 2.0, 10.0, 0.2])
def test_hertz_ellipse_satisfies_hertz_integrals(ratio):
    """Brute-force check: an ellipsoidal pressure of total load N on (a, b) produces the
    surface displacement ``const - A x^2 - B y^2`` with (Johnson 1985, §3.4; Barber)
    ``A = 3N/(4 pi E*) int_0^inf dw / ((a^2+w) sqrt((a^2+w)(b^2+w) w))`` and B with b."""
    from scipy.integrate import quad

    e, nu, n = 210e9, 0.28, 4200.0
    kx, ky = 14.8, 14.8 * ratio
    el = hertz_ellipse(n, curvature_x_1_m=kx, curvature_y_1_m=ky, youngs_modulus_pa=e,
                       poisson_ratio=nu)
    a2, b2 = el.a_m**2, el.b_m**2
    pref = 3 * n / (4 * math.pi * contact_modulus(e, nu))

    def integral(c2):
        def f(u):  # w = u^2 removes the 1/sqrt(w) singularity
            w = u * u
            return 2.0 / ((c2 + w) * math.sqrt((a2 + w) * (b2 + w)))
        return quad(f, 0, np.inf, epsabs=0, epsrel=1e-11, limit=200)[0]

    assert pref * integral(a2) == pytest.approx(kx / 2, rel=1e-7)
    assert pref * integral(b2) == pytest.approx(ky / 2, rel=1e-7)


def test_hertz_rejects_bad_input():
    with pytest.raises(InputError):
        hertz_ellipse(-1.0, curvature_x_1_m=1.0, curvature_y_1_m=1.0)


def test_presets_have_sources():
    assert {"dry", "wet", "vtrack"} <= set(POLACH_PRESETS)
    for name, p in POLACH_PRESETS.items():
        assert p.source, name
    assert "assumed" in POLACH_PRESETS["vtrack"].source
    assert polach_preset("dry").mu0 == 0.55
    with pytest.raises(InputError, match="vtrack"):
        polach_preset("icy")
