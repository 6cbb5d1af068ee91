"""The large-signal theory's compiled Newton solve (theory_kernels.newton_periodic, issue 12
fifth round) against the Python loop it replaced, written here as the reference with the
vectorised Polach force of contact/polach.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from torquemod.analysis.contact.polach import creep_force
from torquemod.twins.vtrack import theory, theory_kernels
from torquemod.twins.vtrack.simulate import load_config
from torquemod.twins.vtrack.theory_kernels import (
    C_N0,
    C_RP,
    C_RW,
    C_V0,
    C_WREF,
    C_XI0,
    C_XIY,
    _dense_solve,
    _fx,
)


def _polach(c: np.ndarray) -> dict:
    keys = ("a_m", "b_m", "c11", "c22", "shear_modulus_pa", "mu0", "a_ratio", "b_s_m", "k_a",
            "k_s")
    return dict(zip(keys, c[7:].tolist(), strict=True))


def newton_reference(x, amp, dc, sine, lin_w, p_op, pl, platform, n, c, rtol, max_iter):
    """theory.py's Newton loop before the fifth round (numpy, vectorised Polach force), on
    the whole ``2n x 2n`` Jacobian (``pl``, which the compiled loop's Schur complement
    uses, is not read)."""
    rw, rp, n0, wref, v0 = c[C_RW], c[C_RP], c[C_N0], c[C_WREF], c[C_V0]
    kw = _polach(c)

    def force(u, w):
        v = (wref + w) * rp
        xi = (v0 * c[C_XI0] + u * rw - w * rp) / v
        return creep_force(xi, c[C_XIY], normal_load_n=n0, speed_m_s=v, **kw)[0]

    def split(x):
        return x[:n], (x[n:] if platform else np.zeros(n))

    def residual(x):
        u, w = split(x)
        fx = force(u, w)
        r1 = lin_w @ u - (dc + amp * sine) + rw * fx
        return np.concatenate([r1, w - p_op @ fx]) if platform else r1

    def jacobian(x):
        u, w = split(x)
        hu = 1e-7 * (1.0 + np.abs(u).max())
        fu = (force(u + hu, w) - force(u - hu, w)) / (2.0 * hu)
        if not platform:
            return lin_w + rw * np.diag(fu)
        hw = 1e-7 * (1e-3 + np.abs(w).max())
        fw = (force(u, w + hw) - force(u, w - hw)) / (2.0 * hw)
        jac = np.empty((2 * n, 2 * n))
        jac[:n, :n] = lin_w + rw * np.diag(fu)
        jac[:n, n:] = rw * np.diag(fw)
        jac[n:, :n] = -p_op * fu[None, :]
        jac[n:, n:] = np.eye(n) - p_op * fw[None, :]
        return jac

    r = residual(x)
    norm = np.linalg.norm(r)
    for it in range(1, max_iter + 1):
        dx = np.linalg.solve(jacobian(x), -r)
        if not np.all(np.isfinite(dx)):
            return x, it, False
        small = np.abs(dx[:n]).max() <= rtol * max(np.abs(x[:n]).max(), 1e-9)
        lam = 1.0
        while True:
            xn = x + lam * dx
            rn = residual(xn)
            nn = np.linalg.norm(rn)
            if np.isfinite(nn) and (nn < norm or small):
                break
            lam *= 0.5
            if lam < 1e-4:
                return x, it, False
        x, r, norm = xn, rn, nn
        if small:
            return x, it, True
    return x, max_iter, False


def test_scalar_force_matches_vectorised_polach():
    """_fx against creep_force over creepages from 1e-9 to 0.3 of both signs, with and
    without lateral creepage; tolerance 4 ulp-ish (1e-15 relative): the same operations,
    only libm's and numpy's exp/atan may round differently."""
    cfg = load_config()
    kw = cfg.rig.contact.polach_kwargs()
    xi = np.concatenate([-np.geomspace(1e-9, 0.3, 200), [0.0], np.geomspace(1e-9, 0.3, 200)])
    for xiy in (0.0, 2e-3):
        c = theory_kernels.pack_constants(0.15, 1.0, 3000.0, 10.0, 10.0, 0.0, xiy, kw)
        ref = creep_force(xi, xiy, normal_load_n=3000.0, speed_m_s=3.7, **kw)[0]
        got = np.array([_fx(float(x), 3.7, c) for x in xi])
        np.testing.assert_allclose(got, ref, rtol=1e-15, atol=1e-300)
    assert _fx(math.nan, 3.7, c) == 0.0  # as creep_force's where(xi > 0, ..., 0)


def test_dense_solve_against_numpy():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((40, 40)) + 5 * np.eye(40)
    b = rng.standard_normal(40)
    np.testing.assert_allclose(_dense_solve(a, b), np.linalg.solve(a, b), rtol=1e-12)


@pytest.mark.parametrize(("drive", "platform"), [("motor", True), ("shaft", True),
                                                 ("shaft", False)])
def test_large_signal_matches_python_newton(monkeypatch, drive, platform):
    """Every default step's large-signal result with the compiled Newton and with the
    Python reference: phases within 1e-9 deg, amplitudes and creepages within 1e-9
    relative, the same iterations and collocation sizes. The mean creep coefficient is a
    central difference with step 1e-7 (rounding amplified ~1e7): 1e-8 relative."""
    cfg = load_config()
    f = cfg.modulation.actual_frequency_hz
    dcs = cfg.procedure.dc_torques_nm[:6]
    fast = [theory.large_signal_phase_deg(dc, cfg.rig, f, 8.0, drive=drive, platform=platform)
            for dc in dcs]
    monkeypatch.setattr(theory, "newton_periodic", newton_reference)
    theory._large_signal_memo.cache_clear()  # solved again, not remembered
    slow = [theory.large_signal_phase_deg(dc, cfg.rig, f, 8.0, drive=drive, platform=platform)
            for dc in dcs]
    for a, b in zip(fast, slow, strict=True):
        assert not a.slipped and not b.slipped
        assert (a.iterations, a.n_samples) == (b.iterations, b.n_samples)
        assert abs(a.phase_deg - b.phase_deg) < 1e-9
        for name in ("speed_amplitude_rad_s", "torque_amplitude_nm", "mean_creepage",
                     "creepage_min", "creepage_max"):
            assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-9, abs=1e-15)
        assert a.mean_creep_coefficient == pytest.approx(b.mean_creep_coefficient, rel=1e-8)


def _solve_one_pivot_at_a_time(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Gaussian elimination with partial pivoting, one pivot at a time (plain Python: the
    form _dense_solve had before it took two pivots per pass)."""
    m = a.shape[0]
    lu = [[float(v) for v in row] for row in a]
    x = [float(v) for v in b]
    for k in range(m):
        piv, big = k, abs(lu[k][k])
        for i in range(k + 1, m):
            if abs(lu[i][k]) > big:
                piv, big = i, abs(lu[i][k])
        if big == 0.0:
            return np.full(m, np.nan)
        lu[k], lu[piv] = lu[piv], lu[k]
        x[k], x[piv] = x[piv], x[k]
        inv = 1.0 / lu[k][k]
        for i in range(k + 1, m):
            fac = lu[i][k] * inv
            if fac != 0.0:
                for j in range(k + 1, m):
                    lu[i][j] -= fac * lu[k][j]
                x[i] -= fac * x[k]
    for i in range(m - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, m):
            acc -= lu[i][j] * x[j]
        x[i] = acc / lu[i][i]
    return np.array(x)


