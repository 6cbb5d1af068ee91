"""Adhesion-creepage laws and measurement records written apart from torquemod's estimator:
nothing here imports torquemod. Used by ``benchmarks/friction_coverage.py`` and by the fast
coverage test.

Each law is a function of the creepage xi [-] (odd, vectorised) with parameters drawn over a
stated range; the truth is computed here by brute force: the available adhesion P (the
curve's maximum, searched on a fine grid and refined by golden section), the creep
coefficient k = dCoA/dxi (central differences), and for the rig the mean point and
describing-function slope under the modulation's creepage swing (bisection on a 64-node
average over the swing's phase), with ``tan(phi) = C/k`` (rigid wheel, V-Track paper Eq. 1).

Laws (ranges):

* ``polach``: Polach 2005 Eq. 8 with constant friction, kA/kS log-uniform in 0.3..7;
* ``polach_falling``: with Eq. 9, A in 0.3..0.8, B in 0.1..1 s/m at the rig's or the
  train's speed;
* ``burckhardt``: ``c1*(1 - exp(-c2*xi)) - c3*xi`` with ``c3/(c1*c2 - c3)`` in 0..0.1
  (the published road-surface table spans 0..0.08);
* ``exponential``: ``mu*(1 - exp(-k0*xi/mu))``;
* ``tanh``: ``mu*tanh(k0*xi/mu)``;
* ``she``: Shen, Hedrick and Elkins (1983): ``mu*(z - z^2/3 + z^3/27)`` for ``z = k0*xi/mu``
  up to 3, then mu;
* ``magic``: Pacejka's magic formula ``D*sin(Cm*atan(B*xi - E*(B*xi - atan(B*xi))))``,
  Cm in 1.2..1.9, E in -1..0.5 (not a member of the estimator's family);
* ``dugoff``: Dugoff, Fancher and Segel (1970): linear ``k0*xi`` up to half the friction,
  then ``mu*(1 - mu/(4*k0*xi))`` (a kink, slope constant at first; the estimator's family
  has held this shape since it was found to miss it);
* ``hyperbolic``: ``mu*z/(1 + z)`` with ``z = k0*xi/mu``: a smooth saturation whose slope
  falls as ``(1 - u)^2`` from the start (the estimator's family has held this shape
  since it was found to miss it).
"""

from __future__ import annotations

import math

import numpy as np

LAWS = ("polach", "polach_falling", "burckhardt", "exponential", "tanh", "she", "magic",
        "dugoff", "hyperbolic")

# the rig: V-Track-like (N, R, V, f, J, modulation amplitude); C = Omega*J*V/(R^2*N)
RIG = {"load_n": 4200.0, "radius_m": 0.0675, "speed_m_s": 1.944, "freq_hz": 2.0,
       "inertia": 4.0, "t_mod_nm": 8.0}
RIG_C = 2 * math.pi * RIG["freq_hz"] * RIG["inertia"] * RIG["speed_m_s"] / (
    RIG["radius_m"] ** 2 * RIG["load_n"])
#: step fractions of the deepest utilisation: V-Track's proportions (the paper's six steps)
RIG_FRACTIONS = np.array([0.0035, 0.35, 0.68, 0.84, 0.92, 1.0])


def _polach_force(xi, mu_fn, k_a, k_s, stiff):
    """Polach 2005 Eq. 8 in lumped form: ``eps = stiff*xi/mu`` with the friction mu(xi)."""
    mu = mu_fn(np.abs(xi))
    eps = stiff * np.abs(xi) / mu
    f = (2 / math.pi) * (k_a * eps / (1 + (k_a * eps) ** 2) + np.arctan(k_s * eps))
    return np.sign(xi) * mu * f


def draw_law(name: str, rng: np.random.Generator, *, speed_m_s: float):
    """(curve(xi), description) of a law with parameters drawn over its range; the friction
    scale 0.1..0.6 and the initial slope 20..200."""
    mu = rng.uniform(0.1, 0.6)
    k0 = math.exp(rng.uniform(math.log(20.0), math.log(200.0)))
    if name in ("polach", "polach_falling"):
        r = math.exp(rng.uniform(math.log(0.3), math.log(7.0)))
        k_s = 1.0
        k_a = r
        stiff = math.pi * k0 / (2 * (k_a + k_s))
        if name == "polach":
            def mu_fn(w):
                return np.full_like(w, mu)
            desc = f"r={r:.2f}"
        else:
            a = rng.uniform(0.3, 0.8)
            b = rng.uniform(0.1, 1.0)

            def mu_fn(w, a=a, b=b):
                return mu * ((1 - a) * np.exp(-b * w * speed_m_s) + a)
            desc = f"r={r:.2f} A={a:.2f} B={b:.2f}"
        return (lambda xi: _polach_force(np.asarray(xi, float), mu_fn, k_a, k_s, stiff)), desc
    if name == "burckhardt":
        d = rng.uniform(0.0, 0.1)
        c2 = k0 / mu  # scale; c1*c2 - c3 = k0, c3 = d*k0
        c3 = d * k0
        c1 = (k0 + c3) / c2
        return (lambda xi: np.sign(xi) * (c1 * (1 - np.exp(-c2 * np.abs(xi)))
                                         - c3 * np.abs(xi))), f"d={d:.3f}"
    if name == "exponential":
        return lambda xi: mu * np.sign(xi) * (1 - np.exp(-k0 * np.abs(xi) / mu)), ""
    if name == "tanh":
        return lambda xi: mu * np.tanh(k0 * np.asarray(xi, float) / mu), ""
    if name == "she":
        def she(xi):
            z = np.minimum(k0 * np.abs(xi) / mu, 3.0)
            return np.sign(xi) * mu * (z - z * z / 3 + z ** 3 / 27)
        return she, ""
    if name == "magic":
        cm = rng.uniform(1.2, 1.9)
        e = rng.uniform(-1.0, 0.5)
        bb = k0 / (cm * mu)  # initial slope B*C*D = k0

        def magic(xi):
            x = bb * np.asarray(xi, float)
            return mu * np.sin(cm * np.arctan(x - e * (x - np.arctan(x))))
        return magic, f"C={cm:.2f} E={e:.2f}"
    if name == "dugoff":
        def dugoff(xi):
            x = np.abs(np.asarray(xi, float))
            lin = k0 * x
            return np.sign(xi) * np.where(lin <= mu / 2, lin,
                                          mu * (1 - mu / (4 * np.maximum(lin, 1e-300))))
        return dugoff, ""
    if name == "hyperbolic":
        def hyperbolic(xi):
            z = k0 * np.abs(np.asarray(xi, float)) / mu
            return np.sign(xi) * mu * z / (1 + z)
        return hyperbolic, ""
    raise ValueError(name)