def test_dense_solve_two_pivots_per_pass_is_one_at_a_time():
    """Bit for bit against one pivot at a time on 120 random systems of 1-40 unknowns, a
    third half zeros (factors that are zero skip rows), some singular, some with -0.0."""
    rng = np.random.default_rng(12)
    for trial in range(120):
        m = int(rng.integers(1, 41))
        a = rng.standard_normal((m, m))
        b = rng.standard_normal(m)
        if trial % 3 == 0:
            a[rng.random((m, m)) < 0.5] = 0.0
        if trial % 7 == 0 and m > 2:
            a[:, m // 2] = 0.0
        if trial % 5 == 0:
            a[rng.random((m, m)) < 0.3] = -0.0
            b[rng.random(m) < 0.3] = -0.0
        got, ref = _dense_solve(a, b), _solve_one_pivot_at_a_time(a, b)
        assert np.array_equal(got, ref, equal_nan=True), trial
        assert np.array_equal(np.signbit(got), np.signbit(ref)), trial


@pytest.mark.parametrize("platform", [True, False])
def test_newton_step_is_the_whole_jacobian_solve(platform):
    """The Newton step through the n x n Schur complement (the platform rows plus P/R_w
    times the wheel rows lose the force) against numpy's solve of the whole Jacobian, for
    arbitrary (non-circulant) L and P with PL = P @ L: rounding only (1e-10 relative)."""
    from torquemod.twins.vtrack.theory_kernels import _newton_step

    rng = np.random.default_rng(21)
    n, rw = 24, 0.0675
    lin_w = rng.standard_normal((n, n)) + 4.0 * np.eye(n)
    p_op = 0.1 * rng.standard_normal((n, n))
    fu, fw = rng.uniform(1e3, 1e4, n), -rng.uniform(1e2, 1e3, n)
    r = rng.standard_normal(2 * n if platform else n)
    c = np.zeros(theory_kernels.N_CONST)
    c[C_RW] = rw
    got = _newton_step(r, lin_w, p_op, p_op @ lin_w, platform, n, c, fu, fw,
                       np.empty((n, n)))
    if platform:
        jac = np.block([[lin_w + rw * np.diag(fu), rw * np.diag(fw)],
                        [-p_op * fu[None, :], np.eye(n) - p_op * fw[None, :]]])
    else:
        jac = lin_w + rw * np.diag(fu)
    ref = np.linalg.solve(jac, -r)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