def peak(curve) -> tuple[float, float]:
    """(xi at the first maximum, the maximum P) by a grid search and golden section; a curve
    still rising at xi = 1e3 is saturating and P is its value there. (A slight fall of the
    friction with the slip velocity puts the peak far out, beyond creepages of 1.)"""
    xi = np.geomspace(1e-7, 1e3, 80001)
    f = curve(xi)
    df = np.diff(f)
    stop = np.flatnonzero(df <= 0)
    if stop.size == 0:  # still rising: the supremum (a saturating law)
        return math.inf, float(f[-1])
    j = int(stop[0])
    a, b = xi[max(j - 1, 0)], xi[min(j + 1, xi.size - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        c, d = b - g * (b - a), a + g * (b - a)
        if curve(np.array([c]))[0] > curve(np.array([d]))[0]:
            b = d
        else:
            a = c
    x = 0.5 * (a + b)
    return x, float(curve(np.array([x]))[0])


def _creepage_at(curve, coa, xi_top):
    """xi on the rising branch with curve(xi) = coa (bisection, vectorised)."""
    lo = np.zeros_like(coa)
    hi = np.full_like(coa, xi_top)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        below = curve(mid) < coa
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _slope(curve, xi):
    h = np.maximum(1e-7 * np.abs(xi), 1e-11)
    return (curve(xi + h) - curve(xi - h)) / (2 * h)


#: the chain's typical standard errors: the phase per rig step [deg] (the twin's default run:
#: 0.09..0.63 deg over its six steps), the creep coefficient per on-board point (relative)
BASE_SE = {"rig": 0.3, "train": 0.03}


def record(name: str, rng: np.random.Generator, depth: float, *, mode: str,
           noise: float) -> dict | None:
    """One record: ``coa``, ``y`` (train: k; rig: phase [deg]), ``se``, (rig: ``swing``,
    ``constant``), the truth ``P`` and ``desc``; None when the swing-averaged curve cannot
    reach the deepest CoA. ``noise``: multiples of :data:`BASE_SE` added (0: exact values,
    stated with the base standard error)."""
    speed = RIG["speed_m_s"] if mode == "rig" else rng.uniform(5.0, 40.0)
    curve, desc = draw_law(name, rng, speed_m_s=speed)
    xi_pk, p_true = peak(curve)
    xi_top = xi_pk if math.isfinite(xi_pk) else 1e3
    if mode == "train":
        coa = np.repeat(np.linspace(0.2, depth, 4), 3) * p_true
        coa = coa * (1 + 0.002 * rng.standard_normal(coa.size))
        coa = np.minimum(coa, depth * p_true)
        k = _slope(curve, _creepage_at(curve, coa, xi_top))
        base = BASE_SE["train"]
        rel = base * max(noise, 1.0)
        y = k * (1 + base * noise * rng.standard_normal(k.size))
        return {"coa": coa, "y": y, "se": rel * k, "P": p_true, "desc": desc,
                "speed_m_s": speed}
    coa = RIG_FRACTIONS * depth * p_true
    n_load, radius = RIG["load_n"], RIG["radius_m"]
    c = RIG_C
    th = (np.arange(64) + 0.5) * (2 * math.pi / 64)
    cs = np.cos(th)
    xi = _creepage_at(curve, coa, xi_top)
    k = _slope(curve, xi)
    for _ in range(8):  # the swing and the slope it produces, to consistency
        a = RIG["t_mod_nm"] / (radius * n_load * np.abs(1j * c + k))
        lo = xi - 3 * a
        hi = np.full_like(xi, xi_top * 1.5 + 1e-3)
        for _ in range(70):
            mid = 0.5 * (lo + hi)
            mean = curve(mid[:, None] + a[:, None] * cs[None, :]).mean(axis=1)
            below = mean < coa
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        xm = 0.5 * (lo + hi)
        mean = curve(xm[:, None] + a[:, None] * cs[None, :]).mean(axis=1)
        if np.any(np.abs(mean - coa) > 1e-9 * p_true):
            return None
        k = 2 * (curve(xm[:, None] + a[:, None] * cs[None, :]) * cs).mean(axis=1) / a
    phase = np.degrees(np.arctan(c / k))
    base = BASE_SE["rig"]
    se = base * max(noise, 1.0)
    return {"coa": coa, "y": phase + base * noise * rng.standard_normal(phase.size),
            "se": np.full(phase.size, se), "swing": a, "constant": c, "P": p_true,
            "speed_m_s": speed,
            "desc": desc}
